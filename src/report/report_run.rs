//! The experiment of a report: every view rendered for its ground truth,
//! then culled by every method, each method timed and measured.

use std::time::Instant;

use super::report_image::{DRAWN_SIDE, Layers};
use super::report_metrics::{MethodSummary, ViewMetrics, ViewTruth, frustum_set, truth_of};
use crate::bitset::ObjectSet;
use crate::geom::Aabb;
use crate::lazy_grid::{GridParams, LazyGrid};
use crate::oracle::Oracle;
use crate::query::{Pvs, View};
use crate::render::{Camera, IdBuffer};
use crate::scene::Scene;
use crate::shrink::ShrinkOracle;
use crate::slices::{HiddenSlices, SlicedScene};
use crate::trace::Tracer;

/// A visibility method a report compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// View-frustum culling: the objects whose bounding box meets the
    /// frustum.
    Frustum,
    /// The vis5d tree (a `.v5d`) queried per view, then frustum culling.
    Tree,
    /// A conservative vis5d tree (`vis5d build --conservative`) queried
    /// the same way, beside the sampled one.
    ConservativeTree,
    /// The lazy occlusion grid of papers/002 (online, from the eye).
    LazyGrid,
    /// The extended-projection oracle of a cube around the eye, within the
    /// frustum.
    Oracle,
    /// Occluder shrinking (papers/004) for the same cube, within the
    /// frustum.
    Shrink,
    /// What neither the oracle nor the shrinking proves hidden: the union
    /// of what each does, since each proves what the other cannot.
    Both,
}

impl Method {
    /// Every method, in the report's order.
    pub const ALL: [Method; 7] = [
        Method::Frustum,
        Method::Tree,
        Method::ConservativeTree,
        Method::LazyGrid,
        Method::Oracle,
        Method::Shrink,
        Method::Both,
    ];

    /// The method's name in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Method::Frustum => "frustum",
            Method::Tree => "vis5d",
            Method::ConservativeTree => "conservative tree",
            Method::LazyGrid => "lazy grid",
            Method::Oracle => "oracle",
            Method::Shrink => "shrinking",
            Method::Both => "oracle and shrinking",
        }
    }

    /// One sentence saying what the method draws.
    pub fn description(self) -> &'static str {
        match self {
            Method::Frustum => "view-frustum culling: objects whose bounding box meets the frustum",
            Method::Tree => {
                "the vis5d tree (.v5d) queried per view (Pvs::query_view: the leaf sets of the \
                 view's directions, culled to its frustum with the object bounds the file stores)"
            }
            Method::ConservativeTree => {
                "a conservative vis5d tree (vis5d build --conservative: the extended-projection \
                 oracle's sets over a spatial tree of view cells) queried per view the same way"
            }
            Method::LazyGrid => {
                "the lazy occlusion grid of papers/002: an occlusion buffer with a grid of cells \
                 updated lazily, object boxes front to back (online, from the eye)"
            }
            Method::Oracle => {
                "the extended-projection oracle of a cube around the eye, within the frustum"
            }
            Method::Shrink => {
                "occluder shrinking (papers/004) for the same cube: closed solids shrunk by its \
                 half diagonal, objects tested from its centre, within the frustum"
            }
            Method::Both => {
                "what neither the oracle nor the shrinking proves hidden (each proves what the \
                 other cannot), within the frustum; its time is the sum of theirs"
            }
        }
    }
}

/// Settings of a report's experiment.
#[derive(Clone, Debug, PartialEq)]
pub struct ReportParams {
    /// Pixels on a side of the ground-truth images (and of the lazy grid's
    /// occlusion buffer).
    pub resolution: u32,
    /// Cell side of the lazy occlusion grid, in pixels (papers/002: 32).
    pub grid_cell: u32,
    /// Side of the oracle's cube around each eye, as a share of the
    /// scene's diagonal.
    pub oracle_cell: f32,
    /// Slices an axis (papers/004 sec. 3) for the oracles' rows: each
    /// kept object's hidden slices are culled too, and the triangles drawn
    /// at slice granularity reported beside those at object granularity
    /// (0: none; at most 255).
    pub slices: usize,
    /// The first this many views keep their ID buffers
    /// ([`Experiment::pictures`]), for the report's pictures (0: none; at
    /// most [`ReportParams::MAX_PICTURES`]).
    pub pictures: usize,
}

impl Default for ReportParams {
    fn default() -> Self {
        Self {
            resolution: 512,
            grid_cell: 32,
            oracle_cell: 0.01,
            slices: 0,
            pictures: 8,
        }
    }
}

impl ReportParams {
    /// The most views pictured.
    pub const MAX_PICTURES: usize = 1000;

    /// Checks the settings; the error names the bad one.
    pub fn validate(&self) -> Result<(), ReportError> {
        let bad = |name, expected, value: &dyn std::fmt::Display| ReportError::Parameter {
            name,
            expected,
            value: value.to_string(),
        };
        if !(1..=8192).contains(&self.resolution) {
            return Err(bad("resolution", "between 1 and 8192", &self.resolution));
        }
        if self.grid_cell == 0 || self.grid_cell > self.resolution {
            return Err(bad(
                "grid_cell",
                "between 1 and the resolution",
                &self.grid_cell,
            ));
        }
        if self.pictures > Self::MAX_PICTURES {
            return Err(bad("pictures", "between 0 (none) and 1000", &self.pictures));
        }
        if self.slices > crate::slices::MAX_SLICES {
            return Err(bad("slices", "between 0 (none) and 255", &self.slices));
        }
        if !(self.oracle_cell.is_finite() && self.oracle_cell > 0.0) {
            return Err(bad(
                "oracle_cell",
                "a positive share of the scene's diagonal",
                &self.oracle_cell,
            ));
        }
        Ok(())
    }
}

/// Why a report cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ReportError {
    /// A setting is outside its domain.
    #[error("invalid report setting: {name} must be {expected}, not {value}")]
    Parameter {
        /// The setting.
        name: &'static str,
        /// What it must be.
        expected: &'static str,
        /// What it was.
        value: String,
    },
    /// No view to report on.
    #[error("no views to report on: give a camera path with views, or ask for random ones")]
    NoViews,
    /// A view has no camera frame.
    #[error(
        "view {index} is degenerate (a zero direction, an up vector along it, or a field of view \
         outside (0, 180) degrees): fix or remove it"
    )]
    DegenerateView {
        /// The view's index.
        index: usize,
    },
    /// The tree was built for other geometry.
    #[error(
        "the tree was built for another scene (geometry fingerprint {file:016x}, the scene's is \
         {scene:016x}): rebuild it with `vis5d build`"
    )]
    WrongScene {
        /// The tree's fingerprint.
        file: u64,
        /// The scene's.
        scene: u64,
    },
}

/// One method's results over the views.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodRun {
    /// The method.
    pub method: Method,
    /// Per view, its figures.
    pub per_view: Vec<ViewMetrics>,
    /// Per view, the objects seen but not drawn.
    pub missed: Vec<Vec<u32>>,
    /// The sets drawn in the first [`ReportParams::pictures`] views, for
    /// the pictures of what the method draws.
    pub pictured: Vec<ObjectSet>,
    /// How many sets `pictured` keeps.
    keep: usize,
}

impl MethodRun {
    /// A run keeping the sets of its first `keep` views.
    fn new(method: Method, keep: usize) -> Self {
        Self {
            method,
            per_view: Vec::new(),
            missed: Vec::new(),
            pictured: Vec::new(),
            keep,
        }
    }

    /// Records the set `drawn` of one view, taking `seconds`.
    fn record(&mut self, scene: &Scene, truth: &ViewTruth, drawn: &ObjectSet, seconds: f64) {
        if self.pictured.len() < self.keep {
            self.pictured.push(drawn.clone());
        }
        self.per_view
            .push(ViewMetrics::of(scene, truth, drawn, seconds));
        self.missed.push(
            truth
                .seen
                .iter()
                .map(|&(o, _)| o)
                .filter(|&o| !drawn.contains(o as usize))
                .collect(),
        );
    }

    /// [`MethodRun::record`], with the triangles drawn at slice
    /// granularity when `with_slices`: the drawn objects' triangles less
    /// what `slices` (per object, the hidden slices and the triangles they
    /// cull) culls.
    fn record_slices(
        &mut self,
        scene: &Scene,
        truth: &ViewTruth,
        drawn: &ObjectSet,
        seconds: f64,
        slices: &[Option<HiddenSlices>],
        with_slices: bool,
    ) {
        self.record(scene, truth, drawn, seconds);
        if with_slices {
            let culled: u64 = drawn
                .iter()
                .filter_map(|o| slices.get(o).and_then(Option::as_ref))
                .map(|h| h.culled() as u64)
                .sum();
            let last = self.per_view.last_mut().expect("just recorded");
            last.slice_triangles = Some(last.triangles - culled);
        }
    }

    /// The method's figures over the views, its geometry ratio against
    /// `frustum` (the frustum culling's run of the same views).
    pub fn summary(&self, frustum: &MethodRun) -> MethodSummary {
        MethodSummary::of(&self.per_view, &frustum.per_view, &self.missed)
    }
}

/// The lazy grid's costs for one view, lazy and busy (papers/002 Fig. 8).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct GridCost {
    /// Pixel-level queries with lazy updates.
    pub lazy_pixel_queries: u64,
    /// Pixel-level queries with busy updates.
    pub busy_pixel_queries: u64,
    /// Whole-cell updates with lazy updates.
    pub lazy_cell_updates: u64,
    /// Whole-cell updates with busy updates.
    pub busy_cell_updates: u64,
    /// Boxes of the hierarchy tested.
    pub boxes_tested: u64,
    /// Milliseconds of the lazy pass.
    pub lazy_ms: f64,
    /// Milliseconds of the busy pass.
    pub busy_ms: f64,
}

/// Everything a report measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Experiment {
    /// Per view, the ground truth.
    pub truths: Vec<ViewTruth>,
    /// The ID buffers of the first [`ReportParams::pictures`] views.
    pub pictures: Vec<IdBuffer>,
    /// The same views' [`Layers`], at most [`DRAWN_SIDE`] pixels a side:
    /// what each method draws there ([`super::drawn_picture`] with
    /// [`MethodRun::pictured`]).
    pub layers: Vec<Layers>,
    /// Seconds spent rendering the ground truth, all views.
    pub truth_seconds: f64,
    /// Per method, in [`Method::ALL`] order (the oracle only when one was
    /// given).
    pub methods: Vec<MethodRun>,
    /// Per view, the lazy grid's costs lazy and busy.
    pub grid_costs: Vec<GridCost>,
    /// The oracle's cube side, in scene units (when it ran).
    pub oracle_cell: Option<f32>,
    /// Where the oracle's Depth Maps were rasterised ("CPU", or "GPU: "
    /// and the adapter), when it ran.
    pub oracle_rasteriser: Option<String>,
}

impl Experiment {
    /// The run of `method`, if it ran.
    pub fn method(&self, method: Method) -> Option<&MethodRun> {
        self.methods.iter().find(|m| m.method == method)
    }

    /// The frustum culling's run, the reference of geometry ratios.
    pub fn frustum(&self) -> &MethodRun {
        self.method(Method::Frustum)
            .expect("frustum culling always runs")
    }
}

/// The trees a report compares: the one of the "vis5d" row, and a
/// conservative one (`vis5d build --conservative`) beside it.
#[derive(Clone, Copy)]
pub struct Trees<'a> {
    /// The tree of the "vis5d" row.
    pub tree: &'a Pvs,
    /// The tree of the "conservative tree" row, when there is one.
    pub conservative: Option<&'a Pvs>,
}

/// The conservative oracles a report runs for a cube around each eye.
#[derive(Clone, Copy, Default)]
pub struct Oracles<'a, 'b> {
    /// The extended-projection oracle (papers/001).
    pub oracle: Option<&'a Oracle<'b>>,
    /// Occluder shrinking (papers/004).
    pub shrink: Option<&'a ShrinkOracle<'b>>,
}

/// Runs the experiment on `views` of `scene` (traced by `tracer`): for
/// each view, the ground truth ([`truth_of`] of its ID buffer), then every method: frustum
/// culling, the trees (built for `scene`), the lazy grid (lazy, then busy for its costs), and the
/// `oracles` given (and their intersection when both are). `progress` gets the
/// number of views done.
pub fn run(
    scene: &Scene,
    tracer: &Tracer,
    trees: Trees,
    oracles: Oracles,
    views: &[View],
    params: &ReportParams,
    progress: &dyn Fn(usize),
) -> Result<Experiment, ReportError> {
    params.validate()?;
    if views.is_empty() {
        return Err(ReportError::NoViews);
    }
    let Trees {
        tree: pvs,
        conservative,
    } = trees;
    let Oracles { oracle, shrink } = oracles;
    for tree in std::iter::once(pvs).chain(conservative) {
        tree.check_fingerprint(scene.fingerprint())
            .map_err(|e| ReportError::WrongScene {
                file: e.file,
                scene: e.scene,
            })?;
    }
    let cameras: Vec<Camera> = views
        .iter()
        .enumerate()
        .map(|(index, v)| {
            Camera::new(v, params.resolution, params.resolution)
                .ok_or(ReportError::DegenerateView { index })
        })
        .collect::<Result<_, _>>()?;
    let half = 0.5 * params.oracle_cell * scene.bounds().diagonal();
    let n = scene.objects().len();
    let mut runs: Vec<MethodRun> = Method::ALL
        .iter()
        .filter(|&&m| m != Method::Oracle || oracle.is_some())
        .filter(|&&m| m != Method::Shrink || shrink.is_some())
        .filter(|&&m| m != Method::Both || (oracle.is_some() && shrink.is_some()))
        .filter(|&&m| m != Method::ConservativeTree || conservative.is_some())
        .map(|&m| MethodRun::new(m, params.pictures))
        .collect();
    let grid = LazyGrid::new(scene);
    let sliced = if params.slices > 0 && (oracle.is_some() || shrink.is_some()) {
        Some(
            SlicedScene::new(scene, params.slices).map_err(|e| ReportError::Parameter {
                name: "slices",
                expected: "a scene whose objects can be sliced",
                value: e.to_string(),
            })?,
        )
    } else {
        None
    };
    let mut out = Experiment {
        truths: Vec::with_capacity(views.len()),
        pictures: Vec::new(),
        layers: Vec::new(),
        truth_seconds: 0.0,
        methods: Vec::new(),
        grid_costs: Vec::with_capacity(views.len()),
        oracle_cell: (oracle.is_some() || shrink.is_some()).then_some(2.0 * half),
        oracle_rasteriser: oracle.map(|o| o.rasteriser().name()),
    };
    let (mut set, mut frustum) = (ObjectSet::new(n), ObjectSet::new(n));
    for (i, (view, camera)) in views.iter().zip(&cameras).enumerate() {
        let start = Instant::now();
        let ids = IdBuffer::render(tracer, camera);
        let t = truth_of(scene, &ids);
        out.truth_seconds += start.elapsed().as_secs_f64();
        if i < params.pictures {
            out.pictures.push(ids);
            let side = params.resolution.min(DRAWN_SIDE);
            let small =
                Camera::new(view, side, side).ok_or(ReportError::DegenerateView { index: i })?;
            out.layers.push(Layers::render(tracer, &small));
        }

        let start = Instant::now();
        frustum_set(scene, view, &mut frustum);
        let frustum_seconds = start.elapsed().as_secs_f64();
        run_of(&mut runs, Method::Frustum).record(scene, &t, &frustum, frustum_seconds);

        // The tree's answer as a user gets it: the leaf sets of the
        // view's directions, culled to its frustum by the query.
        // A tree whose file has slices answers triangle ranges too.
        for (tree, method) in std::iter::once((pvs, Method::Tree))
            .chain(conservative.map(|c| (c, Method::ConservativeTree)))
        {
            let start = Instant::now();
            // Both trees were checked to be the scene's (its fingerprint):
            // the set, made for the scene's objects, is of their size.
            const SAME: &str = "a tree of the scene answers into a set of its size";
            let ranges = if tree.slices().is_some() {
                Some(tree.query_view_triangles(view, &mut set).expect(SAME))
            } else {
                tree.query_view(view, &mut set).expect(SAME);
                None
            };
            let s = start.elapsed().as_secs_f64();
            let run = run_of(&mut runs, method);
            run.record(scene, &t, &set, s);
            if let Some(ranges) = ranges {
                let last = run.per_view.last_mut().expect("just recorded");
                last.slice_triangles = Some(ranges.iter().map(|r| r.count()).sum());
            }
        }

        let mut grid_params = GridParams {
            cell_pixels: params.grid_cell,
            lazy: true,
        };
        let start = Instant::now();
        let lazy = grid.cull(camera, &grid_params, &mut set);
        let lazy_seconds = start.elapsed().as_secs_f64();
        run_of(&mut runs, Method::LazyGrid).record(scene, &t, &set, lazy_seconds);
        grid_params.lazy = false;
        let start = Instant::now();
        let busy = grid.cull(camera, &grid_params, &mut set);
        out.grid_costs.push(GridCost {
            lazy_pixel_queries: lazy.pixel_queries,
            busy_pixel_queries: busy.pixel_queries,
            lazy_cell_updates: lazy.cell_updates,
            busy_cell_updates: busy.cell_updates,
            boxes_tested: lazy.boxes_tested,
            lazy_ms: 1e3 * lazy_seconds,
            busy_ms: 1e3 * start.elapsed().as_secs_f64(),
        });

        let cell = Aabb::new(view.position - half, view.position + half);
        let mut extended = None;
        if let Some(oracle) = oracle {
            let start = Instant::now();
            let r = match &sliced {
                Some(sl) => oracle.cell_slices(&cell, None, sl),
                None => oracle.cell(&cell, None),
            };
            let mut kept = r.visible;
            kept.intersect_with(&frustum);
            let s = start.elapsed().as_secs_f64() + frustum_seconds;
            run_of(&mut runs, Method::Oracle).record_slices(
                scene,
                &t,
                &kept,
                s,
                &r.slices,
                sliced.is_some(),
            );
            extended = Some((kept, s, r.slices));
        }
        if let Some(shrink) = shrink {
            let start = Instant::now();
            let r = match &sliced {
                Some(sl) => shrink.cell_slices(&cell, sl),
                None => shrink.cell(&cell),
            };
            let mut kept = r.visible;
            kept.intersect_with(&frustum);
            let s = start.elapsed().as_secs_f64() + frustum_seconds;
            run_of(&mut runs, Method::Shrink).record_slices(
                scene,
                &t,
                &kept,
                s,
                &r.slices,
                sliced.is_some(),
            );
            if let Some((mut both, s0, mut slices)) = extended {
                both.intersect_with(&kept);
                crate::slices::keep_the_larger(&mut slices, r.slices);
                run_of(&mut runs, Method::Both).record_slices(
                    scene,
                    &t,
                    &both,
                    s0 + s,
                    &slices,
                    sliced.is_some(),
                );
            }
        }
        out.truths.push(t);
        progress(i + 1);
    }
    out.methods = runs;
    Ok(out)
}

/// The run of `method` among `runs`.
fn run_of(runs: &mut [MethodRun], method: Method) -> &mut MethodRun {
    runs.iter_mut()
        .find(|r| r.method == method)
        .expect("every method that runs has a run")
}
