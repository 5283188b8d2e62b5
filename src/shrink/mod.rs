//! Occluder shrinking (papers/004, Yılmaz & Güdükbay 2007, sec. 4.1-4.2):
//! a second conservative from-region method beside the extended
//! projections of [`crate::oracle`].
//!
//! For a view cell whose points lie within `e` of its centre `c` (`e` is
//! half its diagonal), every closed solid of the scene is **shrunk** by
//! `e` (`shrink_mesh.rs`), and visibility is decided **from the one point
//! `c`** against all the shrunk solids together (`shrink_cube.rs`, a cube
//! map of conservative depths): what they hide from `c` is hidden from
//! the whole cell (the paper's Theorem 1), and from a point every
//! occluder fuses with every other it overlaps, whatever their
//! orientations.
//!
//! **Why it is conservative.** Let `s` be a point of a kept shrunk face
//! of solid `X`: the open ball of radius `e` around it lies inside `X`
//! (the erosion check of `shrink_mesh.rs`). Let `p` be a point of an
//! object with `s` strictly between `c` and `p` on the segment `c p` (any
//! such `s`, not only the first), `s = c + l (p - c)`, `0 < l < 1`. For a
//! viewpoint `c' = c + v` of the cell, `|v| <= e`, the segment `c' p`
//! passes through `s' = s + (1 - l) v`, within `e` of `s`, so inside `X`. The cell lies outside `X`'s box,
//! so `c'` is outside `X`, and the segment crosses `X`'s surface between
//! `c'` and `s'`: `p` is hidden from `c'`.
//!
//! **Solids on a floor** (see `Solid` in `shrink_mesh.rs`: footprints
//! without a floor, and a closed solid with a flat bottom shrunk a second
//! way) are shrunk as `X u H`, `H` the half-space `z <= f` below the
//! floor, so `s'` lies in `X u H`. They are drawn only for cells above
//! `f`, and hide only occludee points `p` at or above `f`: then every
//! point of the segment `c' p` but `p` is above `f`, so `s'` (with `l < 1`)
//! is in `X`, and the segment from `c'` to `s'` crosses a real face of `X`
//! (it cannot reach the floor's plane). A pixel keeps apart the depth of
//! the solids not on floors, which binds any occludee, and the depth of
//! all with the floor `F` of the one it came from, which binds occludees
//! whose lowest point is at or above `F`.
//!
//! **The cube map gives the `s`**: in a covered pixel every ray from
//! `c` meets a kept face within `D`, so every point `p` of the pixel
//! farther than `D` has one. An object is hidden when every pixel its
//! box (or each of its triangle clusters' boxes) touches is covered with
//! a `D` below the box's distance from `c`. The `s` may lie on the
//! object's own shrunk faces: the segment then crosses the object's own
//! surface before `p`, and `p` is still not the first point `c'` sees. So
//! no point of a hidden object is the first hit of a segment from the
//! cell. Margins: the
//! erosion check keeps faces `e` plus the tracer's slack from the
//! surface; touching in the cube map is widened, never narrowed.
//!
//! Solids are shrunk once per cell size: `e` is rounded up to the next of
//! eight steps per doubling (shrinking more is still conservative), and
//! the shrunk set is kept for cells of the same step.
//!
//! Deviations from the paper, and why, are in `notes/shrink.md`: the
//! erosion check (the paper's swept-volume test alone does not keep faces
//! deep enough inside, see `shrink_mesh.rs`), exact cube-map coverage of
//! each solid's outline instead of hardware occlusion queries, and no
//! merging of abutting solids.
//!
//! The cube map is drawn on the CPU (`shrink_cube.rs`, the reference) or
//! on the GPU (`shrink_gpu.rs`, wgpu compute shaders, feature `gpu`),
//! which covers only pixels the CPU covers, with depths no smaller
//! ([`ShrinkOracle::with_rasteriser`]).

mod shrink_cube;
mod shrink_geom;
#[cfg(feature = "gpu")]
mod shrink_gpu;
#[cfg(all(test, feature = "gpu"))]
mod shrink_gpu_tests;
mod shrink_mesh;

pub use shrink_mesh::ShrinkCounts;

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::DVec3;

use crate::bitset::ObjectSet;
use crate::geom::Aabb;
use crate::oracle::{
    Cluster, Rasteriser, build_clusters, hidden_below, sliced_solids, tracer_slack,
};
use crate::scene::Scene;
use crate::slices::{HiddenSlices, SlicedScene};
use shrink_cube::CubeMap;
use shrink_mesh::{Shrunk, Solid};

/// Settings of the shrinking oracle.
#[derive(Clone, Debug, PartialEq)]
pub struct ShrinkParams {
    /// Pixels on a side of each of the cube map's six faces (a power of
    /// two in 4..=4096).
    pub resolution: usize,
    /// Occludees below object level: an object not proved hidden whole is
    /// tried cluster by cluster, its triangles cut in halves this many
    /// levels deep (1: whole objects only; at most 16).
    pub occludee_depth: usize,
    /// The shrinking distance over the cell's half diagonal: 1 is the
    /// paper's, and the least that is conservative. Values below 1 are
    /// wrong on purpose, for tests that show the ray check catches them.
    pub erosion_scale: f64,
}

impl Default for ShrinkParams {
    fn default() -> Self {
        Self {
            resolution: 256,
            occludee_depth: 6,
            erosion_scale: 1.0,
        }
    }
}

/// Why the shrinking oracle cannot be set up.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShrinkError {
    /// A setting is outside its domain.
    #[error("invalid shrinking setting: {name} must be {expected}, not {value}")]
    Parameter {
        /// The setting (as `ShrinkParams` names it).
        name: &'static str,
        /// What it must be.
        expected: &'static str,
        /// What it was.
        value: String,
    },
}

impl ShrinkParams {
    /// Checks the settings; the error names the bad one.
    pub fn validate(&self) -> Result<(), ShrinkError> {
        let bad = |name, expected, value: String| ShrinkError::Parameter {
            name,
            expected,
            value,
        };
        if !self.resolution.is_power_of_two() || !(4..=4096).contains(&self.resolution) {
            return Err(bad(
                "resolution",
                "a power of two in 4..=4096",
                self.resolution.to_string(),
            ));
        }
        if !(1..=16).contains(&self.occludee_depth) {
            return Err(bad(
                "occludee_depth",
                "in 1..=16",
                self.occludee_depth.to_string(),
            ));
        }
        if !(self.erosion_scale.is_finite() && self.erosion_scale > 0.0) {
            return Err(bad(
                "erosion_scale",
                "finite and > 0",
                self.erosion_scale.to_string(),
            ));
        }
        Ok(())
    }
}

/// Where a cell's time went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShrinkTimes {
    /// Shrinking the solids (zero when this cell size was shrunk before).
    pub shrink: Duration,
    /// Drawing the cube map.
    pub rasterise: Duration,
    /// Testing the objects.
    pub test: Duration,
}

impl ShrinkTimes {
    /// All of it.
    pub fn total(&self) -> Duration {
        self.shrink + self.rasterise + self.test
    }
}

/// The answer for one cell.
#[derive(Clone, Debug, PartialEq)]
pub struct ShrinkReport {
    /// The objects that may be visible from some point of the cell.
    pub visible: ObjectSet,
    /// Objects whose box meets the cell (always kept).
    pub touching: usize,
    /// Objects proved hidden only cluster by cluster.
    pub cluster_hidden: usize,
    /// The distance the solids were shrunk by (at least half the cell's
    /// diagonal).
    pub erosion: f64,
    /// Shrunk solids drawn from the centre (those with faces left, the
    /// cell outside their box and above their floor).
    pub solids_drawn: usize,
    /// Their faces.
    pub faces_drawn: usize,
    /// What the shrinking did to every solid's faces at this size.
    pub counts: ShrinkCounts,
    /// Cube-map pixels covered.
    pub covered: usize,
    /// Where the time went.
    pub times: ShrinkTimes,
    /// With [`ShrinkOracle::cell_slices`], per object: the slices of a
    /// kept object proved hidden and the triangles they cull (empty
    /// otherwise).
    pub slices: Vec<Option<HiddenSlices>>,
}

/// The scene's solids shrunk by one distance (in the order of
/// [`ShrinkOracle::solids`]).
struct ShrunkSet {
    solids: Vec<Shrunk>,
    counts: ShrinkCounts,
}

/// The occluder-shrinking oracle for one scene.
pub struct ShrinkOracle<'a> {
    scene: &'a Scene,
    params: ShrinkParams,
    solids: Vec<Solid>,
    /// For a closed solid with a flat bottom, the index of the same solid
    /// on its floor (drawn too for cells above that floor).
    twins: Vec<Option<usize>>,
    clusters: Vec<Vec<Cluster>>,
    cache: Mutex<HashMap<(u64, u64), Arc<ShrunkSet>>>,
    rasteriser: Rasteriser,
    /// The cube-map pipelines on the rasteriser's GPU, if it has one and
    /// they were built.
    #[cfg(feature = "gpu")]
    gpu: Option<shrink_gpu::ShrinkGpu>,
    /// Why the GPU of the rasteriser is not used.
    cpu_reason: Option<String>,
}

impl<'a> ShrinkOracle<'a> {
    /// Prepares the oracle: the scene's closed solids (and solids open
    /// only at the bottom), each object's triangle clusters; its cube maps
    /// are drawn on the CPU (the reference; see
    /// [`ShrinkOracle::with_rasteriser`] for the GPU).
    pub fn new(scene: &'a Scene, params: ShrinkParams) -> Result<Self, ShrinkError> {
        Self::with_rasteriser(scene, params, Rasteriser::cpu())
    }

    /// [`ShrinkOracle::new`] with the cube maps drawn by `rasteriser`: on
    /// its GPU when it has one ([`Rasteriser::best`]), never covering a
    /// pixel the CPU would leave open nor with a smaller depth
    /// (`shrink_gpu.rs`); a map that fails there is drawn on the CPU and
    /// counted in [`Rasteriser::gpu_failures`].
    pub fn with_rasteriser(
        scene: &'a Scene,
        params: ShrinkParams,
        rasteriser: Rasteriser,
    ) -> Result<Self, ShrinkError> {
        params.validate()?;
        let mut solids = Vec::new();
        let mut twins = Vec::new();
        for s in sliced_solids(scene) {
            let Some(solid) = Solid::new(&s.triangles, s.open_bottom) else {
                continue;
            };
            let twin = solid.on_its_floor();
            solids.push(solid);
            twins.push(None);
            if let Some(t) = twin {
                *twins.last_mut().expect("pushed") = Some(solids.len());
                solids.push(t);
                twins.push(None);
            }
        }
        #[cfg_attr(not(feature = "gpu"), allow(unused_mut))]
        let mut cpu_reason = None;
        #[cfg(feature = "gpu")]
        let gpu = rasteriser.gpu_device().and_then(|g| {
            if let Some(why) = shrink_gpu::ShrinkGpu::too_big(g, params.resolution) {
                cpu_reason = Some(why);
                return None;
            }
            match shrink_gpu::ShrinkGpu::new(g) {
                Ok(p) => Some(p),
                Err(e) => {
                    cpu_reason = Some(e.to_string());
                    None
                }
            }
        });
        Ok(Self {
            scene,
            twins,
            clusters: build_clusters(scene, params.occludee_depth),
            params,
            solids,
            cache: Mutex::new(HashMap::new()),
            rasteriser,
            #[cfg(feature = "gpu")]
            gpu,
            cpu_reason,
        })
    }

    /// Why the cube maps are drawn on the CPU although the rasteriser has
    /// a GPU (maps too big for it, pipelines that failed to build); `None`
    /// otherwise (see [`Rasteriser::cpu_reason`] for a rasteriser without
    /// one).
    pub fn cpu_reason(&self) -> Option<&str> {
        self.cpu_reason.as_deref()
    }

    /// The rasteriser the cube maps are drawn with.
    pub fn rasteriser(&self) -> &Rasteriser {
        &self.rasteriser
    }

    /// Where the cube maps are drawn: "GPU: " and the adapter's name, or
    /// "CPU".
    pub fn backend(&self) -> String {
        #[cfg(feature = "gpu")]
        if self.gpu.is_some() {
            return self.rasteriser.name();
        }
        "CPU".into()
    }

    /// The cube map around `eye` with `solids` drawn: on the GPU when
    /// there is one (the CPU when it fails), else on the CPU.
    fn cube_map(&self, eye: DVec3, solids: &[&Shrunk]) -> CubeMap {
        let n = self.params.resolution;
        #[cfg(feature = "gpu")]
        if let (Some(p), Some(g)) = (&self.gpu, self.rasteriser.gpu_device()) {
            match p.build(g, eye, n, solids) {
                Ok(map) => return map,
                Err(e) => self.rasteriser.note_gpu_failure(1, e.to_string()),
            }
        }
        let mut map = CubeMap::new(eye, n);
        for s in solids {
            map.draw(s);
        }
        map
    }

    /// The settings.
    pub fn params(&self) -> &ShrinkParams {
        &self.params
    }

    /// The number of solids that can be shrunk (occluders; a closed solid
    /// with a flat bottom, shrunk two ways, counts once).
    pub fn solid_count(&self) -> usize {
        self.solids.len() - self.twins.iter().filter(|t| t.is_some()).count()
    }

    /// The solids shrunk by the step at or above `e`, with `margin` (the
    /// cache is keyed by both).
    fn shrunk(&self, e: f64, margin: f64) -> (Arc<ShrunkSet>, f64, Duration) {
        // The step's distance, never below `e` (a step up where rounding
        // put it a hair under), so that every cell of the step is shrunk
        // by the same distance, at least its own.
        let mut step = (8.0 * e.log2()).ceil();
        if (step / 8.0).exp2() < e {
            step += 1.0;
        }
        let e = (step / 8.0).exp2();
        let key = (step.to_bits(), margin.to_bits());
        if let Some(set) = self.cache.lock().expect("cache lock").get(&key) {
            return (Arc::clone(set), e, Duration::ZERO);
        }
        let start = Instant::now();
        let mut counts = ShrinkCounts::default();
        let mut solids = Vec::new();
        for (s, twin) in self.solids.iter().zip(&self.twins) {
            let (shrunk, c) = s.shrink(e, margin);
            if twin.is_none() {
                // Each solid counted once: on its floor where it has one.
                counts += c;
            }
            solids.push(shrunk);
        }
        let set = Arc::new(ShrunkSet { solids, counts });
        self.cache
            .lock()
            .expect("cache lock")
            .insert(key, Arc::clone(&set));
        (set, e, start.elapsed())
    }

    /// The objects that may be visible from some point of `cell` (local
    /// coordinates, [`Scene::frame`]). A cell that is not a box (NaN,
    /// infinite, inside out) proves nothing.
    pub fn cell(&self, cell: &Aabb) -> ShrinkReport {
        self.run(cell, None)
    }

    /// [`ShrinkOracle::cell`], and for each object it keeps, the slices
    /// proved hidden (papers/004 sec. 3; never a slice box that touches
    /// the cell): per piece, the [`crate::slices::SliceIndex`] that culls
    /// the most of its triangles and how many, or `None` when no piece has
    /// any. The answer's `slices` holds them, one per object.
    pub fn cell_slices(&self, cell: &Aabb, sliced: &SlicedScene) -> ShrinkReport {
        self.run(cell, Some(sliced))
    }

    fn run(&self, cell: &Aabb, sliced: Option<&SlicedScene>) -> ShrinkReport {
        let objects = self.scene.objects().len();
        let (cmin, cmax) = (cell.min.as_dvec3(), cell.max.as_dvec3());
        let mut report = ShrinkReport {
            // Every object with a surface: an empty one is never visible.
            visible: self.scene.surface_objects(),
            touching: objects,
            cluster_hidden: 0,
            erosion: 0.0,
            solids_drawn: 0,
            faces_drawn: 0,
            counts: ShrinkCounts::default(),
            covered: 0,
            times: ShrinkTimes::default(),
            slices: Vec::new(),
        };
        if !(cmin.is_finite() && cmax.is_finite() && cmin.cmple(cmax).all()) {
            return report;
        }
        let slack = tracer_slack(self.scene, cmin, cmax);
        let eye = (cmin + cmax) / 2.0;
        // Every point of the cell within e of the eye (with its rounding),
        // and no shrinking by less than a scene's hair.
        let diag = self.scene.bounds().diagonal() as f64;
        let e = (((cmax - cmin) / 2.0).length() * self.params.erosion_scale)
            .max(1e-5 * diag)
            .max(slack);
        let (set, e, shrink_time) = self.shrunk(e, slack);
        report.erosion = e;
        report.counts = set.counts;
        report.times.shrink = shrink_time;

        let start = Instant::now();
        let (gmin, gmax) = (cmin - slack, cmax + slack);
        let above = |floor: Option<f64>| floor.is_none_or(|f| cmin.z > f + slack);
        // A closed solid and its twin on its floor are both drawn: the twin
        // hides more above the floor, the solid what is below it.
        let mut drawn: Vec<&Shrunk> = Vec::new();
        for s in &set.solids {
            let apart = (0..3).any(|k| s.solid_max[k] < gmin[k] || s.solid_min[k] > gmax[k]);
            if apart && above(s.floor) && !s.triangles.is_empty() {
                drawn.push(s);
                report.solids_drawn += 1;
                report.faces_drawn += s.triangles.len();
            }
        }
        let map = self.cube_map(eye, &drawn);
        report.covered = map.covered();
        report.times.rasterise = start.elapsed();

        let start = Instant::now();
        let mut visible = ObjectSet::new(objects);
        let mut touching = 0;
        for (i, o) in self.scene.objects().iter().enumerate() {
            if o.is_empty() {
                // No triangles: nothing to see, whatever its flags.
                continue;
            }
            if o.flags.always_visible() {
                visible.insert(i);
                continue;
            }
            let (lo, hi) = (o.bounds.min.as_dvec3(), o.bounds.max.as_dvec3());
            if (0..3).all(|k| lo[k] <= gmax[k] && hi[k] >= gmin[k]) {
                touching += 1;
                visible.insert(i);
                continue;
            }
            let hidden = |lo: DVec3, hi: DVec3| {
                let near = shrink_geom::point_box_distance(eye, lo, hi) - slack;
                map.box_hidden(lo, hi, near)
            };
            if hidden(lo, hi) {
                continue;
            }
            let clusters = &self.clusters[i];
            if clusters.is_empty() || !clusters_hidden(clusters, &hidden) {
                visible.insert(i);
            } else {
                report.cluster_hidden += 1;
            }
        }
        if let Some(sliced) = sliced {
            report.slices = vec![None; objects];
            for i in visible.iter() {
                let o = &self.scene.objects()[i];
                let (lo, hi) = (o.bounds.min.as_dvec3(), o.bounds.max.as_dvec3());
                // Slice boxes grown past the rounding of their sides; a box
                // that touches the cell is not hidden (Theorem 1 is for
                // occludees outside it), but the pieces of an object that
                // does (a terrain under the cell) can be.
                let pad = slack + 1e-9 * (hi - lo).max_element();
                let mut hidden = |a: DVec3, b: DVec3| {
                    let (a, b) = (a - pad, b + pad);
                    if (0..3).all(|k| a[k] <= gmax[k] && b[k] >= gmin[k]) {
                        return false;
                    }
                    let near = shrink_geom::point_box_distance(eye, a, b) - slack;
                    map.box_hidden(a, b, near)
                };
                report.slices[i] = sliced.hidden_slices(i, &mut hidden);
            }
        }
        report.times.test = start.elapsed();
        report.visible = visible;
        report.touching = touching;
        report
    }
}

/// Whether every leaf cluster (or a cluster above it) is hidden, below
/// the root (the object's box, tried already).
fn clusters_hidden(clusters: &[Cluster], hidden: &dyn Fn(DVec3, DVec3) -> bool) -> bool {
    let mut test = |a: DVec3, b: DVec3| hidden(a, b);
    match clusters[0].children {
        Some([a, b]) => {
            hidden_below(clusters, a, &mut test) && hidden_below(clusters, b, &mut test)
        }
        None => false,
    }
}
