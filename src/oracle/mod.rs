//! The conservative oracle: extended projections (papers/001, Durand et
//! al. 2000, sec. 2-5 and appendices A-B).
//!
//! For a 3D view cell (a box of viewpoints, all directions) [`Oracle::cell`]
//! computes a set of objects that surely contains every object visible
//! from some point of the cell: an object is left out only when it is
//! *proved* hidden. Checked against the sampled sets of a `.v5d`, it
//! exposes sampling misses.
//!
//! Per cell, first the free space (`oracle_sealed.rs`): the closed solids
//! of the scene cut it into connected pieces over a grid, once per scene,
//! and an object that no free path from the cell reaches (a room behind
//! closed walls, doors and windows) is hidden. Then, for each of six
//! planes around it (one per face, see `oracle_project.rs`):
//!
//! 1. **Occluder selection.** The scene's convex occluders
//!    (`oracle_occluders.rs`) in front of the face are ranked by the solid
//!    angle they subtend from the cell's centre; occluders of objects
//!    already hidden from the parent cell are skipped.
//! 2. **Plane placement.** Candidate positions just behind each of the
//!    largest occluders; the one whose Depth Map fills most pixels (at a
//!    low resolution, with the largest occluders) wins. The plane is a
//!    finite rectangle: the cell's face grown on each side by
//!    `extension` times the plane's distance from the face.
//! 3. **Occluder Projection.** Each occluder (clipped to the cell's side
//!    of the plane) is projected from the 8 cell corners; its Projection
//!    is the intersection of those views, with its maximum depth, drawn
//!    into the Depth Map only where it covers whole pixels (on the CPU by
//!    exact clipping and scan conversion; on the GPU by stencil counting).
//! 4. **Occludee test.** A max pyramid over the map answers "is every
//!    pixel under this rectangle covered by occluders nearer than this
//!    depth?". Object bounding boxes, in a hierarchy, are tested with their
//!    Projection rectangle (and the improved Projection for boxes between
//!    the cell and the plane) and their minimum depth; a box behind the
//!    plane whose rectangle fails is tried with its exact Projection, a
//!    convex polygon (`occludee_polygon`).
//! 5. **Occlusion sweep** (sec. 5, `oracle_sweep.rs`). Planes at the
//!    largest axis-aligned patches in front of the face (`oracle_patches.rs`:
//!    floors, slabs, walls, drawn whole with their holes) and spaced
//!    geometrically away from it; each plane holds the previous one
//!    reprojected (exactly, per pixel; with `sweep_reach`, the planes 2,
//!    4, 8, ... back too), the convex occluders between the two, the cuts
//!    of solids and the patch in it. Objects the placed
//!    planes cannot hide are tried on the sweep planes next to them.
//!
//! An object is hidden when its box is hidden on one plane, or when its
//! box, cut into the pieces in front of each face, has every piece hidden
//! on a plane it lies in front of ("every plane that its Projection
//! reaches"). Objects whose box meets the cell are always kept.
//!
//! Why each step is conservative is argued where it is done; the property
//! test in `tests/it/oracle.rs` checks it with rays.
//!
//! Depth Maps are rasterised by a [`Rasteriser`]: the GPU ([`GpuRasteriser`],
//! wgpu, stencil counting) where an adapter exists, else the CPU reference
//! ([`cpu_rasterise`]). [`check_tree`] cross-checks a built tree against the
//! oracle (`vis5d check`).
//!
//! Files: `oracle_occluders.rs` (convex occluders and sliceable solids of
//! the scene), `oracle_project.rs` (the six plane frames, Projections of
//! occluders and occludees), `oracle_plane.rs` (Depth Maps, the CPU
//! rasteriser, the max pyramid), `oracle_slice.rs` (slices of solids, sec.
//! 3.3), `oracle_patches.rs` (axis-aligned patches), `oracle_sweep.rs`
//! (reprojection and the sweep), `oracle_gpu.rs` with `oracle_gpu.wgsl` (the GPU rasteriser),
//! `oracle_raster.rs` (the GPU-or-CPU choice), `oracle_sealed.rs` (the
//! free space), `oracle_terrain.rs` (height fields as solids),
//! `oracle_check.rs` (the cross-check).
#![cfg_attr(not(feature = "gpu"), doc = "\n\n[`GpuRasteriser`]: crate#features")]

mod oracle_check;
mod oracle_clusters;
#[cfg(feature = "gpu")]
mod oracle_gpu;
mod oracle_inside;
mod oracle_occluders;
mod oracle_patches;
mod oracle_plane;
mod oracle_project;
mod oracle_raster;
mod oracle_sealed;
mod oracle_shaft;
mod oracle_slice;
mod oracle_sweep;
mod oracle_terrain;

pub use oracle_check::{CheckParams, CheckReport, LeafCheck, Suspect, Violation, check_tree};
pub(crate) use oracle_clusters::{Cluster, build as build_clusters, hidden_below};
#[cfg(feature = "gpu")]
pub(crate) use oracle_gpu::ErrorScopes;
#[cfg(feature = "gpu")]
pub use oracle_gpu::{GpuError, GpuRasteriser};
pub use oracle_occluders::OccluderCounts;
pub use oracle_plane::{MapJob, ProjectedOccluder, cpu_rasterise};
pub(crate) use oracle_project::corners;
pub use oracle_raster::Rasteriser;
pub use oracle_sealed::SealedCounts;

/// A margin for the tracer's rounding around the cell `[cmin, cmax]` of
/// `scene`: 8 f32 ulps of the extent and the largest coordinate of the
/// scene and the cell together (both oracles use it).
pub(crate) fn tracer_slack(scene: &Scene, cmin: DVec3, cmax: DVec3) -> f64 {
    let b = scene.bounds();
    let (lo, hi) = (b.min.as_dvec3().min(cmin), b.max.as_dvec3().max(cmax));
    let scale = (hi - lo).length() + lo.abs().max(hi.abs()).max_element();
    8.0 * f32::EPSILON as f64 * scale
}

/// The objects that can be sliced (closed, or open only at the bottom),
/// for the shrinking oracle ([`crate::shrink`]).
pub(crate) fn sliced_solids(scene: &Scene) -> Vec<SlicedSolid> {
    oracle_occluders::extract_with(scene, false).solids
}

use std::time::{Duration, Instant};

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use crate::bitset::ObjectSet;
use crate::geom::polygon::{convex_hull, signed_area};
use crate::geom::{Aabb, BoxTree};
use crate::scene::Scene;
use crate::slices::{HiddenSlices, SlicedScene};
use oracle_occluders::{Occluder, SlicedSolid};
use oracle_patches::Patch;
use oracle_plane::DepthMap;
use oracle_project::{
    Frame, clip_above, clip_below, improved_rect, occludee_polygon, occludee_rect, occluder_views,
    ordered_views, project,
};
use oracle_sweep::{Sweep, SweepPlane};

/// Settings of the oracle.
#[derive(Clone, Debug, PartialEq)]
pub struct OracleParams {
    /// Depth Map resolution, pixels on a side (a power of two; the paper
    /// found 256 best).
    pub resolution: usize,
    /// How far the plane rectangle reaches beyond the cell's face, in
    /// multiples of the plane's distance from the face (the paper: 1.5).
    pub extension: f64,
    /// How many of the largest occluders propose a plane position.
    pub plane_candidates: usize,
    /// How many of the largest occluders score each position.
    pub placement_occluders: usize,
    /// The resolution at which positions are scored.
    pub placement_resolution: usize,
    /// The most occluders drawn into one Depth Map (the largest first).
    pub max_occluders: usize,
    /// Planes per face: the best position, then those that hide most
    /// objects the chosen ones do not (the paper used one).
    pub planes_per_face: usize,
    /// Occlusion sweep (sec. 5): planes per face spaced geometrically from
    /// the nearest occluder to the farthest (0: none). With the shafts on
    /// (`shaft_budget` > 0) the sweep runs only in cells whose slices are
    /// culled ([`Oracle::cell_slices`]): for whole objects the shafts prove
    /// nearly all it hides (0.3 objects a cell more kept on two of nine
    /// scenes measured, the same on seven), and it cost 12-45% of a cell's
    /// time (notes/oracle.md, stop 49).
    pub sweep_planes: usize,
    /// Occlusion sweep: planes per face at the axis-aligned patches
    /// (floors, slabs, walls) that subtend the largest solid angles from
    /// the cell, each drawn there whole (0: none).
    pub sweep_patches: usize,
    /// How far each sweep plane's rectangle reaches beyond the cell's
    /// face, in multiples of its distance from the face.
    pub sweep_extension: f64,
    /// Occlusion sweep: each plane takes the reprojections of this many
    /// planes before it, 1, 2, 4, ... planes back (1: the previous one
    /// only; at most 8). Each reprojection loses up to a pixel at the
    /// edges of what it carries, so through a chain of k planes an umbra
    /// shrinks by up to k pixels; with planes 2^j back it shrinks by about
    /// log2(k). The default, 3, reaches over a default sweep's planes
    /// (San Francisco's hillsides behind blocks, culled in slices); more
    /// pays with many sweep planes (a forest's crowns fuse only through
    /// thin steps), at one reprojection more per plane for each step of
    /// reach.
    pub sweep_reach: usize,
    /// Occludees below object level: an object not proved hidden whole is
    /// tried cluster by cluster, its triangles cut in halves this many
    /// levels deep (1: whole objects only; at most 16).
    pub occludee_depth: usize,
    /// Shafts (`oracle_shaft.rs`): an object the maps and sweeps did not
    /// hide is tried one occluder at a time, the cell and its box cut in
    /// halves, testing at most this many shafts (0: not tried).
    pub shaft_budget: usize,
    /// Shafts: the most cuts along one path (at most 32).
    pub shaft_depth: usize,
    /// Sealed rooms (`oracle_sealed.rs`): the free space between the
    /// closed solids, in connected components over a grid of about this
    /// many voxels at most; an object no free path from the cell reaches
    /// is hidden (0: not tried).
    pub seal_voxels: usize,
}

impl Default for OracleParams {
    fn default() -> Self {
        Self {
            resolution: 256,
            extension: 1.5,
            plane_candidates: 12,
            placement_occluders: 128,
            placement_resolution: 64,
            max_occluders: 4096,
            planes_per_face: 2,
            sweep_planes: 4,
            sweep_patches: 4,
            sweep_extension: 1.5,
            sweep_reach: 3,
            occludee_depth: 6,
            shaft_budget: 4096,
            shaft_depth: 24,
            seal_voxels: 1 << 24,
        }
    }
}

/// Why the oracle cannot be set up.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OracleError {
    /// A setting is outside its domain.
    #[error("invalid oracle setting: {name} must be {expected}, not {value}")]
    Parameter {
        /// The setting (as `OracleParams` names it).
        name: &'static str,
        /// What it must be.
        expected: &'static str,
        /// What it was.
        value: String,
    },
}

impl OracleParams {
    /// Checks the settings; the error names the bad one.
    pub fn validate(&self) -> Result<(), OracleError> {
        let bad = |name, expected, value: &dyn std::fmt::Display| OracleError::Parameter {
            name,
            expected,
            value: value.to_string(),
        };
        let power = "a power of two in 4..=4096";
        if !self.resolution.is_power_of_two() || !(4..=4096).contains(&self.resolution) {
            return Err(bad("resolution", power, &self.resolution));
        }
        if !self.placement_resolution.is_power_of_two()
            || !(4..=4096).contains(&self.placement_resolution)
        {
            return Err(bad(
                "placement_resolution",
                power,
                &self.placement_resolution,
            ));
        }
        if !(self.extension.is_finite() && self.extension >= 0.0) {
            return Err(bad("extension", "finite and >= 0", &self.extension));
        }
        if !(self.sweep_extension.is_finite() && self.sweep_extension >= 0.0) {
            return Err(bad(
                "sweep_extension",
                "finite and >= 0",
                &self.sweep_extension,
            ));
        }
        if self.shaft_depth > 32 {
            return Err(bad("shaft_depth", "in 0..=32", &self.shaft_depth));
        }
        if self.seal_voxels > 1 << 28 {
            return Err(bad("seal_voxels", "at most 268435456", &self.seal_voxels));
        }
        if !(1..=8).contains(&self.sweep_reach) {
            return Err(bad("sweep_reach", "in 1..=8", &self.sweep_reach));
        }
        if !(1..=16).contains(&self.occludee_depth) {
            return Err(bad("occludee_depth", "in 1..=16", &self.occludee_depth));
        }
        for (name, n) in [
            ("plane_candidates", self.plane_candidates),
            ("placement_occluders", self.placement_occluders),
            ("max_occluders", self.max_occluders),
            ("planes_per_face", self.planes_per_face),
        ] {
            if n == 0 {
                return Err(bad(name, "at least 1", &n));
            }
        }
        Ok(())
    }
}

/// What one plane did for a cell.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneReport {
    /// "+x", "-y", ...
    pub face: &'static str,
    /// The plane's coordinate along its axis (the scene's local
    /// coordinates, [`crate::scene::Scene::frame`]).
    pub position: f64,
    /// Convex occluders drawn into its Depth Map.
    pub occluders: usize,
    /// Solids whose cut by the plane was drawn.
    pub slices: usize,
    /// Depth Map pixels holding an occluder.
    pub filled: usize,
    /// Objects this plane alone proved hidden.
    pub hidden: usize,
}

/// Time spent on one cell, by stage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CellTimes {
    /// Occluder selection and plane placement.
    pub select: Duration,
    /// Occluder Projection into the Depth Maps (and the pyramids).
    pub rasterise: Duration,
    /// Occludee tests.
    pub test: Duration,
}

impl CellTimes {
    /// The whole cell.
    pub fn total(&self) -> Duration {
        self.select + self.rasterise + self.test
    }
}

/// The oracle's answer for one cell.
#[derive(Clone, Debug)]
pub struct CellReport {
    /// The objects not proved hidden: a superset of the visible ones.
    pub visible: ObjectSet,
    /// Objects taken as hidden because the parent cell hid them.
    pub hidden_by_parent: usize,
    /// Objects whose box meets the cell (never tested).
    pub touching: usize,
    /// Per plane, in the order +x, -x, +y, -y, +z, -z; planes with no occluder in
    /// front are left out.
    pub planes: Vec<PlaneReport>,
    /// Planes of the occlusion sweeps, all faces together.
    pub sweep_planes: usize,
    /// Objects only the sweeps proved hidden.
    pub sweep_hidden: usize,
    /// Objects proved hidden only cluster by cluster.
    pub cluster_hidden: usize,
    /// Objects proved hidden only shaft by shaft (`oracle_shaft.rs`).
    pub shaft_hidden: usize,
    /// Objects proved hidden by the free space (`oracle_sealed.rs`): no
    /// path between the closed solids leads from the cell to them.
    pub sealed_hidden: usize,
    /// Closed convex solids the cell reaches into by a whole slab (or lies
    /// in): the projections ran from the rest of the cell, and what meets
    /// their boxes is kept (`oracle_inside.rs`).
    pub inside_solids: usize,
    /// The cell the projections ran from (the cell itself, unless a solid
    /// cut a slab off it).
    pub projected_from: Aabb,
    /// Time by stage.
    pub times: CellTimes,
    /// With [`Oracle::cell_slices`], per object: the slices of a kept
    /// object proved hidden and the triangles they cull (empty otherwise).
    pub slices: Vec<Option<HiddenSlices>>,
}

/// The oracle over one scene: its occluders and the hierarchy of its
/// objects' boxes, built once.
pub struct Oracle<'a> {
    scene: &'a Scene,
    occluders: Vec<Occluder>,
    solids: Vec<SlicedSolid>,
    /// The terrains (height fields over a rectangle of the ground): the
    /// maps draw their cuts after the sliceable solids'.
    terrains: Vec<oracle_terrain::Terrain>,
    patches: Vec<Patch>,
    clusters: Vec<Vec<oracle_clusters::Cluster>>,
    counts: OccluderCounts,
    hierarchy: BoxTree,
    /// The shafts' view of the occluders (none when shafts are off).
    shafts: Option<oracle_shaft::Shafts>,
    /// Rays for the shafts' witnesses (none when shafts are off).
    tracer: Option<crate::trace::Tracer>,
    /// The free space's components (none when off or without solids).
    sealed: Option<oracle_sealed::Sealed>,
    params: OracleParams,
    rasteriser: Rasteriser,
}

impl<'a> Oracle<'a> {
    /// Prepares the oracle for a scene, its Depth Maps made by
    /// `rasteriser` ([`Rasteriser::best`]: the GPU where there is one).
    pub fn new(
        scene: &'a Scene,
        params: OracleParams,
        rasteriser: Rasteriser,
    ) -> Result<Self, OracleError> {
        params.validate()?;
        let oracle_occluders::Extracted {
            occluders,
            solids,
            counts,
        } = oracle_occluders::extract(scene);
        let boxes: Vec<Aabb> = scene.objects().iter().map(|o| o.bounds).collect();
        let patches = if params.sweep_patches > 0 {
            oracle_patches::extract(scene, 0.0)
        } else {
            Vec::new()
        };
        let clusters = oracle_clusters::build(scene, params.occludee_depth);
        let shafts =
            (params.shaft_budget > 0).then(|| oracle_shaft::Shafts::new(&occluders, &solids));
        let tracer = (params.shaft_budget > 0).then(|| crate::trace::Tracer::new(scene));
        let sealed = oracle_sealed::Sealed::new(scene, &solids, params.seal_voxels);
        let terrains = (0..scene.objects().len())
            .filter(|&i| {
                let o = &scene.objects()[i];
                o.flags.occludes() && !o.is_empty()
            })
            .collect::<Vec<_>>()
            .into_par_iter()
            .filter_map(|i| oracle_terrain::Terrain::detect(i as u32, scene.object_triangles(i)))
            .collect();
        Ok(Self {
            scene,
            occluders,
            solids,
            terrains,
            patches,
            clusters,
            counts,
            hierarchy: BoxTree::new(&boxes),
            shafts,
            tracer,
            sealed,
            params,
            rasteriser,
        })
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        self.scene
    }

    /// The settings.
    pub fn params(&self) -> &OracleParams {
        &self.params
    }

    /// Where the Depth Maps are rasterised.
    pub fn rasteriser(&self) -> &Rasteriser {
        &self.rasteriser
    }

    /// How the objects became occluders.
    pub fn occluder_counts(&self) -> OccluderCounts {
        self.counts
    }

    /// The number of convex occluders.
    pub fn occluder_count(&self) -> usize {
        self.occluders.len()
    }

    /// The number of objects that can be sliced (closed, or open only at
    /// the bottom).
    pub fn solid_count(&self) -> usize {
        self.solids.len()
    }

    /// The number of terrains: objects covering a rectangle of the ground
    /// once, used as solids from cells above them.
    pub fn terrain_count(&self) -> usize {
        self.terrains.len()
    }

    /// The grid of the free space between the solids (all zero when
    /// [`OracleParams::seal_voxels`] is 0 or the scene has no solid).
    pub fn sealed_counts(&self) -> SealedCounts {
        self.sealed.as_ref().map(|s| s.counts()).unwrap_or_default()
    }

    /// The objects that may be visible from some point of `cell`, the
    /// Depth Maps made by the oracle's [`Rasteriser`]. `parent_hidden`,
    /// the objects proved hidden from a cell holding this one, are taken
    /// as hidden and skipped as occluders.
    pub fn cell(&self, cell: &Aabb, parent_hidden: Option<&ObjectSet>) -> CellReport {
        self.cell_with(cell, parent_hidden, &mut |jobs| {
            self.rasteriser.rasterise_many(jobs)
        })
    }

    /// [`Oracle::cell`] with the Depth Maps made by `rasterise` instead
    /// (tests compare rasterisers this way): it gets all the cell's maps
    /// at once, each as a resolution and its occluders, and returns their
    /// level-0 maps in order (see [`cpu_rasterise`]).
    pub fn cell_with(
        &self,
        cell: &Aabb,
        parent_hidden: Option<&ObjectSet>,
        rasterise: &mut dyn FnMut(&[MapJob]) -> Vec<Vec<f64>>,
    ) -> CellReport {
        self.run(cell, parent_hidden, rasterise, None)
    }

    /// [`Oracle::cell`] for several cells at once, each with the objects
    /// proved hidden from a cell around it (or `None`): the same reports,
    /// in the same order, but every cell's Depth Maps are made in one call
    /// of the rasteriser (on the GPU, one submission for them all, where
    /// one cell's dozen maps are too little work to pay for a
    /// submission and its readback), and the cells' other work runs in
    /// parallel.
    pub fn cells(&self, cells: &[(Aabb, Option<&ObjectSet>)]) -> Vec<CellReport> {
        self.cells_with(cells, &mut |jobs| self.rasteriser.rasterise_many(jobs))
    }

    /// [`Oracle::cells`] with the Depth Maps made by `rasterise` (as for
    /// [`Oracle::cell_with`]: one call, every cell's maps in turn). Each
    /// report's rasterise time holds an equal share of that call.
    ///
    /// # Panics
    /// When `rasterise` returns another number of maps than it was given.
    pub fn cells_with(
        &self,
        cells: &[(Aabb, Option<&ObjectSet>)],
        rasterise: &mut dyn FnMut(&[MapJob]) -> Vec<Vec<f64>>,
    ) -> Vec<CellReport> {
        let prepared: Vec<Prepared> = cells
            .par_iter()
            .map(|(cell, hidden)| self.prepare(cell, *hidden, self.sweeps(false)))
            .collect();
        let n = self.params.resolution;
        let (mut jobs, mut counts) = (Vec::new(), Vec::with_capacity(prepared.len()));
        for p in &prepared {
            let here = match p {
                Prepared::Maps(pending) => pending.jobs(n),
                Prepared::Done(_) => Vec::new(),
            };
            counts.push(here.len());
            jobs.extend(here);
        }
        let start = Instant::now();
        let level0s = if jobs.is_empty() {
            Vec::new()
        } else {
            rasterise(&jobs)
        };
        assert_eq!(level0s.len(), jobs.len(), "one level-0 map per job");
        drop(jobs);
        let waiting = prepared
            .iter()
            .filter(|p| matches!(p, Prepared::Maps(_)))
            .count();
        let share = start.elapsed() / waiting.max(1) as u32;
        let mut level0s = level0s.into_iter();
        let work: Vec<(Prepared, Vec<Vec<f64>>)> = prepared
            .into_iter()
            .zip(counts)
            .map(|(p, k)| (p, level0s.by_ref().take(k).collect()))
            .collect();
        work.into_par_iter()
            .zip(cells.par_iter())
            .map(|((p, maps), (_, hidden))| {
                let report = match p {
                    Prepared::Done(report) => *report,
                    Prepared::Maps(pending) => self.finish(*pending, maps, share, *hidden, None),
                };
                self.settle(report)
            })
            .collect()
    }

    /// [`Oracle::cell`], and for each object it keeps, the slices proved
    /// hidden (papers/004 sec. 3) on the same maps and sweeps (never a
    /// slice box that touches the cell): per piece, the [`crate::slices::SliceIndex`] that
    /// culls the most of its triangles and how many, or `None` when no
    /// piece has any (in [`CellReport::slices`]).
    pub fn cell_slices(
        &self,
        cell: &Aabb,
        parent_hidden: Option<&ObjectSet>,
        sliced: &SlicedScene,
    ) -> CellReport {
        self.run(
            cell,
            parent_hidden,
            &mut |jobs| self.rasteriser.rasterise_many(jobs),
            Some(sliced),
        )
    }

    /// [`Oracle::prove`], with the objects flagged always visible kept
    /// whatever it proved, and the empty objects (no surface) hidden.
    fn run(
        &self,
        cell: &Aabb,
        parent_hidden: Option<&ObjectSet>,
        rasterise: &mut dyn FnMut(&[MapJob]) -> Vec<Vec<f64>>,
        sliced: Option<&SlicedScene>,
    ) -> CellReport {
        self.settle(self.prove(cell, parent_hidden, rasterise, sliced))
    }

    /// `report` with the objects flagged always visible kept and the empty
    /// objects hidden.
    fn settle(&self, mut report: CellReport) -> CellReport {
        for o in self.scene.always_visible() {
            report.visible.insert(o);
        }
        for o in self.scene.empty_objects() {
            report.visible.remove(o);
        }
        report
    }

    fn prove(
        &self,
        cell: &Aabb,
        parent_hidden: Option<&ObjectSet>,
        rasterise: &mut dyn FnMut(&[MapJob]) -> Vec<Vec<f64>>,
        sliced: Option<&SlicedScene>,
    ) -> CellReport {
        match self.prepare(cell, parent_hidden, self.sweeps(sliced.is_some())) {
            Prepared::Done(report) => *report,
            Prepared::Maps(pending) => {
                let start = Instant::now();
                let level0s = rasterise(&pending.jobs(self.params.resolution));
                let spent = start.elapsed();
                self.finish(*pending, level0s, spent, parent_hidden, sliced)
            }
        }
    }

    /// Whether a cell's proof runs the occlusion sweep: always with the
    /// shafts off; with them on, only where the slices of the objects kept
    /// are culled (`culls_slices`), which the shafts do not test: for
    /// whole objects the sweep hides next to none they do not prove, for
    /// much of a cell's time (notes/oracle.md, stop 49).
    fn sweeps(&self, culls_slices: bool) -> bool {
        self.shafts.is_none() || culls_slices
    }

    /// A cell's proof up to its Depth Maps: the free space, the solids it
    /// reaches into, each face's plane placement and sweep plan, and every
    /// map's occluders projected; or the whole report when there is nothing
    /// to rasterise. `sweep`: whether the occlusion sweep may run.
    fn prepare(&self, cell: &Aabb, parent_hidden: Option<&ObjectSet>, sweep: bool) -> Prepared {
        let objects = self.scene.objects().len();
        let (cmin, cmax) = (cell.min.as_dvec3(), cell.max.as_dvec3());
        if !(cmin.is_finite() && cmax.is_finite() && cmin.cmple(cmax).all()) {
            // Not a box (NaN, infinite, inside out): nothing is proved.
            return Prepared::Done(Box::new(CellReport {
                visible: ObjectSet::full(objects),
                hidden_by_parent: 0,
                touching: objects,
                planes: Vec::new(),
                sweep_planes: 0,
                sweep_hidden: 0,
                cluster_hidden: 0,
                shaft_hidden: 0,
                sealed_hidden: 0,
                inside_solids: 0,
                projected_from: *cell,
                times: CellTimes::default(),
                slices: Vec::new(),
            }));
        }
        let slack = self.slack(cmin, cmax);
        let mut times = CellTimes::default();
        let mut hidden = ObjectSet::new(objects);
        let mut hidden_by_parent = 0;
        if let Some(parent) = parent_hidden {
            for i in parent.iter().filter(|&i| i < objects) {
                hidden.insert(i);
                hidden_by_parent += 1;
            }
        }
        // Empty objects have no surface: hidden from the start, so that no
        // test meets their (empty) boxes.
        for i in self.scene.empty_objects() {
            hidden.insert(i);
        }
        // What no free path from the cell reaches.
        let start = Instant::now();
        let mut sealed_hidden = 0;
        if let Some(seen) = self.sealed.as_ref().and_then(|s| {
            s.visible(
                self.scene,
                &self.solids,
                &self.hierarchy,
                (cmin, cmax),
                slack,
            )
        }) {
            for i in (0..objects).filter(|&i| !seen.contains(i)) {
                if hidden.insert(i) {
                    sealed_hidden += 1;
                }
            }
        }
        times.select += start.elapsed();
        // The part of the cell inside closed convex solids sees only what
        // lies within them: project from the rest, keep what meets them.
        let start = Instant::now();
        let parent_hid = |o: &Occluder| hidden.contains(o.object as usize) || !o.usable(slack);
        let (cmin, cmax, inside, whole_inside) =
            match oracle_inside::reduce(&self.occluders, cmin, cmax, slack, &parent_hid) {
                oracle_inside::Reduced::Cell { min, max, solids } => (min, max, solids, false),
                oracle_inside::Reduced::Inside(i) => (cmin, cmax, vec![i], true),
            };
        // Solids the cell reaches into or touches (within the tracer's
        // rounding) are occluders from every face, clipped at each plane;
        // from a viewpoint inside or on such a solid, a segment to a point
        // inside it, or touching it, need not cross its surface. So what
        // meets their boxes (within the rounding) is kept, as is what meets
        // the solids cut off above.
        let pad = DVec3::splat(slack);
        let mut reached: Vec<usize> = inside.clone();
        for (i, o) in self.occluders.iter().enumerate() {
            if o.solid
                && !hidden.contains(o.object as usize)
                && (o.min - pad).cmple(cmax).all()
                && (o.max + pad).cmpge(cmin).all()
                && !reached.contains(&i)
            {
                reached.push(i);
            }
        }
        let mut keep = ObjectSet::new(objects);
        let mut near = Vec::new();
        for &i in &reached {
            let s = &self.occluders[i];
            let (smin, smax) = (s.min - pad, s.max + pad);
            // The hierarchy's candidates (f32 box rounded outwards), then
            // the exact test.
            let outward = Aabb::new(
                smin.as_vec3().map(f32::next_down),
                smax.as_vec3().map(f32::next_up),
            );
            near.clear();
            self.hierarchy.overlapping(&outward, &mut near);
            for &j in &near {
                let j = j as usize;
                let o = &self.scene.objects()[j];
                let (a, b) = (o.bounds.min.as_dvec3(), o.bounds.max.as_dvec3());
                if a.cmple(smax).all() && b.cmpge(smin).all() && !hidden.contains(j) {
                    keep.insert(j);
                }
            }
        }
        times.select += start.elapsed();
        let projected_from = Aabb::new(cmin.as_vec3(), cmax.as_vec3());
        if whole_inside {
            return Prepared::Done(Box::new(CellReport {
                visible: keep,
                hidden_by_parent,
                touching: 0,
                planes: Vec::new(),
                sweep_planes: 0,
                sweep_hidden: 0,
                cluster_hidden: 0,
                shaft_hidden: 0,
                sealed_hidden,
                inside_solids: 1,
                projected_from,
                times,
                slices: Vec::new(),
            }));
        }
        // Placement per face, then every map's occluders, rasterised in one
        // batch (one GPU submission), then the maps finished on the CPU.
        let mut faces: Vec<(Frame, Vec<f64>, FaceSetup, Vec<SweepStep>)> = Vec::new();
        // The six faces are independent: each on its own thread where
        // there are threads to spare (the results do not depend on it).
        let start = Instant::now();
        faces.extend(
            Frame::ALL
                .par_iter()
                .filter_map(|&frame| {
                    let mut t = CellTimes::default();
                    let (chosen, face) = self.plane(frame, cmin, cmax, parent_hidden, &mut t)?;
                    let steps = if sweep {
                        self.sweep_plan(frame, cmin, cmax, &face, &mut t)
                    } else {
                        Vec::new()
                    };
                    Some((frame, chosen, face, steps))
                })
                .collect::<Vec<_>>(),
        );
        times.select += start.elapsed();
        let start = Instant::now();
        let n = self.params.resolution;
        let placed_planes: Vec<(usize, f64)> = faces
            .iter()
            .enumerate()
            .flat_map(|(k, f)| f.1.iter().map(move |&wp| (k, wp)))
            .collect();
        let placed: Vec<Vec<ProjectedOccluder>> = placed_planes
            .par_iter()
            .map(|&(k, wp)| {
                let (frame, _, face, _) = &faces[k];
                let (lmin, lmax) = frame.local_box(cmin, cmax);
                self.project_occluders(
                    *frame,
                    &face.ranked,
                    self.params.max_occluders,
                    &face.eyes,
                    lmin,
                    lmax,
                    wp,
                    n,
                    self.plane_rect(lmin, lmax, wp),
                    f64::NEG_INFINITY,
                )
            })
            .collect();
        times.rasterise += start.elapsed();
        Prepared::Maps(Box::new(Pending {
            cmin,
            cmax,
            slack,
            times,
            hidden,
            hidden_by_parent,
            sealed_hidden,
            inside,
            keep,
            reached,
            projected_from,
            faces,
            placed_planes,
            placed,
        }))
    }

    /// The rest of a cell's proof once its maps (`level0s`, in the order of
    /// [`Pending::jobs`]) are rasterised, which took `spent`: the maps and
    /// sweeps finished, and every object tested on them, by clusters and by
    /// shafts.
    fn finish(
        &self,
        pending: Pending,
        level0s: Vec<Vec<f64>>,
        spent: Duration,
        parent_hidden: Option<&ObjectSet>,
        sliced: Option<&SlicedScene>,
    ) -> CellReport {
        let Pending {
            cmin,
            cmax,
            slack,
            mut times,
            mut hidden,
            hidden_by_parent,
            sealed_hidden,
            inside,
            keep,
            reached,
            projected_from,
            faces,
            placed_planes,
            placed,
        } = pending;
        let objects = self.scene.objects().len();
        let pad = DVec3::splat(slack);
        times.rasterise += spent;
        let start = Instant::now();
        let mut level0s = level0s.into_iter();
        let placed_level0s: Vec<Vec<f64>> = level0s.by_ref().take(placed.len()).collect();
        let (planes, maps): (Vec<PlaneReport>, Vec<(Frame, DepthMap, f64)>) = placed_planes
            .par_iter()
            .zip(placed.par_iter())
            .zip(placed_level0s)
            .map(|((&(k, wp), occluders), level0)| {
                let (frame, _, face, _) = &faces[k];
                let (lmin, lmax) = frame.local_box(cmin, cmax);
                let (map, report) = self.finish_placed(
                    *frame,
                    &face.solids,
                    lmin,
                    lmax,
                    wp,
                    occluders.len(),
                    level0,
                );
                (report, (*frame, map, wp))
            })
            .unzip();
        let mut planes = planes;
        let sweep_jobs: Vec<_> = faces
            .into_iter()
            .map(|(frame, _, face, steps)| {
                let level0: Vec<Vec<f64>> = level0s.by_ref().take(steps.len()).collect();
                (frame, face, steps, level0)
            })
            .collect();
        let sweeps: Vec<Sweep> = sweep_jobs
            .into_par_iter()
            .filter_map(|(frame, face, steps, level0)| {
                self.sweep_finish(frame, cmin, cmax, &face, steps, level0)
            })
            .collect();
        times.rasterise += start.elapsed();
        // Occludee tests: whole boxes per plane, through the hierarchy.
        let start = Instant::now();
        for (k, (frame, map, wp)) in maps.iter().enumerate() {
            let before = hidden.count();
            let (lmin, lmax) = frame.local_box(cmin, cmax);
            let test = |qmin: DVec3, qmax: DVec3| {
                let (a, b) = frame.local_box(qmin, qmax);
                box_hidden(map, lmin, lmax, a, b, *wp, slack)
            };
            self.hierarchy.mark_where(
                &|b: &Aabb| test(b.min.as_dvec3(), b.max.as_dvec3()),
                &mut hidden,
            );
            planes[k].hidden = hidden.count() - before;
        }
        // Boxes not hidden whole: cut into the pieces in front of each face;
        // then the sweeps, whole and in pieces.
        let on_maps = |pmin: DVec3, pmax: DVec3| {
            maps.iter().any(|(frame, map, wp)| {
                let (lmin, lmax) = frame.local_box(cmin, cmax);
                let (a, b) = frame.local_box(pmin, pmax);
                box_hidden(map, lmin, lmax, a, b, *wp, slack)
            })
        };
        let on_sweeps = |pmin: DVec3, pmax: DVec3| {
            oracle_sweep::sweep_hides(&sweeps, cmin, cmax, pmin, pmax, slack)
        };
        let skip_parent = |object: u32| parent_hidden.is_some_and(|h| h.contains(object as usize));
        let terrains: Vec<&oracle_terrain::Terrain> = self
            .terrains
            .iter()
            .filter(|t| !skip_parent(t.object) && t.usable(cmin, cmax, slack))
            .collect();
        let shaft_search = oracle_shaft::Search {
            occluders: &self.occluders,
            skip: &skip_parent,
            slack,
            budget: self.params.shaft_budget,
            depth: self.params.shaft_depth,
            terrains: &terrains,
        };
        // Each object on its own: 0 not hidden, 1 touching the cell, 2
        // hidden on the maps, 3 by the sweeps, 4 cluster by cluster, 5
        // shaft by shaft.
        let verdicts: Vec<u8> = self
            .scene
            .objects()
            .par_iter()
            .enumerate()
            .map(|(i, o)| {
                if hidden.contains(i) {
                    return 0;
                }
                let (qmin, qmax) = (o.bounds.min.as_dvec3(), o.bounds.max.as_dvec3());
                if qmin.cmple(cmax).all() && qmax.cmpge(cmin).all() {
                    return 1;
                }
                if pieces_hidden(&on_maps, cmin, cmax, qmin, qmax) {
                    return 2;
                }
                if !sweeps.is_empty()
                    && (on_sweeps(qmin, qmax)
                        || pieces_hidden(
                            &|a, b| on_maps(a, b) || on_sweeps(a, b),
                            cmin,
                            cmax,
                            qmin,
                            qmax,
                        ))
                {
                    return 3;
                }
                if let Some([a, b]) = self.clusters[i].first().and_then(|c| c.children) {
                    // The object's box failed: its clusters, from the halves.
                    let both = |x: DVec3, y: DVec3| on_maps(x, y) || on_sweeps(x, y);
                    let mut test = |x: DVec3, y: DVec3| {
                        !(x.cmple(cmax).all() && y.cmpge(cmin).all())
                            && pieces_hidden(&both, cmin, cmax, x, y)
                    };
                    let tree = &self.clusters[i];
                    if oracle_clusters::hidden_below(tree, a, &mut test)
                        && oracle_clusters::hidden_below(tree, b, &mut test)
                    {
                        return 4;
                    }
                }
                if let Some(shafts) = &self.shafts
                    && !self.witnessed(i, cmin, cmax)
                    && shafts.hidden(
                        &shaft_search,
                        i as u32,
                        &self.clusters[i],
                        (cmin, cmax),
                        qmin,
                        qmax,
                    )
                {
                    return 5;
                }
                0
            })
            .collect();
        let count = |v: u8| verdicts.iter().filter(|&&x| x == v).count();
        let (touching, sweep_hidden, cluster_hidden, shaft_hidden) =
            (count(1), count(3), count(4), count(5));
        for (i, &v) in verdicts.iter().enumerate() {
            if v >= 2 {
                hidden.insert(i);
            }
        }
        hidden.subtract(&keep);
        let mut visible = ObjectSet::full(objects);
        visible.subtract(&hidden);
        // Slices of the objects kept, on the same maps and sweeps: never a
        // slice box that touches the cell or meets a solid it reaches into
        // (whose objects are kept), but the pieces of an object that does
        // (a terrain under the cell) can be hidden.
        let mut slices = Vec::new();
        if let Some(sliced) = sliced {
            let both =
                |x: DVec3, y: DVec3| on_maps(x, y) || (!sweeps.is_empty() && on_sweeps(x, y));
            let reached_boxes: Vec<(DVec3, DVec3)> = reached
                .iter()
                .map(|&i| (self.occluders[i].min - pad, self.occluders[i].max + pad))
                .collect();
            slices = (0..objects)
                .into_par_iter()
                .map(|i| {
                    if !visible.contains(i) {
                        return None;
                    }
                    let o = &self.scene.objects()[i].bounds;
                    let (lo, hi) = (o.min.as_dvec3(), o.max.as_dvec3());
                    let slice_pad = slack + 1e-9 * (hi - lo).max_element();
                    let mut hidden = |a: DVec3, b: DVec3| {
                        let (a, b) = (a - slice_pad, b + slice_pad);
                        let meets = |(smin, smax): &(DVec3, DVec3)| {
                            a.cmple(*smax).all() && b.cmpge(*smin).all()
                        };
                        !meets(&(cmin, cmax))
                            && !reached_boxes.iter().any(meets)
                            && pieces_hidden(&both, cmin, cmax, a, b)
                    };
                    sliced.hidden_slices(i, &mut hidden)
                })
                .collect();
        }
        times.test = start.elapsed();
        CellReport {
            visible,
            hidden_by_parent,
            touching,
            planes,
            sweep_planes: sweeps.iter().map(|s| s.planes.len()).sum(),
            sweep_hidden,
            cluster_hidden,
            shaft_hidden,
            sealed_hidden,
            inside_solids: inside.len(),
            projected_from,
            times,
            slices,
        }
    }

    /// Places, fills and reduces one plane's Depth Map; `None` when no
    /// occluder lies in front of the face.
    fn plane(
        &self,
        frame: Frame,
        cmin: DVec3,
        cmax: DVec3,
        parent_hidden: Option<&ObjectSet>,
        times: &mut CellTimes,
    ) -> Option<(Vec<f64>, FaceSetup)> {
        let start = Instant::now();
        let (lmin, lmax) = frame.local_box(cmin, cmax);
        let centre = 0.5 * (lmin + lmax);
        let slack = self.slack(cmin, cmax);
        let skip = |o: &Occluder| {
            parent_hidden.is_some_and(|h| h.contains(o.object as usize)) || !o.usable(slack)
        };
        // Candidates: occluders starting strictly in front of the face,
        // ranked by the area of their view from the centre on the plane
        // one unit in front of it (a solid-angle measure).
        // Large scenes: a cheap bound from the occluder's box first (its
        // extents over the squared distance), keeping a generous shortlist
        // for the exact measure.
        let mut front: Vec<(f64, usize, DVec3, DVec3)> = Vec::new();
        for (i, o) in self.occluders.iter().enumerate() {
            if skip(o) {
                continue;
            }
            let (mut omin, omax) = frame.local_box(o.min, o.max);
            if omax.z <= lmax.z {
                continue;
            }
            if omin.z <= lmax.z {
                // A convex solid straddling the face's plane: its part in
                // front of the face occludes (clipped there when
                // projected), even when the cell reaches into it: a segment
                // from a viewpoint inside it to a point beyond it leaves it
                // through its surface, which the (two-sided) tracer hits
                // (what lies inside it or touches it is kept: see
                // `cell_with`). (Polygons
                // straddling the plane are left out: there are many in
                // meshes of small triangles, each costing its views on
                // every map, for little.)
                if !o.solid {
                    continue;
                }
                // Only within sixteen cell sizes of the cell's side: one
                // far to the side is seen at a grazing angle, its view
                // from the centre huge (it ranks first, crowding out
                // better occluders) and its umbra thin. Without this
                // limit the committed city's street cells took 93 ms and
                // kept 64.4 objects, with it 52 ms and 63.0.
                let reach = 16.0 * (lmax - lmin).max_element();
                if omin.x > lmax.x + reach
                    || omax.x < lmin.x - reach
                    || omin.y > lmax.y + reach
                    || omax.y < lmin.y - reach
                {
                    continue;
                }
                omin.z = lmax.z;
            }
            let e = omax - omin;
            let d = omin.z - centre.z;
            front.push(((e.x + e.z) * (e.y + e.z) / (d * d), i, omin, omax));
        }
        let shortlist = 4 * self
            .params
            .max_occluders
            .max(self.params.placement_occluders);
        if front.len() > shortlist {
            front.select_nth_unstable_by(shortlist, |a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            front.truncate(shortlist);
        }
        let mut ranked: Vec<(f64, usize, DVec3, DVec3)> = Vec::with_capacity(front.len());
        let mut scratch = Vec::new();
        let near = lmax.z + 1e-6 * (lmax.z - lmin.z).max(slack);
        let mut local = Vec::new();
        for (_, i, omin, omax) in front {
            local.clear();
            local.extend(self.occluders[i].points.iter().map(|&p| frame.local(p)));
            let straddles = local.iter().any(|p| p.z <= lmax.z);
            if straddles {
                match clip_above(&local, near) {
                    Some(c) => local = c,
                    None => continue,
                }
            }
            scratch.clear();
            scratch.extend(local.iter().map(|&p| project(centre, p, centre.z + 1.0)));
            // A polygon's corners are in order: its area needs no hull.
            let area = if self.occluders[i].solid || straddles {
                signed_area(&convex_hull(&mut scratch))
            } else {
                signed_area(&scratch).abs()
            };
            if area > 0.0 {
                ranked.push((area, i, omin, omax));
            }
        }
        // Solids to slice: away from the cell (so no viewpoint is inside),
        // and above the floor of those open at the bottom.
        let solids: Vec<(f64, usize, f64, f64)> = self
            .solids
            .iter()
            .enumerate()
            .filter(|(_, s)| {
                let hidden = parent_hidden.is_some_and(|h| h.contains(s.object as usize));
                // Within the tracer's rounding of the cell counts as
                // touching: a ray from a hair outside a face can start
                // past it (a review's counterexample: a cell one f32 step
                // short of a floorless building's wall saw into it).
                let pad = DVec3::splat(slack);
                let touching = (s.min - pad).cmple(cmax).all() && (s.max + pad).cmpge(cmin).all();
                !hidden && !touching && s.open_bottom.is_none_or(|floor| cmin.z > floor + slack)
            })
            .map(|(i, s)| {
                let (smin, smax) = frame.local_box(s.min, s.max);
                let e = smax - smin;
                let d = (smin.z - centre.z).max(lmax.z - centre.z);
                ((e.x + e.z) * (e.y + e.z) / (d * d), i, smin.z, smax.z)
            })
            .chain(
                self.terrains
                    .iter()
                    .enumerate()
                    .filter(|(_, t)| {
                        !parent_hidden.is_some_and(|h| h.contains(t.object as usize))
                            && t.usable(cmin, cmax, slack)
                    })
                    .map(|(k, t)| {
                        let (a, b) = frame.local_box(
                            DVec3::new(t.lo.x, t.lo.y, t.zmin),
                            DVec3::new(t.hi.x, t.hi.y, t.zmax),
                        );
                        // Ranked last: no plane is placed through it.
                        (0.0, self.solids.len() + k, a.z, b.z)
                    }),
            )
            .filter(|s| s.3 > lmax.z)
            .collect();
        if ranked.is_empty() && solids.is_empty() {
            times.select += start.elapsed();
            return None;
        }
        ranked.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let eyes: Vec<DVec3> = corners(lmin, lmax).to_vec();
        // Plane placement: just behind each of the largest occluders, and
        // through the middle of the largest solids in front of the face.
        let mut positions: Vec<f64> = ranked
            .iter()
            .take(self.params.plane_candidates)
            .map(|r| r.3.z)
            .collect();
        let mut by_size: Vec<&(f64, usize, f64, f64)> =
            solids.iter().filter(|s| s.2 > lmax.z).collect();
        by_size.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        positions.extend(
            by_size
                .iter()
                .take(self.params.plane_candidates / 2)
                .map(|s| 0.5 * (s.2 + s.3)),
        );
        // And at the crests of the terrains' ground in front of the face.
        for s in &solids {
            if let Some(t) = s.1.checked_sub(self.solids.len()) {
                positions.extend(self.terrains[t].crests(frame, cmin, cmax, 2));
            }
        }
        positions.sort_by(f64::total_cmp);
        positions.dedup();
        if positions.is_empty() {
            times.select += start.elapsed();
            return None;
        }
        let mut scored: Vec<(ObjectSet, usize, f64)> = Vec::with_capacity(positions.len());
        for &wp in &positions {
            let m = self.params.placement_resolution;
            let occ = self.project_occluders(
                frame,
                &ranked,
                self.params.placement_occluders,
                &eyes,
                lmin,
                lmax,
                wp,
                m,
                self.plane_rect(lmin, lmax, wp),
                f64::NEG_INFINITY,
            );
            let mut level0 = cpu_rasterise(m, &occ);
            let rect = self.plane_rect(lmin, lmax, wp);
            self.draw_slices(frame, &solids, rect, wp, m, slack, &mut level0);
            let filled = level0.iter().filter(|d| d.is_finite()).count();
            // The score: objects this plane alone hides at the low
            // resolution, then filled pixels (the paper's measure).
            let (rmin, rmax) = self.plane_rect(lmin, lmax, wp);
            let mut map = DepthMap::from_level0(rmin, rmax, m, level0);
            map.build_pyramid();
            let mut hidden = ObjectSet::new(self.scene.objects().len());
            let test = |qmin: DVec3, qmax: DVec3| {
                let (a, b) = frame.local_box(qmin, qmax);
                box_hidden_with(&map, lmin, lmax, a, b, wp, slack, false)
            };
            self.hierarchy.mark_where(
                &|b: &Aabb| test(b.min.as_dvec3(), b.max.as_dvec3()),
                &mut hidden,
            );
            scored.push((hidden, filled, wp));
        }
        // The best position, then (greedily) those that hide the most
        // objects the chosen ones do not.
        let mut chosen: Vec<f64> = Vec::new();
        let mut covered = ObjectSet::new(self.scene.objects().len());
        while chosen.len() < self.params.planes_per_face {
            let pick = scored
                .iter()
                .filter(|c| !chosen.contains(&c.2))
                .map(|c| {
                    let mut new = c.0.clone();
                    new.subtract(&covered);
                    ((new.count(), c.1), c)
                })
                .max_by(|a, b| a.0.cmp(&b.0).then(b.1.2.total_cmp(&a.1.2)));
            match pick {
                Some(((gain, _), c)) if gain > 0 || chosen.is_empty() => {
                    covered.union_with(&c.0);
                    chosen.push(c.2);
                }
                _ => break,
            }
        }
        times.select += start.elapsed();
        Some((
            chosen,
            FaceSetup {
                ranked,
                solids,
                eyes,
            },
        ))
    }

    /// The occlusion sweep away from one face (see `oracle_sweep.rs`),
    /// planned: planes at the largest axis-aligned patches in front of the
    /// face and spaced geometrically from the nearest occluder to the
    /// farthest, each with its rectangle and the convex occluders between
    /// it and the previous plane, projected; [`Oracle::sweep_finish`] makes
    /// the maps once these are rasterised. Empty when the sweep is off.
    fn sweep_plan(
        &self,
        frame: Frame,
        cmin: DVec3,
        cmax: DVec3,
        face: &FaceSetup,
        times: &mut CellTimes,
    ) -> Vec<SweepStep> {
        if self.params.sweep_planes == 0 && self.params.sweep_patches == 0 {
            return Vec::new();
        }
        let start = Instant::now();
        let (lmin, lmax) = frame.local_box(cmin, cmax);
        let centre = 0.5 * (lmin + lmax);
        let sign = if frame.positive { 1.0 } else { -1.0 };
        // Patch planes in front of the face by more than the tracer's
        // rounding (a review's counterexample: a floor one f32 step above
        // the face, where a ray from the face slants through the floor at
        // a t that rounds below 0 and goes on), largest solid angle first.
        let slack = self.slack(cmin, cmax);
        let mut at_patches: Vec<(f64, f64, usize)> = self
            .patches
            .iter()
            .enumerate()
            .filter(|(_, p)| p.axis == frame.axis && sign * p.coord > lmax.z + slack)
            .map(|(i, p)| {
                let d = sign * p.coord - centre.z;
                (p.area / (d * d), sign * p.coord, i)
            })
            .collect();
        at_patches.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.2.cmp(&b.2)));
        at_patches.truncate(self.params.sweep_patches);
        let mut positions: Vec<(f64, Option<usize>)> =
            at_patches.iter().map(|p| (p.1, Some(p.2))).collect();
        // Geometric planes from the nearest occluder to the farthest.
        let (mut near, mut far) = (f64::INFINITY, f64::NEG_INFINITY);
        for r in &face.ranked {
            near = near.min(r.2.z);
            far = far.max(r.3.z);
        }
        for s in &face.solids {
            far = far.max(s.3);
        }
        for p in &positions {
            near = near.min(p.0);
            far = far.max(p.0);
        }
        let side = (lmax - lmin).truncate().min_element();
        let first = (near - lmax.z).max(0.25 * side);
        let last = far - lmax.z;
        let g = self.params.sweep_planes;
        if g > 0 && first.is_finite() && last > first {
            for k in 1..=g {
                let d = first * (last / first).powf(k as f64 / g as f64);
                positions.push((lmax.z + d, None));
            }
        }
        // Geometric planes closer than a millionth of their distance to a
        // patch's plane or to the previous plane are dropped.
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * (a.max(b) - lmax.z);
        let patch_at: Vec<f64> = at_patches.iter().map(|p| p.1).collect();
        positions.retain(|p| p.1.is_some() || !patch_at.iter().any(|&w| close(w, p.0)));
        positions.sort_by(|a, b| a.0.total_cmp(&b.0));
        positions.dedup_by(|b, a| b.1.is_none() && close(a.0, b.0));
        let n = self.params.resolution;
        let mut steps: Vec<SweepStep> = Vec::with_capacity(positions.len());
        for &(wp, patch) in &positions {
            // The face grown by the extension, and all of the patch drawn
            // here, and where the previous plane's coverage can land.
            let grow = self.params.sweep_extension * (wp - lmax.z);
            let mut rect = (lmin.truncate() - grow, lmax.truncate() + grow);
            if let Some(i) = patch {
                rect = (
                    rect.0.min(self.patches[i].min),
                    rect.1.max(self.patches[i].max),
                );
            }
            if let Some(prev) = steps.last() {
                let (a, b) = oracle_sweep::image(prev.rect, prev.wp, lmin, lmax, wp);
                if a.cmplt(b).all() {
                    rect = (rect.0.min(a), rect.1.max(b));
                }
            }
            let after = steps.last().map_or(f64::NEG_INFINITY, |p| p.wp);
            let occluders = self.project_occluders(
                frame,
                &face.ranked,
                self.params.max_occluders,
                &face.eyes,
                lmin,
                lmax,
                wp,
                n,
                rect,
                after,
            );
            steps.push(SweepStep {
                wp,
                patch,
                rect,
                occluders,
            });
        }
        times.select += start.elapsed();
        steps
    }

    /// The sweep's maps from its plan and the rasterised occluders of its
    /// planes (`level0`, one per step): the cuts of solids and the patch of
    /// each plane, then the previous plane reprojected onto it. `None`
    /// when there is no plane.
    fn sweep_finish(
        &self,
        frame: Frame,
        cmin: DVec3,
        cmax: DVec3,
        face: &FaceSetup,
        steps: Vec<SweepStep>,
        level0: Vec<Vec<f64>>,
    ) -> Option<Sweep> {
        let (lmin, lmax) = frame.local_box(cmin, cmax);
        let n = self.params.resolution;
        let mut planes: Vec<SweepPlane> = Vec::with_capacity(steps.len());
        for (step, mut level0) in steps.into_iter().zip(level0) {
            let (wp, rect) = (step.wp, step.rect);
            let slack = self.slack(cmin, cmax);
            self.draw_slices(frame, &face.solids, rect, wp, n, slack, &mut level0);
            if let Some(i) = step.patch {
                oracle_patches::draw_patch(&mut level0, n, rect.0, rect.1, &self.patches[i]);
            }
            // The planes 1, 2, 4, ... back (`sweep_reach` of them; only
            // planes with something on them are kept, below), reprojected:
            // each is a bound of its own (a segment from the cell to this
            // plane crosses every earlier plane in its window), so the
            // smallest Depth of them all is one too.
            for back in (0..self.params.sweep_reach).map(|k| 1 << k) {
                let Some(prev) = planes.len().checked_sub(back).map(|i| &planes[i]) else {
                    break;
                };
                let carried =
                    oracle_sweep::reproject(&prev.map, prev.wp, lmin, lmax, wp, rect.0, rect.1, n);
                for (d, c) in level0.iter_mut().zip(carried) {
                    *d = d.min(c);
                }
            }
            // A plane with nothing on it proves nothing: the next one
            // reprojects the last plane that has something.
            if level0.iter().all(|d| d.is_infinite()) {
                continue;
            }
            let mut map = DepthMap::from_level0(rect.0, rect.1, n, level0);
            map.build_pyramid();
            planes.push(SweepPlane { map, wp });
        }
        (!planes.is_empty()).then_some(Sweep { frame, planes })
    }

    /// Finishes the full-resolution Depth Map of one placed plane from its
    /// rasterised occluders (`occluders` of them): the cuts of solids, the
    /// pyramid, the report.
    #[allow(clippy::too_many_arguments)]
    fn finish_placed(
        &self,
        frame: Frame,
        solids: &[(f64, usize, f64, f64)],
        lmin: DVec3,
        lmax: DVec3,
        wp: f64,
        occluders: usize,
        mut level0: Vec<f64>,
    ) -> (DepthMap, PlaneReport) {
        let n = self.params.resolution;
        let (rmin, rmax) = self.plane_rect(lmin, lmax, wp);
        let (wa, wb) = (frame.world(lmin), frame.world(lmax));
        let slack = self.slack(wa.min(wb), wa.max(wb));
        let sliced = self.draw_slices(frame, solids, (rmin, rmax), wp, n, slack, &mut level0);
        let mut map = DepthMap::from_level0(rmin, rmax, n, level0);
        map.build_pyramid();
        let report = PlaneReport {
            face: frame.name(),
            position: frame.world(DVec3::new(0.0, 0.0, wp))[frame.axis],
            occluders,
            slices: sliced,
            filled: map.filled(),
            hidden: 0,
        };
        (map, report)
    }

    /// Draws the cuts of the eligible solids (`(size, index, w min, w max)`;
    /// an index past the sliceable solids is a terrain's, counted on from
    /// them) that straddle the plane at `wp` into the `n` x `n` level-0
    /// map over the plane rectangle `rect`, at Depth 0, for a cell whose
    /// tracer slack is `slack`; returns how many solids were cut.
    #[allow(clippy::too_many_arguments)]
    fn draw_slices(
        &self,
        frame: Frame,
        solids: &[(f64, usize, f64, f64)],
        rect: (DVec2, DVec2),
        wp: f64,
        n: usize,
        slack: f64,
        level0: &mut [f64],
    ) -> usize {
        let (rmin, rmax) = rect;
        let Some(pixel) = oracle_plane::pixel_size(rect, n) else {
            return 0;
        };
        let mut count = 0;
        for &(_, i, w0, w1) in solids {
            if !(w0 < wp && wp < w1) {
                continue;
            }
            let Some(s) = self.solids.get(i) else {
                let t = &self.terrains[i - self.solids.len()];
                if t.draw(frame, wp, rect, n, slack, level0) > 0 {
                    count += 1;
                }
                continue;
            };
            let (smin, smax) = frame.local_box(s.min, s.max);
            if smax.x <= rmin.x || smax.y <= rmin.y || smin.x >= rmax.x || smin.y >= rmax.y {
                continue;
            }
            let Some(segments) = oracle_slice::slice_segments(s, frame, wp) else {
                continue;
            };
            let px: Vec<[DVec2; 2]> = segments
                .iter()
                .map(|seg| seg.map(|p| (p - rmin) / pixel))
                .collect();
            if oracle_slice::draw_slice(level0, n, &px, 0.0) > 0 {
                count += 1;
            }
        }
        count
    }

    /// How far behind the occluders an occludee must be to be hidden: the
    /// rounding of the f32 ray tracer the oracle is checked against, 8 ulps
    /// of the size of the scene and the cell together (diagonal plus
    /// largest coordinate). Closer than that, the tracer may report either
    /// hit first (a review found occludees one ulp behind a wall "hit").
    /// Whether one of a few segments from points of the cell to points of
    /// object `i`'s surface hits it first: seen, so the shafts need not
    /// try (a guide that only ever keeps an object). The points are drawn
    /// from a stream seeded by the cell and the object: the same answer
    /// whatever the thread count.
    fn witnessed(&self, i: usize, cmin: DVec3, cmax: DVec3) -> bool {
        use rand::{RngExt, SeedableRng};
        let Some(tracer) = &self.tracer else {
            return false;
        };
        let mut seed = 0xcbf2_9ce4_8422_2325u64;
        for x in [cmin.x, cmin.y, cmin.z, cmax.x, cmax.y, cmax.z] {
            seed = (seed ^ x.to_bits()).wrapping_mul(0x0000_0100_0000_01b3);
        }
        seed = (seed ^ i as u64).wrapping_mul(0x0000_0100_0000_01b3);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..oracle_shaft::WITNESSES).any(|_| {
            let u = DVec3::new(rng.random(), rng.random(), rng.random());
            let p = (cmin + (cmax - cmin) * u).as_vec3();
            let q = self.scene.sample_surface(i, &mut rng);
            let ray =
                crate::trace::Ray::segment(p, q).with_tmax(1.0 + crate::sample::SEGMENT_SLACK);
            ray.is_valid()
                && tracer
                    .closest_hit_towards(&ray, i as u32)
                    .is_some_and(|h| h.object as usize == i)
        })
    }

    fn slack(&self, cmin: DVec3, cmax: DVec3) -> f64 {
        tracer_slack(self.scene, cmin, cmax)
    }

    /// The plane rectangle at `wp`.
    fn plane_rect(&self, lmin: DVec3, lmax: DVec3, wp: f64) -> (DVec2, DVec2) {
        let grow = self.params.extension * (wp - lmax.z);
        (lmin.truncate() - grow, lmax.truncate() + grow)
    }

    /// The views of the `limit` largest occluders in front of the plane at
    /// `wp` (clipped to `w <= wp`) that reach beyond `w = after`, in the
    /// pixel coordinates of an `n` x `n` map over the plane rectangle
    /// `rect`.
    #[allow(clippy::too_many_arguments)]
    fn project_occluders(
        &self,
        frame: Frame,
        ranked: &[(f64, usize, DVec3, DVec3)],
        limit: usize,
        eyes: &[DVec3],
        lmin: DVec3,
        lmax: DVec3,
        wp: f64,
        n: usize,
        rect: (DVec2, DVec2),
        after: f64,
    ) -> Vec<ProjectedOccluder> {
        let (rmin, rmax) = rect;
        let Some(pixel) = oracle_plane::pixel_size(rect, n) else {
            return Vec::new();
        };
        let mut out = Vec::new();
        let mut points = Vec::new();
        let (wa, wb) = (frame.world(lmin), frame.world(lmax));
        let slack = self.slack(wa.min(wb), wa.max(wb));
        // An occluder's Projection lies in its view from the cell's centre,
        // whose area on this plane is its ranking area (on the plane one
        // unit from the centre) times the squared distance: once that is
        // under a pixel, it and every smaller one cover no whole pixel.
        let distance = wp - 0.5 * (lmin.z + lmax.z);
        let smallest = pixel.x * pixel.y / (distance * distance);
        let centre = 0.5 * (lmin + lmax);
        for &(area, i, omin, omax) in ranked {
            if out.len() >= limit || area < smallest {
                break;
            }
            if omin.z >= wp || omax.z <= after {
                continue;
            }
            // Its Projection lies in its box's view from the centre: off
            // the map, it is useless (checked before the 8 views).
            let (vlo, vhi) = corners(omin, omax).iter().fold(
                (DVec2::INFINITY, DVec2::NEG_INFINITY),
                |(a, b), &q| {
                    let x = project(centre, q, wp);
                    (a.min(x), b.max(x))
                },
            );
            if vhi.x <= rmin.x || vhi.y <= rmin.y || vlo.x >= rmax.x || vlo.y >= rmax.y {
                continue;
            }
            let o = &self.occluders[i];
            points.clear();
            points.extend(o.points.iter().map(|&p| frame.local(p)));
            // A polygon seen at a grazing angle: the tracer's rounding moves
            // a ray across its line by up to the slack, which moves its
            // crossing along the polygon's plane by that over the sine of
            // its angle to the plane (a review found rays a thousandth of a
            // radian from a triangle passing outside it where the exact
            // segment crosses inside). Its part inset by that much is
            // drawn; nothing when it vanishes.
            if !o.solid && !inset_for_rounding(&mut points, eyes, slack + o.tolerance()) {
                continue;
            }
            // Keep the part on the cell's side of the plane, and away from
            // the cell's face by a millionth of the plane's depth: a corner
            // almost on the face projects from the corners on the face to
            // near infinity, where clipping rounds away whole edges (a
            // review's counterexample). A convex part of a convex occluder
            // is still one. A solid or wall the cell's face touches (or
            // reaches into) still has views from the corners on the face
            // reaching near infinity: then the part from a twentieth of the
            // way to the plane onwards is tried, whose views stay bounded.
            let near = lmax.z + 1e-6 * (wp - lmin.z);
            let fallback = (lmax.z + 0.05 * (wp - lmax.z)).max(near);
            // Err(true): the views blew up (worth the fallback); Err(false):
            // nothing left, or a view seen edge-on.
            let attempt = |near: f64| -> Result<(Vec<Vec<DVec2>>, f64), bool> {
                let clipped = clip_below(&points, wp)
                    .and_then(|p| clip_above(&p, near))
                    .ok_or(false)?;
                let depth = clipped
                    .iter()
                    .map(|p| p.z)
                    .fold(f64::NEG_INFINITY, f64::max)
                    - wp;
                // Unclipped polygons keep their corners in order.
                let ordered = (!o.solid && clipped == points)
                    .then(|| ordered_views(&clipped, eyes, wp))
                    .flatten();
                let views = ordered.unwrap_or_else(|| occluder_views(&clipped, eyes, wp));
                if views.iter().any(|v| v.len() < 3) {
                    return Err(false);
                }
                // A safety net against the same: views reaching 1e8 pixels
                // away are dropped.
                let far = 1e8 * pixel.max_element();
                let wild = views.iter().flatten().any(|p| {
                    !(*p - rmin).abs().max_element().is_finite()
                        || (*p - rmin).abs().max_element() >= far
                });
                if wild { Err(true) } else { Ok((views, depth)) }
            };
            let lowest = points.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
            let (mut views, depth) = match attempt(near) {
                Ok(found) => found,
                Err(true) if lowest < fallback => match attempt(fallback) {
                    Ok(found) => found,
                    Err(_) => continue,
                },
                Err(_) => continue,
            };
            // Off the map entirely: useless.
            let (vlo, vhi) = views[0]
                .iter()
                .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
                    (a.min(p), b.max(p))
                });
            if vhi.x <= rmin.x || vhi.y <= rmin.y || vlo.x >= rmax.x || vlo.y >= rmax.y {
                continue;
            }
            for v in &mut views {
                for p in v.iter_mut() {
                    *p = (*p - rmin) / pixel;
                }
            }
            out.push(ProjectedOccluder { views, depth });
        }
        out
    }
}

/// Insets the convex planar polygon `points` (in order) within its plane
/// by `rounding` over the smallest sine of the angle between its plane and
/// a segment from one of `eyes` to one of its corners (the smallest over
/// the segments from the cell to the polygon: the share of a direction
/// along the normal is quasi-concave). A ray that the tracer moves by up
/// to `rounding` across its line still crosses the polygon where the exact
/// segment crosses the inset part. Returns false (`points` unchanged)
/// when nothing is left: a degenerate polygon, one seen edge-on from a
/// corner, or one thinner than twice the inset.
fn inset_for_rounding(points: &mut [DVec3], eyes: &[DVec3], rounding: f64) -> bool {
    let k = points.len();
    if k < 3 {
        return false;
    }
    let mut n = DVec3::ZERO;
    for i in 0..k {
        n += points[i].cross(points[(i + 1) % k]);
    }
    let Some(n) = n.try_normalize() else {
        return false;
    };
    let mut sine = f64::INFINITY;
    for &e in eyes {
        for &p in points.iter() {
            let d = p - e;
            sine = sine.min(n.dot(d).abs() / d.length());
        }
    }
    if sine.is_nan() || sine <= 0.0 {
        return false;
    }
    let inset = rounding / sine;
    // Each edge's line moved inwards; a corner where its two edges' lines
    // meet. The inward normal of edge `u -> v` is `n x (v - u)` (the
    // points run counter-clockwise about `n`).
    let lines: Vec<(DVec3, f64)> = (0..k)
        .map(|i| {
            let (u, v) = (points[i], points[(i + 1) % k]);
            let m = n.cross(v - u).normalize_or_zero();
            (m, m.dot(u) + inset)
        })
        .collect();
    let mut moved = Vec::with_capacity(k);
    for i in 0..k {
        let (a, ca) = lines[(i + k - 1) % k];
        let (b, cb) = lines[i];
        // The point of the plane through points[i] (n . x fixed) with
        // a . x = ca and b . x = cb.
        let cn = n.dot(points[i]);
        let det = a.dot(b.cross(n));
        let x = if det.abs() < 1e-9 {
            // Two edges in line: the corner moves straight in.
            points[i] + a * inset
        } else {
            (b.cross(n) * ca + n.cross(a) * cb + a.cross(b) * cn) / det
        };
        if !x.is_finite() {
            return false;
        }
        moved.push(x);
    }
    // Still the same polygon, smaller: every edge keeps its direction and
    // every corner is inside every moved line.
    for i in 0..k {
        let (u, v) = (moved[i], moved[(i + 1) % k]);
        if (v - u).dot(points[(i + 1) % k] - points[i]) <= 0.0 {
            return false;
        }
        if lines
            .iter()
            .any(|&(m, c)| m.dot(u) < c - 1e-9 * inset.max(1e-300))
        {
            return false;
        }
    }
    points.copy_from_slice(&moved);
    true
}

/// One plane of a planned sweep: its position, the patch lying in it, its
/// rectangle and its convex occluders, projected.
struct SweepStep {
    wp: f64,
    patch: Option<usize>,
    rect: (DVec2, DVec2),
    occluders: Vec<ProjectedOccluder>,
}

/// A cell's proof before or without its maps ([`Oracle::prepare`]).
enum Prepared {
    /// Nothing to rasterise: the report.
    Done(Box<CellReport>),
    /// Maps to rasterise, then [`Oracle::finish`].
    Maps(Box<Pending>),
}

/// What [`Oracle::prepare`] leaves for [`Oracle::finish`]: the cell the
/// projections run from and the tracer's slack, what is hidden or kept so
/// far, and each face's planes and sweep steps with their occluders
/// projected.
struct Pending {
    cmin: DVec3,
    cmax: DVec3,
    slack: f64,
    times: CellTimes,
    hidden: ObjectSet,
    hidden_by_parent: usize,
    sealed_hidden: usize,
    inside: Vec<usize>,
    keep: ObjectSet,
    reached: Vec<usize>,
    projected_from: Aabb,
    faces: Vec<(Frame, Vec<f64>, FaceSetup, Vec<SweepStep>)>,
    placed_planes: Vec<(usize, f64)>,
    placed: Vec<Vec<ProjectedOccluder>>,
}

impl Pending {
    /// Its maps to rasterise at `n` x `n` pixels: the placed planes', then
    /// each face's sweep steps'.
    fn jobs(&self, n: usize) -> Vec<MapJob<'_>> {
        self.placed
            .iter()
            .map(|o| (n, o.as_slice()))
            .chain(
                self.faces
                    .iter()
                    .flat_map(|f| f.3.iter().map(|s| (n, s.occluders.as_slice()))),
            )
            .collect()
    }
}

/// What one face's plane placement found, for its sweep: the occluders in
/// front of the face (`(size, index, box min, box max)`, frame
/// coordinates, largest first), the solids to slice (`(size, index, w
/// min, w max)`: sliceable solids by their index, then terrains numbered
/// on from them, see [`Oracle::draw_slices`]) and the cell's corners.
struct FaceSetup {
    ranked: Vec<(f64, usize, DVec3, DVec3)>,
    solids: Vec<(f64, usize, f64, f64)>,
    eyes: Vec<DVec3>,
}

/// Whether the box `[qmin, qmax]` (frame coordinates) is proved hidden on
/// the plane `w = wp` whose Depth Map is `map`, from the cell `[lmin, lmax]`.
#[allow(clippy::too_many_arguments)]
fn box_hidden(
    map: &DepthMap,
    lmin: DVec3,
    lmax: DVec3,
    qmin: DVec3,
    qmax: DVec3,
    wp: f64,
    slack: f64,
) -> bool {
    box_hidden_with(map, lmin, lmax, qmin, qmax, wp, slack, true)
}

/// [`box_hidden`], trying the exact polygon behind the plane only when
/// `polygon` (plane placement scores positions without it).
#[allow(clippy::too_many_arguments)]
fn box_hidden_with(
    map: &DepthMap,
    lmin: DVec3,
    lmax: DVec3,
    qmin: DVec3,
    qmax: DVec3,
    wp: f64,
    slack: f64,
    polygon: bool,
) -> bool {
    if qmin.z <= lmax.z {
        return false;
    }
    // Behind the occluders by more than the tracer's rounding: an f32 ray
    // cannot then order the two hits the other way.
    let depth = qmin.z - wp - slack;
    let (lo, hi) = occludee_rect(lmin, lmax, qmin, qmax, wp);
    let failed = match map.test_rect(lo, hi, depth) {
        Ok(()) => return true,
        Err(pixel) => pixel,
    };
    // Behind the plane, the exact Projection is a convex polygon, often
    // much less than its rectangle (a cell seeing the box at a slant);
    // tried unless the pixel that failed the rectangle is one of its own.
    if polygon && qmin.z >= wp {
        let poly = occludee_polygon(lmin, lmax, qmin, qmax, wp);
        if failed.is_none_or(|p| !map.pixel_meets_polygon(p, &poly))
            && map.hides_polygon(&poly, depth)
        {
            return true;
        }
    }
    if qmax.z <= wp
        && let Some((lo, hi)) = improved_rect(lmin, lmax, qmin, qmax, wp)
    {
        return map.hides(lo, hi, depth);
    }
    false
}

/// Whether `hides` proves every piece of the box `[qmin, qmax]` (world,
/// disjoint from the cell) hidden (on some plane it lies in front of). The box is cut along
/// each axis at the cell's slab (a hair outside it, so that each outer
/// piece lies strictly in front of that side's face and the middle piece
/// stays strictly in front of the faces the whole box was in front of).
fn pieces_hidden(
    hides: &dyn Fn(DVec3, DVec3) -> bool,
    cmin: DVec3,
    cmax: DVec3,
    qmin: DVec3,
    qmax: DVec3,
) -> bool {
    let hair = 1e-9
        * (cmax - cmin)
            .max_element()
            .max((qmax - qmin).max_element())
            .max(1e-30);
    let cuts = |k: usize| -> Vec<(f64, f64)> {
        let (a, b) = (cmin[k] - hair, cmax[k] + hair);
        let mut out = Vec::new();
        if qmin[k] < a {
            out.push((qmin[k], a.min(qmax[k])));
        }
        if qmax[k] >= a && qmin[k] <= b {
            out.push((qmin[k].max(a), qmax[k].min(b)));
        }
        if qmax[k] > b {
            out.push((b.max(qmin[k]), qmax[k]));
        }
        out
    };
    let (xs, ys, zs) = (cuts(0), cuts(1), cuts(2));
    for &(x0, x1) in &xs {
        for &(y0, y1) in &ys {
            for &(z0, z1) in &zs {
                let (pmin, pmax) = (DVec3::new(x0, y0, z0), DVec3::new(x1, y1, z1));
                if !hides(pmin, pmax) {
                    return false;
                }
            }
        }
    }
    true
}
