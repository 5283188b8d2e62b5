//! The builder: the 5D k-d tree of visible sets of papers/003 sec. 4-5,
//! built by ray sampling.
//!
//! Recursively, for a cell C with candidate objects (the parent's set; all
//! objects at the root):
//! 1. top up C's cache of uniform cell rays (those of the parent that fall
//!    in C are kept: the paper's "re-use rays cast to determine an inner
//!    node's partitioning", sec. 9) and trace them; every object a cached
//!    ray hits is proven visible (`builder_node.rs`). The object samples
//!    that C's ancestors traced and that fall in C are rays of C too
//!    ([`BuildParams::inherit_samples`]): what they hit is proven, and
//!    their owners' misses count in the owners' tests;
//! 2. decide the other candidates by the SPRT on object samples
//!    (`builder_leaf.rs`): C's set.
//!    A leaf then retests objects its ancestors dropped near what its rays
//!    hit, and casts edge rays past the triangles its rays hit
//!    (`builder_edges.rs`, after GVS's border sampling); both only add
//!    objects a ray hit. Each leaf keeps a [`LeafRecord`](crate::tree::LeafRecord)
//!    of what its rejections rest on;
//! 3. stop on the depth limit, on too few visible triangles (the paper's
//!    "split only if at least 500 polygons are visible"), or when no
//!    candidate split scores E(A, B) above the threshold
//!    (`builder_split.rs`); otherwise split, hand each child its half of the
//!    cache and of the object samples, and C's set as candidates, build both in parallel, and make C's
//!    set the union of theirs.
//!
//! With `spatial_only`, only x, y, z are split, and each final cell is cut
//! into `angular_leaves` angular intervals (the paper's apartment used 8).
//!
//! Invariants: a child's set is a subset of its parent's and an internal
//! set is the union of its children's (so [`VisTree::validate`] holds);
//! every random number comes from a stream seeded by (seed, node path,
//! object), so the tree is the same for any thread count.
//!
//! Note: deviation from the paper: an object is in a cell's set as soon as
//! any ray of the cell proves it visible (its own samples or any other
//! ray); the SPRT decides only the objects that no ray has hit, so it only
//! ever says "invisible" or runs into its cap. The paper could declare an
//! object invisible after seeing it hit (visible fraction below
//! s_thresh): that is popping, which vis5d does not trade for tightness.

mod builder_edges;
mod builder_leaf;
mod builder_node;
mod builder_split;
mod builder_top;
mod builder_verify;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

pub use builder_top::{
    DEFAULT_SUBTREE_OBJECTS, GraftError, MAX_TOP_LEVELS, MergeError, deal, graft, merge,
    subtree_cells, subtree_costs,
};
pub use builder_verify::{PixelError, VerifyParams, pixel_error};

use crate::bitset::ObjectSet;
use crate::codec::{Coding, FileObject, V5dFile, code_size};
use crate::geom::cell::{Cell, THETA};
use crate::geom::{Aabb, BoxTree};
use crate::scene::Scene;
use crate::sprt::{SprtError, SprtParams};
use crate::trace::{Ray, Tracer};
use crate::tree::{TreeSummary, VisTree};

/// The thickness given to the flat axes of a view box, as a share of its
/// diagonal ([`BuildParams::root_box`]).
pub const FLAT_THICKNESS: f32 = 1e-3;

/// How the builder scores a candidate split of a cell C into A and B
/// (`builder_split.rs`); vis(X) is the set of objects the cached rays
/// falling in X hit, m(X) the 5D measure. The default is papers/003's
/// effectiveness; notes/build.md compares the two on every scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SplitScore {
    /// The share of the expected set of a random view ray that the split
    /// removes: `1 - (|vis(A)| m(A) + |vis(B)| m(B)) / (|vis(C)| m(C))`.
    /// A wall near a cell's face that hides a slab of the next room from
    /// the rest scores well, though the slab is thin.
    ExpectedSet,
    /// papers/003's effectiveness `E(A, B) = (1 - |vis(A) n vis(B)| /
    /// |vis(C)|) * (1 - |m(A) - m(B)| / m(C))`, whose balance factor
    /// refuses such a cut (a slab of a tenth scores at most 0.2).
    Effectiveness,
}

impl SplitScore {
    /// The threshold measured with it (notes/build.md): 0.1 for the
    /// expected set, 0.3 for the effectiveness.
    pub fn default_threshold(self) -> f64 {
        match self {
            SplitScore::ExpectedSet => 0.1,
            SplitScore::Effectiveness => 0.3,
        }
    }

    /// Both scores, the default first.
    pub const ALL: [SplitScore; 2] = [SplitScore::Effectiveness, SplitScore::ExpectedSet];

    /// The score named `name` ([`SplitScore::name`]), if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The name used on the command line and in the parameters' text.
    pub fn name(self) -> &'static str {
        match self {
            SplitScore::ExpectedSet => "expected-set",
            SplitScore::Effectiveness => "effectiveness",
        }
    }
}

/// Every parameter of a build. [`BuildParams::default`] is the measured
/// default (notes/build.md says how each value was chosen).
#[derive(Clone, Debug, PartialEq)]
pub struct BuildParams {
    /// The sequential test deciding objects that no ray has hit.
    pub sprt: SprtParams,
    /// An internal node declares an object near one its rays hit (boxes
    /// grown by a tenth of their diagonal overlap) invisible only after
    /// this many times the misses in a row that the SPRT needs on its own:
    /// every cell below inherits the verdict, so an object that peeks out
    /// from behind a visible one, seen from a small part of the cell, must
    /// not be dropped on thin evidence. Objects far from every hit need the
    /// SPRT's own run (a block of apartments drops the others' thousands).
    pub internal_miss_factor: u32,
    /// Uniform cell rays cached per cell to score splits and prove
    /// visibility (parents hand theirs down).
    pub cache_rays: u32,
    /// How candidate splits are scored.
    pub split_score: SplitScore,
    /// A split is made only if its score exceeds this
    /// ([`SplitScore::default_threshold`] says what suits each score).
    pub split_threshold: f64,
    /// The deepest a leaf may be (splits from the root).
    pub max_depth: u32,
    /// The smallest child in x, y and z, as a fraction of the root's
    /// extent in that dimension.
    pub min_cell_fraction: f32,
    /// The smallest child in theta and phi, as a fraction of the full range
    /// (2 pi, pi).
    pub min_angle_fraction: f32,
    /// A cell is split only if its set holds at least this many
    /// triangles.
    pub min_visible_triangles: u64,
    /// Split x, y, z only (then cut leaves into `angular_leaves`).
    pub spatial_only: bool,
    /// With `spatial_only`: the number of angular intervals (a power of
    /// two) each spatial leaf is cut into. 1 = no cut.
    pub angular_leaves: u32,
    /// Candidate split values tried per angular dimension (equal-measure
    /// quantiles).
    pub angular_candidates: u32,
    /// q: split values lie on a 2^q grid of the node's range.
    pub grid_bits: u32,
    /// Object samples rejected (direction outside the angular box) per
    /// object and cell, after which the object is kept as visible
    /// undecided.
    pub rejection_budget: u32,
    /// Object samples with which a leaf retests each object that an
    /// ancestor's test called invisible and that lies near an object the
    /// leaf's rays hit (0: no retest). An object seen from a small part of
    /// a big cell falls under the test's threshold there, and is lost to
    /// every cell below it unless retested where its visible fraction is
    /// large: in the leaves. "Near": the objects' boxes, each grown by a
    /// tenth of its diagonal, overlap; it keeps a block of apartments from
    /// retesting, in every leaf, the thousands of objects of the others.
    pub retest_rays: u32,
    /// Edge rays a leaf casts per cached cell ray that hit something:
    /// from the same origin, just past an edge of the triangle it hit
    /// (`builder_edges.rs`, after GVS's adaptive border sampling), to find
    /// objects that peek out from behind nearer ones (0: none).
    pub edge_rays: u32,
    /// Hand each node's object samples down to the child they fall in
    /// (their hits prove objects there, their misses count in the child's
    /// tests), instead of testing every candidate of a child from scratch.
    pub inherit_samples: bool,
    /// The positions to build for, in the scene's local coordinates
    /// ([`Scene::frame`]; the world's for a scene near the origin); `None`
    /// = the scene's bounding box.
    pub view_box: Option<Aabb>,
    /// The view box is grown by this fraction of its diagonal on every
    /// side.
    pub view_grow: f32,
    /// The seed of every random stream.
    pub seed: u64,
    /// The most nodes the tree may have: a build that would make more
    /// fails (deterministically: exactly when the whole tree has more)
    /// rather than running for hours or out of memory. Default 2^20; the
    /// trees measured have 2k-7k nodes (notes/build.md).
    pub max_nodes: u64,
    /// Cuts made before any ray is cast (0 to [`MAX_TOP_LEVELS`]): the
    /// root is halved this many times across its longest spatial axis,
    /// and each of the 2^k cells is built as a root of its own (every
    /// object a candidate, no rays inherited), so that shards of a build
    /// can make them apart and [`graft`] them into this very tree
    /// (`vis5d build --shard`, `vis5d merge`; notes/scale.md). 0 (the
    /// default): one root, split by E(A, B) like every other node, unless
    /// the scene has more than [`BuildParams::subtree_objects`] objects.
    /// The build uses [`BuildParams::fixed_levels`].
    pub top_levels: u32,
    /// The most objects a subtree of the fixed top holds, on average,
    /// when the top is chosen from the scene: a scene of n objects with a
    /// surface has at least s levels fixed, s the fewest cuts that leave
    /// at most this many objects a subtree (at most [`MAX_TOP_LEVELS`]
    /// and `max_depth`; [`BuildParams::scene_levels`]), so that a big
    /// world's plain build is already in subtrees that shards build apart
    /// and checkpoints save. 0 levels, one root, for every scene up to
    /// this many objects (every real scene measured: their files keep
    /// their bytes).
    pub subtree_objects: u64,
}

impl Default for BuildParams {
    fn default() -> Self {
        Self {
            sprt: SprtParams {
                s_thresh: 0.01,
                accept: 50.0,
                reject: 0.2,
                prior_a: 1.0,
                prior_b: 50.0,
                max_rays: 2000,
            },
            internal_miss_factor: 2,
            cache_rays: 2048,
            split_score: SplitScore::Effectiveness,
            split_threshold: 0.3,
            max_depth: 12,
            min_cell_fraction: 1.0 / 64.0,
            min_angle_fraction: 1.0 / 16.0,
            min_visible_triangles: 500,
            spatial_only: false,
            angular_leaves: 1,
            angular_candidates: 3,
            grid_bits: 10,
            rejection_budget: 4096,
            retest_rays: 16,
            edge_rays: 1,
            inherit_samples: true,
            view_box: None,
            view_grow: 0.0,
            seed: 1,
            max_nodes: 1 << 20,
            top_levels: 0,
            subtree_objects: DEFAULT_SUBTREE_OBJECTS,
        }
    }
}

/// Why a build cannot start: a parameter outside its domain.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BuildError {
    /// The SPRT's parameters are invalid.
    #[error(transparent)]
    Sprt(#[from] SprtError),
    /// The SPRT would call an object visible before any ray hits it.
    #[error(
        "with s_thresh {s_thresh} and prior Beta({prior_a}, {prior_b}) the SPRT's odds after a \
         miss are above A = {accept}: it would call objects visible before any ray hits them; \
         raise A or prior_b"
    )]
    VisibleOnMisses {
        /// s_thresh.
        s_thresh: f64,
        /// The prior's a.
        prior_a: f64,
        /// The prior's b.
        prior_b: f64,
        /// A.
        accept: f64,
    },
    /// The tree would have more nodes than [`BuildParams::max_nodes`].
    #[error(
        "the tree would have more than {max_nodes} nodes: raise the node budget (--max-nodes) \
         if the machine has the memory, or coarsen the tree (a smaller --max-depth, larger \
         --min-cell and --min-angle, a higher --split-threshold)"
    )]
    TooManyNodes {
        /// The budget.
        max_nodes: u64,
    },
    /// A parameter is outside its domain.
    #[error("invalid build parameter: {name} must be {expected}, not {value}")]
    Parameter {
        /// The parameter (as `BuildParams` names it).
        name: &'static str,
        /// What it must be.
        expected: String,
        /// What it was.
        value: String,
    },
}

impl BuildParams {
    /// The values of papers/003 where it gives them: s_thresh 0.01, A = 50,
    /// B = 0.2 (its worked example, sec. 5), the uniform prior Beta(1, 1)
    /// it assumes, "split only if at least 500 polygons are visible", and
    /// trees of depth 8 (its coding figures, sec. 8). The rest are the
    /// defaults. `notes/build.md` says why the defaults differ (the prior).
    pub fn paper() -> Self {
        let d = Self::default();
        Self {
            sprt: SprtParams {
                prior_a: 1.0,
                prior_b: 1.0,
                ..d.sprt
            },
            max_depth: 8,
            min_visible_triangles: 500,
            ..d
        }
    }

    /// The named presets, for tests and benches that loop over them:
    /// `default` and `paper`.
    pub fn presets() -> [(&'static str, BuildParams); 2] {
        [("default", Self::default()), ("paper", Self::paper())]
    }

    /// Checks every parameter; the error says which is wrong and why.
    pub fn validate(&self) -> Result<(), BuildError> {
        self.sprt.validate()?;
        if !self.sprt.misses_mean_invisible() {
            return Err(BuildError::VisibleOnMisses {
                s_thresh: self.sprt.s_thresh,
                prior_a: self.sprt.prior_a,
                prior_b: self.sprt.prior_b,
                accept: self.sprt.accept,
            });
        }
        let bad = |name, expected: &str, value: &dyn std::fmt::Display| BuildError::Parameter {
            name,
            expected: expected.to_owned(),
            value: value.to_string(),
        };
        let counts: [(&'static str, u64, std::ops::RangeInclusive<u64>); 8] = [
            (
                "internal_miss_factor",
                self.internal_miss_factor.into(),
                1..=1_000,
            ),
            ("cache_rays", self.cache_rays.into(), 1..=1_000_000),
            ("angular_candidates", self.angular_candidates.into(), 1..=64),
            (
                "rejection_budget",
                self.rejection_budget.into(),
                1..=10_000_000,
            ),
            ("max_nodes", self.max_nodes, 1..=u32::MAX as u64),
            ("subtree_objects", self.subtree_objects, 1..=u32::MAX as u64),
            ("retest_rays", self.retest_rays.into(), 0..=100_000),
            ("edge_rays", self.edge_rays.into(), 0..=64),
        ];
        for (name, value, range) in counts {
            if !range.contains(&value) {
                let expected = format!("in {}..={}", range.start(), range.end());
                return Err(bad(name, &expected, &value));
            }
        }
        if !(0.0..1.0).contains(&self.split_threshold) {
            return Err(bad("split_threshold", "in [0, 1)", &self.split_threshold));
        }
        for (name, f) in [
            ("min_cell_fraction", self.min_cell_fraction),
            ("min_angle_fraction", self.min_angle_fraction),
        ] {
            if !(1e-6..0.5).contains(&f) {
                return Err(bad(name, "in [1e-6, 0.5)", &f));
            }
        }
        if !self.angular_leaves.is_power_of_two() || self.angular_leaves > 256 {
            return Err(bad(
                "angular_leaves",
                "a power of two up to 256",
                &self.angular_leaves,
            ));
        }
        if !(1..=16).contains(&self.grid_bits) {
            return Err(bad("grid_bits", "in 1..=16", &self.grid_bits));
        }
        let deepest = self.max_depth as u64 + self.angular_leaves.trailing_zeros() as u64;
        if deepest > crate::tree::MAX_DEPTH as u64 {
            return Err(bad(
                "max_depth (plus the angular cuts)",
                &format!("at most {}", crate::tree::MAX_DEPTH),
                &deepest,
            ));
        }
        if self.top_levels > MAX_TOP_LEVELS.min(self.max_depth) {
            return Err(bad(
                "top_levels",
                &format!("at most {MAX_TOP_LEVELS} and at most max_depth"),
                &self.top_levels,
            ));
        }
        if !(0.0..=100.0).contains(&self.view_grow) {
            return Err(bad("view_grow", "in [0, 100] (diagonals)", &self.view_grow));
        }
        if let Some(b) = self.view_box
            && !(b.min.is_finite() && b.max.is_finite() && b.min.cmplt(b.max).all())
        {
            return Err(bad(
                "view_box",
                "a finite box with min < max in x, y and z",
                &format!("{:?} .. {:?}", b.min.to_array(), b.max.to_array()),
            ));
        }
        if let Some(b) = self.view_box
            && root_of(b, self.view_grow).is_none()
        {
            return Err(bad(
                "view_box",
                ROOT_FITS,
                &format!("{:?} .. {:?}", b.min.to_array(), b.max.to_array()),
            ));
        }
        Ok(())
    }

    /// The levels `scene` fixes ([`BuildParams::subtree_objects`]): the
    /// fewest cuts s with the objects that have a surface at most
    /// `subtree_objects` 2^s, at most [`MAX_TOP_LEVELS`] and `max_depth`.
    pub fn scene_levels(&self, scene: &Scene) -> u32 {
        let objects = scene.surface_objects().count() as u64;
        let most = MAX_TOP_LEVELS.min(self.max_depth);
        let per = self.subtree_objects.max(1);
        (0..most).find(|&s| objects <= per << s).unwrap_or(most)
    }

    /// The levels of the fixed top for `scene`: [`BuildParams::top_levels`]
    /// or [`BuildParams::scene_levels`], the more.
    pub fn fixed_levels(&self, scene: &Scene) -> u32 {
        self.top_levels.max(self.scene_levels(scene))
    }

    /// The spatial box of the root cell for `scene`.
    ///
    /// A flat box (a scene in one plane: a floor plan, a terrain of one
    /// height) is given a thickness of [`FLAT_THICKNESS`] times its
    /// diagonal on its flat axes, so that the root cell has a volume.
    pub fn root_box(&self, scene: &Scene) -> Aabb {
        let b = self.view_box.unwrap_or(scene.bounds());
        let b = b.expanded(self.view_grow * b.diagonal());
        b.thickened(FLAT_THICKNESS * b.diagonal())
    }
}

/// What a view box must be for its root cell to exist in f32.
pub(crate) const ROOT_FITS: &str =
    "a box whose size, grown, fits in f32 (a diagonal under about 1.8e19)";

/// The root box grown from the view box `b` by `grow` diagonals and
/// thickened where flat ([`BuildParams::root_box`]), or `None` when it
/// does not fit in f32 (its diagonal overflows, and the box would be NaN).
pub(crate) fn root_of(b: Aabb, grow: f32) -> Option<Aabb> {
    let d = b.diagonal();
    if !d.is_finite() {
        return None;
    }
    let grown = b.expanded(grow * d);
    let root = grown.thickened(FLAT_THICKNESS * grown.diagonal());
    (root.min.is_finite() && root.max.is_finite() && root.diagonal().is_finite()).then_some(root)
}

impl BuildParams {
    /// The parameters as `key=value` lines, as stored in `.v5d` files
    /// (the view box is the root box actually used for `scene`, in world
    /// coordinates).
    pub fn to_text(&self, scene: &Scene) -> String {
        let b = self.root_box(scene);
        let frame = scene.frame();
        let p = &self.sprt;
        let lines = [
            format!("vis5d={}", env!("CARGO_PKG_VERSION")),
            format!("seed={}", self.seed),
            format!(
                "view_box={},{}",
                frame.world_text(b.min),
                frame.world_text(b.max)
            ),
            format!("s_thresh={}", p.s_thresh),
            format!("accept={}", p.accept),
            format!("reject={}", p.reject),
            format!("prior={},{}", p.prior_a, p.prior_b),
            format!("max_rays={}", p.max_rays),
            format!("internal_miss_factor={}", self.internal_miss_factor),
            format!("cache_rays={}", self.cache_rays),
            format!("split_score={}", self.split_score.name()),
            format!("split_threshold={}", self.split_threshold),
            format!("max_depth={}", self.max_depth),
            format!("min_cell_fraction={}", self.min_cell_fraction),
            format!("min_angle_fraction={}", self.min_angle_fraction),
            format!("min_visible_triangles={}", self.min_visible_triangles),
            format!("spatial_only={}", self.spatial_only),
            format!("angular_leaves={}", self.angular_leaves),
            format!("angular_candidates={}", self.angular_candidates),
            format!("grid_bits={}", self.grid_bits),
            format!("rejection_budget={}", self.rejection_budget),
            format!("retest_rays={}", self.retest_rays),
            format!("edge_rays={}", self.edge_rays),
            format!("inherit_samples={}", self.inherit_samples),
        ];
        let mut text = lines.join("\n") + "\n";
        // Only where used, so that the files of builds without a fixed top
        // keep their bytes.
        let fixed = self.fixed_levels(scene);
        if fixed > 0 {
            text += &format!("top_levels={fixed}\n");
        }
        text
    }
}

/// The `.v5d` contents for `tree`, built for `scene` with `params`, with
/// `coding`, or the smallest of the three when `None`.
pub fn to_file(
    scene: &Scene,
    tree: VisTree,
    params: &BuildParams,
    coding: Option<Coding>,
) -> V5dFile {
    file_with_params(scene, tree, params.to_text(scene), coding)
}

/// The `.v5d` file of any `tree` built for `scene` (the sampled builder's,
/// or the conservative bake's), its parameter text `params` (`key=value`
/// lines), in `coding` (the smallest when `None`), with the scene's
/// objects, their ids ([`Scene::ids`]: the model's own where it has
/// them), flags and bounds.
pub fn file_with_params(
    scene: &Scene,
    tree: VisTree,
    params: String,
    coding: Option<Coding>,
) -> V5dFile {
    let coding = coding.unwrap_or_else(|| smallest_coding(&tree));
    V5dFile {
        coding,
        fingerprint: scene.fingerprint(),
        frame: scene.frame(),
        params,
        objects: scene
            .objects()
            .iter()
            .zip(scene.ids())
            .map(|(o, id)| FileObject {
                name: o.name.clone(),
                id,
                triangles: o.triangle_count() as u32,
                // An empty object has no box (stored as "not known").
                bounds: (!o.is_empty()).then_some(o.bounds),
                flags: o.flags,
            })
            .collect(),
        tree,
        slices: None,
    }
}

/// The coding that makes `tree` smallest (the first of
/// [`Coding::ALL`] on a tie).
pub fn smallest_coding(tree: &VisTree) -> Coding {
    let mut best = (u64::MAX, Coding::Sibling);
    for c in Coding::ALL {
        let bits = code_size(tree, c).total_bits();
        if bits < best.0 {
            best = (bits, c);
        }
    }
    best.1
}

/// How the candidate objects of the cells were decided, summed over all
/// cells (internal nodes included).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Decisions {
    /// Proven visible by a ray's closest hit (a cached cell ray, the
    /// object's own sample, or another object's sample).
    pub proven_by_hit: u64,
    /// Declared invisible by the SPRT.
    pub sprt_invisible: u64,
    /// Of those, decided by the misses of object samples that ancestors
    /// traced inside the cell alone, without a ray of the cell's own
    /// ([`BuildParams::inherit_samples`]).
    pub decided_by_ancestors: u64,
    /// The SPRT reached its ray cap: kept as visible.
    pub cap_reached: u64,
    /// Invisible by geometry: no direction of the cell reaches the
    /// object's bounding box.
    pub geometry_invisible: u64,
    /// Almost every sample was rejected (rejection budget spent): kept as
    /// visible.
    pub rejection_kept: u64,
    /// Objects a leaf retested because an ancestor called them invisible
    /// ([`BuildParams::retest_rays`]).
    pub retested: u64,
    /// Of those, the ones a retest ray hit: visible in the leaf after all.
    pub retest_found: u64,
    /// Objects a leaf's edge rays found that nothing else had
    /// ([`BuildParams::edge_rays`]).
    pub edge_found: u64,
}

impl Decisions {
    fn add(&mut self, o: &Decisions) {
        self.proven_by_hit += o.proven_by_hit;
        self.sprt_invisible += o.sprt_invisible;
        self.decided_by_ancestors += o.decided_by_ancestors;
        self.cap_reached += o.cap_reached;
        self.geometry_invisible += o.geometry_invisible;
        self.rejection_kept += o.rejection_kept;
        self.retested += o.retested;
        self.retest_found += o.retest_found;
        self.edge_found += o.edge_found;
    }
}

/// What a build did, counted where it happened.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildStats {
    /// Uniform cell rays cast (the split caches).
    pub cell_rays: u64,
    /// Object sample rays cast (the SPRTs).
    pub object_rays: u64,
    /// Edge rays cast (leaves, [`BuildParams::edge_rays`]).
    pub edge_rays: u64,
    /// Object samples rejected: direction outside the angular box.
    pub rejected: u64,
    /// Decisions by kind.
    pub decisions: Decisions,
    /// Seconds spent inside the tracer, summed over threads.
    pub trace_seconds: f64,
    /// Wall-clock seconds of the whole build (BVH excluded).
    pub seconds: f64,
}

impl BuildStats {
    fn add(&mut self, o: &BuildStats) {
        self.cell_rays += o.cell_rays;
        self.object_rays += o.object_rays;
        self.edge_rays += o.edge_rays;
        self.rejected += o.rejected;
        self.decisions.add(&o.decisions);
        self.trace_seconds += o.trace_seconds;
    }

    /// All rays cast.
    pub fn rays(&self) -> u64 {
        self.cell_rays + self.object_rays + self.edge_rays
    }
}

/// The shape and set sizes of `tree` built for `scene`
/// ([`VisTree::summarize`] with the scene's triangle counts).
pub fn summarize(tree: &VisTree, scene: &Scene) -> TreeSummary {
    let tris: Vec<u64> = scene
        .objects()
        .iter()
        .map(|o| o.triangle_count() as u64)
        .collect();
    tree.summarize(&tris)
}

/// Builds the tree of `scene` traced by `tracer` (built from the same
/// scene). `progress` is called with the fraction of view space finished
/// (by measure), from any thread.
pub fn build(
    scene: &Scene,
    tracer: &Tracer,
    params: &BuildParams,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<(VisTree, BuildStats), BuildError> {
    let (parts, stats) = build_recording(scene, tracer, params, None, progress, None)?;
    let trees: Vec<VisTree> = parts.into_iter().map(|(_, t)| t).collect();
    let root = Cell::all_directions(params.root_box(scene));
    let tree = graft(root, params.fixed_levels(scene), params.grid_bits, &trees)
        .expect("the subtrees were built for their places");
    Ok((tree, stats))
}

/// The subtrees of the fixed top that shard `shard` of `shards` builds
/// (indices in [`subtree_cells`]' order), for `scene` and `params`.
pub fn shard_subtrees(scene: &Scene, params: &BuildParams, shard: u32, shards: u32) -> Vec<u32> {
    let root = Cell::all_directions(params.root_box(scene));
    let cells = subtree_cells(root, params.fixed_levels(scene), params.grid_bits);
    deal(&subtree_costs(scene, &cells), shards)
        .into_iter()
        .enumerate()
        .filter(|&(_, s)| s == shard)
        .map(|(i, _)| i as u32)
        .collect()
}

/// The first `n` rays a build of `scene` with `params` traces (cell rays,
/// object samples as segments, edge and retest rays, in the order the
/// build traces them), for timing ray casters on the builder's own work
/// (`vis5d trace --kind builder`, notes/trace.md). The build stops
/// splitting cells once it has them. The order follows the build's
/// schedule: the same on one thread (as `vis5d trace` runs it) for the
/// same scene, parameters and seed.
pub fn record_rays(
    scene: &Scene,
    tracer: &Tracer,
    params: &BuildParams,
    n: usize,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<Vec<Ray>, BuildError> {
    let log = crate::raylog::RayLog::new(n);
    build_recording(scene, tracer, params, None, progress, Some(&log))?;
    Ok(log.into_rays())
}

/// The subtrees of the fixed top that `shard` (shard, shards) builds, or
/// all of them, each with its index and its tree.
fn build_recording(
    scene: &Scene,
    tracer: &Tracer,
    params: &BuildParams,
    shard: Option<(u32, u32)>,
    progress: &(dyn Fn(f64) + Sync),
    record: Option<&crate::raylog::RayLog>,
) -> Result<(Vec<(u32, VisTree)>, BuildStats), BuildError> {
    build_resuming(
        scene,
        tracer,
        params,
        shard,
        Vec::new(),
        &|_, _| {},
        progress,
        record,
    )
}

/// The subtrees of the fixed top ([`BuildParams::top_levels`]) that shard
/// `shard` (shard, shards) builds, or all of them, in index order, with
/// those in `done` (built before, from checkpoints: each must be the
/// subtree of its index, rooted at its cell) taken as they are and the
/// others built, each handed to `on_built` as soon as it is finished
/// (from any thread; not when the node budget cut it short). The same
/// subtrees as an uninterrupted build: each depends only on the scene,
/// the parameters and its index, so the shards' subtrees together,
/// [`graft`]ed, are the tree [`build`] makes, node for node (`vis5d build
/// --shard`, `--checkpoint`, `vis5d merge`). A shard's subtrees are
/// those [`shard_subtrees`] deals it. `progress` counts the cells built
/// now; `record` takes the rays traced, for `vis5d trace`. The node
/// budget ([`BuildParams::max_nodes`]) counts the fixed top and the
/// subtrees built now.
///
/// # Errors
/// As [`build`]; [`BuildError::Parameter`] (`resumed subtree`) when a
/// subtree of `done` does not fit its place.
#[allow(clippy::too_many_arguments)]
pub fn build_resuming(
    scene: &Scene,
    tracer: &Tracer,
    params: &BuildParams,
    shard: Option<(u32, u32)>,
    done: Vec<(u32, VisTree)>,
    on_built: &(dyn Fn(u32, &VisTree) + Sync),
    progress: &(dyn Fn(f64) + Sync),
    record: Option<&crate::raylog::RayLog>,
) -> Result<(Vec<(u32, VisTree)>, BuildStats), BuildError> {
    params.validate()?;
    let fixed = params.fixed_levels(scene);
    let start = Instant::now();
    let root = Cell::all_directions(params.root_box(scene));
    let cells = subtree_cells(root, fixed, params.grid_bits);
    let wanted: Vec<u32> = match shard {
        None => (0..cells.len() as u32).collect(),
        Some((i, n)) => shard_subtrees(scene, params, i, n),
    };
    let mut reused: Vec<Option<VisTree>> = vec![None; cells.len()];
    for (j, tree) in done {
        let fits = cells.get(j as usize).is_some_and(|c| {
            tree.root_cell() == *c
                && tree.grid_bits() == params.grid_bits
                && tree.object_count() == scene.objects().len()
        });
        if !fits {
            return Err(BuildError::Parameter {
                name: "resumed subtree",
                expected: format!(
                    "one of the {} subtrees of this scene and these parameters, in its cell",
                    cells.len()
                ),
                value: j.to_string(),
            });
        }
        reused[j as usize] = Some(tree);
    }
    let todo: Vec<u32> = wanted
        .iter()
        .copied()
        .filter(|&j| reused[j as usize].is_none())
        .collect();
    let measure = if todo.len() == cells.len() {
        root.measure()
    } else {
        todo.iter().map(|&j| cells[j as usize].measure()).sum()
    };
    let ctx = builder_node::Ctx {
        scene,
        tracer,
        params,
        min_width: std::array::from_fn(|d| {
            let f = if d < THETA {
                params.min_cell_fraction
            } else {
                params.min_angle_fraction
            };
            root.width(d) * f
        }),
        triangles: scene
            .objects()
            .iter()
            .map(|o| o.triangle_count() as u64)
            .collect(),
        neighbours: if params.retest_rays > 0 || params.internal_miss_factor > 1 {
            neighbours(scene)
        } else {
            Vec::new()
        },
        always_visible: scene.always_visible().collect(),
        root_measure: measure,
        misses_decision: params.sprt.misses_decision(),
        internal_min_misses: params
            .sprt
            .misses_to_invisible()
            .saturating_mul(params.internal_miss_factor),
        done: AtomicU64::new(0),
        // The fixed top's nodes, its subtrees' roots among them.
        nodes: AtomicU64::new((2u64 << fixed) - 1),
        over_budget: AtomicBool::new(false),
        progress,
        record,
    };
    // Every object with a surface: an empty one (no triangles) is never
    // sampled and never in a set.
    let candidates = scene.surface_objects();
    let built: Vec<(VisTree, BuildStats)> = todo
        .par_iter()
        .map(|&j| {
            let mut stats = BuildStats::default();
            let built = builder_node::build_node(
                &ctx,
                cells[j as usize],
                builder_node::NodeState::top(fixed),
                params.subtree_seed(fixed, j as usize),
                &candidates,
                &ObjectSet::new(scene.objects().len()),
                Vec::new(),
                Vec::new(),
                &mut stats,
            );
            let mut nodes = Vec::new();
            let mut records = Vec::new();
            built.flatten_into(&mut nodes, &mut records);
            let tree = VisTree::from_parts(
                cells[j as usize],
                params.grid_bits,
                scene.objects().len(),
                nodes,
            )
            .with_leaf_records(Some(records))
            .expect("one record per leaf");
            // A subtree cut short by the node budget is not finished.
            if !ctx.over_budget.load(Ordering::Relaxed) {
                on_built(j, &tree);
            }
            (tree, stats)
        })
        .collect();
    if ctx.over_budget.load(Ordering::Relaxed) {
        return Err(BuildError::TooManyNodes {
            max_nodes: params.max_nodes,
        });
    }
    let mut stats = BuildStats::default();
    for ((tree, s), &j) in built.into_iter().zip(&todo) {
        stats.add(&s);
        reused[j as usize] = Some(tree);
    }
    let parts = wanted
        .iter()
        .map(|&j| {
            let tree = reused[j as usize].take().expect("built or resumed");
            (j, tree)
        })
        .collect();
    stats.seconds = start.elapsed().as_secs_f64();
    Ok((parts, stats))
}

/// Per object, the objects whose bounding boxes, each grown by a tenth of
/// its diagonal, overlap its own grown box (itself excluded), in index
/// order. (Grown by half, the apartment block retested 3.4 times as many
/// objects, 39.7 M rays against 30.6 M, for the same pixel errors on the
/// office, city, duplex and FZK-Haus; notes/build.md.)
/// The grown boxes are queried in a [`BoxTree`] of themselves, so that the
/// work grows with the pairs that are near, not with the square of the
/// objects.
pub(crate) fn neighbours(scene: &Scene) -> Vec<Vec<u32>> {
    let grown: Vec<Aabb> = scene
        .objects()
        .iter()
        .map(|o| o.bounds.expanded(0.1 * o.bounds.diagonal()))
        .collect();
    let tree = BoxTree::new(&grown);
    let mut out = vec![Vec::new(); grown.len()];
    for (i, b) in grown.iter().enumerate() {
        let near = &mut out[i];
        tree.overlapping(b, near);
        near.retain(|&j| j as usize != i);
        near.sort_unstable();
    }
    out
}

/// A 64-bit mix of two values (splitmix64 finaliser): seeds of the random
/// streams of nodes and objects.
pub(crate) fn mix(a: u64, b: u64) -> u64 {
    let mut z = a ^ b.wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(17);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::procedural::{SceneKind, generate};

    /// The fixed top from the scene: the fewest cuts that leave at most
    /// `subtree_objects` objects a subtree, within 10 and `max_depth`,
    /// and never fewer than `top_levels`.
    #[test]
    fn a_scene_of_many_objects_fixes_its_top() {
        let scene = generate(SceneKind::Apartment, 1, 1);
        let n = scene.surface_objects().count() as u64;
        assert!(n > 100);
        let levels = |subtree_objects: u64, top_levels: u32, max_depth: u32| {
            let params = BuildParams {
                subtree_objects,
                top_levels,
                max_depth,
                ..BuildParams::default()
            };
            (params.scene_levels(&scene), params.fixed_levels(&scene))
        };
        assert_eq!(levels(DEFAULT_SUBTREE_OBJECTS, 0, 12), (0, 0));
        assert_eq!(levels(n, 0, 12), (0, 0));
        assert_eq!(levels(n - 1, 0, 12), (1, 1));
        assert_eq!(levels(n.div_ceil(2), 0, 12), (1, 1));
        assert_eq!(levels(n.div_ceil(2) - 1, 0, 12), (2, 2));
        assert_eq!(levels(n.div_ceil(4), 3, 12), (2, 3));
        let all = 64 - (n - 1).leading_zeros();
        assert_eq!(levels(1, 0, 12), (all, all));
        assert_eq!(levels(1, 0, 4), (4, 4));
        let block = generate(SceneKind::Apartment, 1, 18);
        let one = BuildParams {
            subtree_objects: 1,
            ..BuildParams::default()
        };
        assert_eq!(one.scene_levels(&block), MAX_TOP_LEVELS);
        let text = BuildParams::default().to_text(&scene);
        assert!(!text.contains("top_levels"), "one root: the old text");
        let fixed = BuildParams {
            subtree_objects: n - 1,
            ..BuildParams::default()
        };
        assert!(fixed.to_text(&scene).ends_with("top_levels=1\n"));
    }

    #[test]
    fn neighbours_on_the_grid_are_the_pairs_of_overlapping_grown_boxes() {
        for kind in [SceneKind::City, SceneKind::Machine] {
            let scene = generate(kind, 3, 2);
            let grown: Vec<Aabb> = scene
                .objects()
                .iter()
                .map(|o| o.bounds.expanded(0.1 * o.bounds.diagonal()))
                .collect();
            let fast = neighbours(&scene);
            for (i, a) in grown.iter().enumerate() {
                let slow: Vec<u32> = (0..grown.len())
                    .filter(|&j| {
                        j != i && a.min.cmple(grown[j].max).all() && grown[j].min.cmple(a.max).all()
                    })
                    .map(|j| j as u32)
                    .collect();
                assert_eq!(fast[i], slow, "{kind} object {i}");
            }
            let pairs: usize = fast.iter().map(Vec::len).sum();
            assert!(
                pairs > 0 && pairs < grown.len() * grown.len() / 2,
                "{pairs}"
            );
        }
    }
}
