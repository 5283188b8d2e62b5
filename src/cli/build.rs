//! `vis5d build`: the 5D visibility tree of a scene, written to a `.v5d`.

use std::io::{self, Write};
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use clap::builder::TypedValueParser;
use serde::Serialize;
use vis5d::builder::{BuildError, BuildParams, BuildStats, PixelError, SplitScore, VerifyParams};
use vis5d::codec::{self, Coding};
use vis5d::conservative::{BakeError, BakeParams};
use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
use vis5d::scene::Scene;
use vis5d::sprt::SprtParams;
use vis5d::trace::Tracer;
use vis5d::tree::TreeSummary;

use crate::checkpoint::Checkpoints;
use crate::common::{
    CodingSize, ShapeReport, World, WorldBox, check_output, coding_sizes, flag, load_scene_up,
    parse_box, parse_pair, print_shape, progress_bar,
};
use crate::memory;
use crate::oracle::{GpuWarning, gpu_else_cpu};

#[derive(Args, Debug)]
pub struct BuildArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
    /// The scene's up axis in its file: x, y or z (glTF and most game
    /// engines: y). Local z follows it: directions are parametrised by
    /// their angle from it (phi) and about it (theta), floorless buildings
    /// stand on it. The .v5d file stores it, and its queries take world coordinates.
    #[arg(long, value_name = "AXIS", default_value = "z")]
    up: vis5d::geom::Up,
    /// Where to write the tree [default: the model's path with the
    /// extension .v5d].
    #[arg(short, long, value_name = "FILE.v5d")]
    output: Option<PathBuf>,
    /// How to code the sets: leaf (leaves only), parent (children relative
    /// to the parent) or sibling (the heavier sibling relative to the
    /// lighter too) [default: the smallest for this tree].
    #[arg(long)]
    coding: Option<Coding>,
    /// Build and report, but write nothing.
    #[arg(long)]
    dry_run: bool,
    /// Print the summary as JSON instead of text.
    #[arg(long)]
    json: bool,
    /// The positions to build for, as x0,y0,z0,x1,y1,z1 in world
    /// coordinates [default: the scene's bounding box].
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", value_parser = parse_box, allow_hyphen_values = true)]
    view_box: Option<WorldBox>,
    /// Grow the view box by this fraction of its diagonal on every side
    /// [0 to 100].
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    grow: f32,
    /// Seed of every random stream: the same seed gives the same tree,
    /// whatever the thread count.
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().seed)]
    seed: u64,
    /// Threads [1 to 1024; default: all cores].
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// SPRT: the visible fraction separating visible from invisible
    /// [above 0, below 1].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().sprt.s_thresh, allow_hyphen_values = true)]
    s_thresh: f64,
    /// SPRT: odds above which an object is visible (the paper's A) [finite,
    /// above B].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().sprt.accept, allow_hyphen_values = true)]
    accept: f64,
    /// SPRT: odds below which an object is invisible (the paper's B)
    /// [above 0, below A].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().sprt.reject, allow_hyphen_values = true)]
    reject: f64,
    /// SPRT: the prior Beta(a, b) on the visible fraction, as a,b [both
    /// finite and above 0].
    #[arg(conflicts_with = "conservative", long, value_name = "A,B", value_parser = parse_pair,
          default_value = "1,50", allow_hyphen_values = true)]
    prior: (f64, f64),
    /// SPRT: rays after which an undecided object is kept as visible [1 to
    /// 1,000,000].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().sprt.max_rays, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    max_rays: u32,
    /// Internal nodes declare an object invisible only after this many
    /// times the misses the SPRT needs (their verdict holds for every cell
    /// below) [1 to 1,000].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().internal_miss_factor, value_parser = clap::value_parser!(u32).range(1..=1_000))]
    internal_miss_factor: u32,
    /// Uniform cell rays cached per cell to score splits [1 to
    /// 1,000,000].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().cache_rays, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    cache_rays: u32,
    /// How a candidate split is scored: effectiveness (papers/003's
    /// E(A, B), which refuses unbalanced cuts) or expected-set (the share
    /// of a random view ray's expected set that the split removes; it cuts
    /// off thin slabs behind walls, for 10-66% more rays)
    #[arg(
        conflicts_with = "conservative",
        long,
        default_value = SplitScore::Effectiveness.name(),
        value_parser = clap::builder::PossibleValuesParser::new(SplitScore::ALL.map(SplitScore::name))
            .map(|name| SplitScore::from_name(&name).expect("a possible value"))
    )]
    split_score: SplitScore,
    /// Split only when the split's score exceeds this [0 to below 1;
    /// default 0.3 for effectiveness, 0.1 for expected-set]
    #[arg(conflicts_with = "conservative", long, allow_hyphen_values = true)]
    split_threshold: Option<f64>,
    /// The deepest a leaf may be [0 to 64, less the angular cuts; default:
    /// 12, and 10 with --conservative].
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=64))]
    max_depth: Option<u32>,
    /// The smallest cell in x, y, z, as a fraction of the root's extent
    /// [1e-6 to below 0.5].
    #[arg(long, default_value_t = BuildParams::default().min_cell_fraction, allow_hyphen_values = true)]
    min_cell: f32,
    /// The smallest cell in theta and phi, as a fraction of 2 pi and pi
    /// [1e-6 to below 0.5].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().min_angle_fraction, allow_hyphen_values = true)]
    min_angle: f32,
    /// Split a cell only if its set holds at least this many triangles
    /// (the paper: 500) [any count].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().min_visible_triangles)]
    min_visible_triangles: u64,
    /// Split x, y, z only, then cut each final cell into
    /// --angular-leaves angular intervals.
    #[arg(conflicts_with = "conservative", long)]
    spatial_only: bool,
    /// With --spatial-only: angular intervals per final cell (a power of
    /// two; the paper used 8) [1 to 256].
    #[arg(conflicts_with = "conservative", long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=256))]
    angular_leaves: u32,
    /// Candidate split values per angular dimension [1 to 64].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().angular_candidates, value_parser = clap::value_parser!(u32).range(1..=64))]
    angular_candidates: u32,
    /// Split values lie on a 2^q grid of the node's range [1 to 16].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().grid_bits, value_parser = clap::value_parser!(u32).range(1..=16))]
    grid_bits: u32,
    /// Rejected samples per object and cell after which it is kept as
    /// visible [1 to 10,000,000].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().rejection_budget, value_parser = clap::value_parser!(u32).range(1..=10_000_000))]
    rejection_budget: u32,
    /// Samples with which each leaf retests every object an ancestor
    /// called invisible (an object seen from a small part of a big cell is
    /// found in the leaf where it is well visible) [0 = no retest, to
    /// 100,000].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().retest_rays, value_parser = clap::value_parser!(u32).range(0..=100_000))]
    retest_rays: u32,
    /// Rays each leaf casts per cell ray that hit something, from the same
    /// origin to just past an edge of the triangle it hit (guided
    /// visibility sampling: finds objects that peek out from behind nearer
    /// ones) [0 = none, to 64].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().edge_rays, value_parser = clap::value_parser!(u32).range(0..=64))]
    edge_rays: u32,
    /// Test every candidate of a cell from scratch, instead of counting
    /// the object samples its ancestors traced inside it (their hits as
    /// proofs, their misses toward the test)
    #[arg(conflicts_with = "conservative", long)]
    no_inherit_samples: bool,
    /// After building, render this many random views and report the pixel
    /// error [0 to 1,000,000].
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=1_000_000))]
    verify_views: u32,
    /// Pixels per side of each verification view [1 to 8192; the memory
    /// a view needs is checked first].
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=8192))]
    verify_resolution: u32,
    /// Bake a conservative tree instead of sampling one: a spatial k-d
    /// tree of view cells, each leaf holding the objects that the
    /// extended-projection oracle (papers/001, `vis5d oracle`) cannot prove
    /// hidden from its box, cells cut in two where their set holds more
    /// than --triangle-budget triangles (papers/001 sec. 6). It never drops
    /// a visible object; its sets are usually larger than the sampled
    /// tree's. Same
    /// file format and queries; `vis5d stat` shows the method. The
    /// sampler's flags do not apply.
    #[arg(long)]
    conservative: bool,
    /// With --conservative: cut a cell whose set holds more triangles than
    /// this [default: a hundredth of the scene's triangles, at least 500].
    #[arg(long, requires = "conservative")]
    triangle_budget: Option<u64>,
    /// With --conservative: try the middle of each side of a cell and keep
    /// the cut whose halves hold the fewest triangles, instead of cutting
    /// the longest side (runs the oracle on the halves of every cut tried:
    /// 2.4-3x the time).
    #[arg(long, requires = "conservative")]
    try_cuts: bool,
    /// With --conservative: stop cutting where this many levels in a row
    /// proved nothing more hidden (saves time on open scenes, where big
    /// cells prove nothing; in buildings deeper cells often do) [0 = cut
    /// to the depth limit and the budget, to 64].
    #[arg(long, requires = "conservative", default_value_t = BakeParams::default().stall_levels,
          value_parser = clap::value_parser!(u32).range(0..=64))]
    stall_levels: u32,
    /// With --conservative: the oracle's occlusion sweep, planes per face
    /// spaced from the nearest occluder to the farthest (`vis5d oracle
    /// --sweep-planes`). Off by default in the bake: with 4 sweep planes
    /// and 4 patch planes a cell costs about 4-5x the time for 10-15% fewer
    /// objects kept (notes/oracle.md) [0 to 64].
    #[arg(long, requires = "conservative", default_value_t = 0,
          value_parser = clap::value_parser!(u8).range(0..=64))]
    sweep_planes: u8,
    /// With --conservative: the sweep's planes per face at the largest
    /// axis-aligned patches, floors, slabs and walls drawn whole (`vis5d
    /// oracle --sweep-patches`); off by default in the bake [0 to 64].
    #[arg(long, requires = "conservative", default_value_t = 0,
          value_parser = clap::value_parser!(u8).range(0..=64))]
    sweep_patches: u8,
    /// With --conservative: each sweep plane takes the reprojections of
    /// this many planes before it, 1, 2, 4, ... back (`vis5d oracle
    /// --sweep-reach`, whose default is 3; the bake's sweep is off by
    /// default, and with it the reach stays 1 unless asked) [1 to 8].
    #[arg(long, requires = "conservative", default_value_t = 1,
          value_parser = clap::value_parser!(u8).range(1..=8))]
    sweep_reach: u8,
    /// With --conservative: the oracle's shafts, at most this many an
    /// object (`vis5d oracle --shaft-budget`): objects the maps did not
    /// hide tried one occluder at a time, the cell and the object cut in
    /// halves or passed on through a wall's door [0 (off) to 1,000,000].
    #[arg(long, requires = "conservative", default_value_t = 0,
          value_parser = clap::value_parser!(u32).range(0..=1_000_000))]
    shaft_budget: u32,
    /// With --conservative: sealed rooms (`vis5d oracle --seal-voxels`),
    /// the free space between the closed solids in connected pieces over
    /// a grid of at most about this many voxels; what no free path from a
    /// cell reaches is hidden [0 (off) to 268,435,456].
    #[arg(long, requires = "conservative", default_value_t = 1 << 24,
          value_parser = clap::value_parser!(u32).range(0..=(1 << 28)))]
    seal_voxels: u32,
    /// With --conservative: rasterise the oracle's Depth Maps on the GPU
    /// (wgpu) where one exists, the maps of all the halves of a cell's
    /// cuts in one submission. The bake uses the CPU by default: the GPU
    /// was slower per cell where measured (notes/oracle.md: 12 against 33
    /// ms on Mesa's lavapipe, 9.8 against 11.9 ms on an H100, one cell a
    /// submission then), and the bake keeps every core busy with cells.
    #[arg(long, requires = "conservative")]
    gpu: bool,
    /// The most nodes the tree may have [1 to 4,294,967,295; lowered to
    /// what the memory budget holds]: a build that would make more fails,
    /// rather than running for hours or out of memory.
    #[arg(long, default_value_t = BuildParams::default().max_nodes, value_parser = clap::value_parser!(u64).range(1..=4_294_967_295))]
    max_nodes: u64,
    /// Cut the root this many times, each time halving its longest
    /// spatial axis, before any ray is cast, and build the 2^K cells as
    /// roots of their own (every object a candidate): what lets `--shard`
    /// split the build and `vis5d merge` put it back together byte for
    /// byte [0 to 10, at most --max-depth; 0: one root, split by E(A, B)
    /// like every node]. A scene of more objects than --subtree-objects
    /// has more levels fixed, whatever this says.
    #[arg(conflicts_with = "conservative", long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=10))]
    top_levels: u32,
    /// Fix the top from the scene: a scene of more objects (with a
    /// surface) than this is cut as --top-levels cuts, into the fewest
    /// 2^s subtrees of at most this many objects on average (s at most 10
    /// and at most --max-depth), so that a big world's plain build is one
    /// that --shard splits and --checkpoint resumes. The tree below is
    /// built as without (the same depth and smallest cell). Scenes up to
    /// this many objects keep one root [1 to 4,294,967,295].
    #[arg(conflicts_with = "conservative", long, default_value_t = BuildParams::default().subtree_objects, value_parser = clap::value_parser!(u64).range(1..=4_294_967_295))]
    subtree_objects: u64,
    /// Build only shard I of N (I from 0 to N-1): the subtrees of the
    /// fixed top (--top-levels) dealt to it by their estimated cost, so
    /// that shards take about the same time. Writes a part (to -o, else
    /// the model's path with .partI.v5dpart), which `vis5d merge` checks
    /// and joins with the other N-1 into the very file a single build
    /// writes. Not with --slices or --verify-views (they need the whole
    /// tree: run them on the merged file).
    #[arg(long, value_name = "I/N", value_parser = parse_shard,
          conflicts_with_all = ["conservative", "slices", "verify_views"])]
    shard: Option<(u32, u32)>,
    /// Save each finished subtree of the fixed top (--top-levels) in this
    /// folder as it completes (atomically), and on a run after an
    /// interruption take the ones saved instead of building them again:
    /// the file is byte for byte that of an uninterrupted build. A
    /// checkpoint that is damaged or from another build (another scene,
    /// other parameters) is refused, never used. The folder is kept
    /// afterwards (a rerun reuses it all); remove it when done.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["conservative", "dry_run"])]
    checkpoint: Option<PathBuf>,
    /// Slices (papers/004): cut every object into N slices along each
    /// axis (an object of over 1,024 triangles into pieces across x and y
    /// first) and store, per leaf, the slices that the extended-projection
    /// oracle proves hidden from the leaf's box of positions, on the
    /// sampled tree as on the conservative one. Queries then answer the
    /// ranges of each visible object's triangles to draw (`vis5d query
    /// --triangles`, `Pvs::query_view_triangles`). One oracle run per
    /// distinct box of positions [0 (off) to 127].
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=127))]
    slices: u8,
    /// The objects' ids, as the engine calls them: a JSON object from
    /// default ids to ids. An object's default id is its name, or, where
    /// names repeat, the name and its occurrence in the model (`crate#1`,
    /// `crate#2`). A glTF node may give its own id (`"extras": {"vis5d":
    /// {"id": "door-17"}}`); this file's ids replace the model's (its keys
    /// are still the default ids). Ids are stored in the .v5d (`query
    /// --json --ids`, `Pvs::object_index`); unique, 1 to 1024 bytes, no
    /// NUL.
    #[arg(long, value_name = "IDS.json")]
    ids: Option<PathBuf>,
    /// Objects' flags, the overrides engines offer: a JSON object from
    /// default ids (as for --ids) to lists of flags, for example
    /// `{"sky": ["always_visible"], "window#2": ["never_occluder"]}`.
    /// `always_visible`: in every set, never tested (a sky, what must
    /// never be culled). `never_occluder`: rays pass through it (glass,
    /// foliage, fences): it is seen where a ray reaches it and hides
    /// nothing. Added to the flags the model gives (a glTF node's
    /// `"extras": {"vis5d": {"flags": ["never_occluder"]}}`). Honoured by
    /// the builder and the oracles, stored in the .v5d (`query --json
    /// --ids` shows them; `vis5d check` honours them).
    #[arg(long, value_name = "FLAGS.json")]
    flags: Option<PathBuf>,
}

impl BuildArgs {
    /// The parameters, all but the view box, which needs the scene's
    /// frame ([`WorldBox::to_local`]).
    fn params(&self) -> BuildParams {
        let split_score = self.split_score;
        BuildParams {
            sprt: SprtParams {
                s_thresh: self.s_thresh,
                accept: self.accept,
                reject: self.reject,
                prior_a: self.prior.0,
                prior_b: self.prior.1,
                max_rays: self.max_rays,
            },
            internal_miss_factor: self.internal_miss_factor,
            cache_rays: self.cache_rays,
            split_score,
            split_threshold: self
                .split_threshold
                .unwrap_or(split_score.default_threshold()),
            max_depth: self.max_depth.unwrap_or(BuildParams::default().max_depth),
            min_cell_fraction: self.min_cell,
            min_angle_fraction: self.min_angle,
            min_visible_triangles: self.min_visible_triangles,
            spatial_only: self.spatial_only,
            angular_leaves: self.angular_leaves,
            angular_candidates: self.angular_candidates,
            grid_bits: self.grid_bits,
            rejection_budget: self.rejection_budget,
            retest_rays: self.retest_rays,
            edge_rays: self.edge_rays,
            inherit_samples: !self.no_inherit_samples,
            view_box: None,
            view_grow: self.grow,
            seed: self.seed,
            max_nodes: self.max_nodes,
            top_levels: self.top_levels,
            subtree_objects: self.subtree_objects,
        }
    }
}

/// Everything `build` reports.
#[derive(Serialize)]
struct BuildReport {
    file: String,
    objects: usize,
    triangles: usize,
    view_box: [World; 2],
    #[serde(skip_serializing_if = "Option::is_none")]
    frame_origin: Option<[f64; 3]>,
    /// The scene's up axis.
    up: String,
    threads: usize,
    seed: u64,
    /// The fixed top's levels (`--top-levels`, or more for a scene of
    /// more objects than `--subtree-objects`).
    top_levels: u32,
    #[serde(flatten)]
    tree: ShapeReport,
    rays_cast: u64,
    cell_rays: u64,
    object_rays: u64,
    edge_rays: u64,
    rays_rejected: u64,
    rays_per_second: f64,
    decisions: DecisionReport,
    seconds: StageSeconds,
    pixel_error: Option<PixelErrorReport>,
    coding_sizes: Vec<CodingSize>,
    slices: Option<SliceReport>,
    written: Option<Written>,
}

/// What `--slices` added to the file.
#[derive(Serialize)]
struct SliceReport {
    /// Slices an axis.
    slices: u8,
    /// Pieces over all objects.
    pieces: usize,
    /// Oracle runs: one per distinct box of positions of the leaves.
    oracle_cells: usize,
    /// (leaf, object) pairs with hidden slices stored.
    entries: usize,
    seconds: f64,
}

/// With `--slices N`: the slices of `tree`'s leaves, proved by `oracle`
/// (made here, on the CPU, for a sampled tree), and what to report.
fn tree_slices(
    args: &BuildArgs,
    scene: &Scene,
    tree: &vis5d::tree::VisTree,
    oracle: Option<&Oracle>,
    conservative: bool,
) -> Result<Option<(vis5d::slices::TreeSlices, SliceReport)>> {
    if args.slices == 0 || args.dry_run {
        return Ok(None);
    }
    let start = Instant::now();
    let sliced = vis5d::slices::SlicedScene::new(scene, args.slices.into())
        .map_err(|e| anyhow::anyhow!("--slices: {e}"))?;
    let made;
    let oracle = match oracle {
        Some(o) => o,
        None => {
            made = Oracle::new(scene, OracleParams::default(), Rasteriser::cpu())?;
            &made
        }
    };
    let bar = progress_bar("slicing", 1);
    let cells = std::sync::atomic::AtomicUsize::new(0);
    let leaves = vis5d::slices::leaf_slices(tree, oracle, &sliced, conservative, &|done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        cells.store(total, std::sync::atomic::Ordering::Relaxed);
    });
    bar.finish_and_clear();
    let report = SliceReport {
        slices: args.slices,
        pieces: (0..scene.objects().len())
            .map(|o| sliced.pieces(o).len())
            .sum(),
        oracle_cells: cells.into_inner(),
        entries: leaves.iter().map(Vec::len).sum(),
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok(Some((vis5d::slices::TreeSlices { sliced, leaves }, report)))
}

/// What `build` wrote.
#[derive(Serialize)]
struct Written {
    path: String,
    bytes: usize,
    coding: String,
}

#[derive(Serialize)]
struct DecisionReport {
    proven_by_hit: u64,
    sprt_invisible: u64,
    decided_by_ancestors: u64,
    cap_reached: u64,
    geometry_invisible: u64,
    rejection_kept: u64,
    retested: u64,
    retest_found: u64,
    edge_found: u64,
}

#[derive(Serialize)]
struct StageSeconds {
    load: f64,
    bvh: f64,
    build: f64,
    tracing: f64,
    tracing_share: f64,
    verify: f64,
}

#[derive(Serialize)]
struct PixelErrorReport {
    views: u32,
    resolution: u32,
    hit_pixels: u64,
    missing_pixels: u64,
    fraction: f64,
    worst_view: f64,
    missing_objects: Vec<(String, u64)>,
}

/// Runs `vis5d build`.
pub fn run(args: &BuildArgs) -> Result<()> {
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.into())
            .build_global()
            .context("cannot set up the thread pool")?;
    }
    if args.conservative {
        return run_conservative(args);
    }
    let mut params = args.params();
    params.validate().map_err(|e| match &e {
        BuildError::Parameter { name, .. } => anyhow::anyhow!("{}: {e}", build_flag(name)),
        _ => e.into(),
    })?;
    let output = checked_output(args)?;
    // Work whose size is known: the caches of cell rays (a 5D point and a
    // hit per ray, one cache per level of each thread's recursion) and
    // one verification view's rays and hits.
    let threads = rayon::current_num_threads() as u64;
    memory::check(
        u64::from(args.cache_rays) * 32 * (u64::from(params.max_depth) + 1) * threads,
        "--cache-rays",
        "cache fewer rays or build shallower trees",
    )?;
    let (scene, load_seconds) = load_scene_up(&args.file, args.up)?;
    let scene = crate::common::with_flags(args.flags.as_deref(), scene)?;
    let ids = object_ids(args, &scene)?;
    if let Some(local) = local_view_box(args, &scene)? {
        params.view_box = Some(local);
        params
            .validate()
            .map_err(|e| anyhow::anyhow!("--view-box: {e} (in the scene's local frame)"))?;
    }
    params.max_nodes = node_budget(&scene, params.max_nodes);
    let start = Instant::now();
    let tracer = Tracer::new(&scene);
    let bvh_seconds = start.elapsed().as_secs_f64();
    if let Some(shard) = args.shard {
        return run_shard(
            args,
            &scene,
            &tracer,
            &params,
            ids.as_deref(),
            shard,
            &output,
        );
    }

    let bar = progress_bar("building", 1000);
    let (subtrees, stats) =
        build_subtrees(args, &scene, &tracer, &params, ids.as_deref(), None, &bar)?;
    bar.finish_and_clear();
    let trees: Vec<_> = subtrees.into_iter().map(|(_, t)| t).collect();
    let root = vis5d::geom::cell::Cell::all_directions(params.root_box(&scene));
    let tree = vis5d::builder::graft(root, params.fixed_levels(&scene), params.grid_bits, &trees)
        .map_err(|e| anyhow::anyhow!("internal error: {e}"))?;
    tree.validate()
        .map_err(|e| anyhow::anyhow!("internal error: the built tree is inconsistent: {e}"))?;
    let summary = vis5d::builder::summarize(&tree, &scene);

    let start = Instant::now();
    let verify = (args.verify_views > 0).then(|| {
        let v = VerifyParams {
            views: args.verify_views,
            resolution: args.verify_resolution,
            ..VerifyParams::default()
        };
        vis5d::builder::pixel_error(&scene, &tracer, &tree, &v)
    });
    let verify_seconds = start.elapsed().as_secs_f64();
    let sizes = coding_sizes(&tree);
    let slices = tree_slices(args, &scene, &tree, None, false)?;
    let written = if args.dry_run {
        None
    } else {
        let mut file = vis5d::builder::to_file(&scene, tree.clone(), &params, args.coding);
        file.slices = slices.as_ref().map(|(s, _)| s.clone());
        set_ids(&mut file, ids.as_deref());
        Some(write_tree(&file, &output)?)
    };
    let mut report = build_report(
        args,
        &params,
        &scene,
        summary,
        &stats,
        verify.as_ref(),
        [load_seconds, bvh_seconds, verify_seconds],
    );
    report.coding_sizes = sizes;
    report.slices = slices.map(|(_, r)| r);
    report.written = written;
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
    } else {
        print_build(&mut out, &report)?;
    }
    Ok(())
}

/// The subtrees of the fixed top that `shard` builds (all of them
/// without), in index order, resumed from and saved to `--checkpoint`
/// when given, with the build's statistics (of the subtrees built now).
fn build_subtrees(
    args: &BuildArgs,
    scene: &Scene,
    tracer: &Tracer,
    params: &BuildParams,
    ids: Option<&[String]>,
    shard: Option<(u32, u32)>,
    bar: &indicatif::ProgressBar,
) -> Result<(Vec<(u32, vis5d::tree::VisTree)>, BuildStats)> {
    let checkpoints = args
        .checkpoint
        .as_deref()
        .map(|dir| Checkpoints::open(dir, scene, params, ids))
        .transpose()?;
    let done = match &checkpoints {
        Some(c) => c.read()?,
        None => Vec::new(),
    };
    if !done.is_empty() {
        say!(
            "resuming: {} subtrees from {}",
            done.len(),
            args.checkpoint
                .as_deref()
                .expect("checkpoints read")
                .display()
        );
    }
    let save = |index: u32, tree: &vis5d::tree::VisTree| {
        if let Some(c) = &checkpoints {
            c.save(index, tree);
        }
    };
    let built = vis5d::builder::build_resuming(
        scene,
        tracer,
        params,
        shard,
        done,
        &save,
        &|f| bar.set_position((f * 1000.0) as u64),
        None,
    )
    .map_err(|e| match e {
        BuildError::TooManyNodes { .. } if params.max_nodes < args.max_nodes => anyhow::anyhow!(
            "{e} (the memory budget, {}, holds {} nodes of this scene)",
            memory::human(memory::budget().unwrap_or(0)),
            params.max_nodes
        ),
        BuildError::Parameter {
            name: "resumed subtree",
            ..
        } => anyhow::anyhow!(
            "{}: a checkpoint does not fit this build ({e}); remove the folder to start again",
            args.checkpoint
                .as_deref()
                .map_or(String::new(), |d| d.display().to_string())
        ),
        e => e.into(),
    })?;
    if let Some(c) = checkpoints {
        c.finish()?;
    }
    Ok(built)
}

/// Parses `I/N`, a shard of a build: I below N, N from 1 to 65,536.
fn parse_shard(s: &str) -> Result<(u32, u32), String> {
    let (i, n) = s.split_once('/').ok_or("expected I/N, as 0/4")?;
    let p = |x: &str| x.trim().parse::<u32>().map_err(|e| format!("{x:?}: {e}"));
    let (i, n) = (p(i)?, p(n)?);
    if !(1..=65_536).contains(&n) {
        return Err(format!("the number of shards must be 1 to 65536, not {n}"));
    }
    if i >= n {
        return Err(format!(
            "shards count from 0: shard {i} of {n} does not exist (0 to {})",
            n - 1
        ));
    }
    Ok((i, n))
}

/// `vis5d build --shard I/N`: the shard's subtrees of `scene` (traced by
/// `tracer`, ids `ids`), written to `output` as a part.
fn run_shard(
    args: &BuildArgs,
    scene: &Scene,
    tracer: &Tracer,
    params: &BuildParams,
    ids: Option<&[String]>,
    (shard, shards): (u32, u32),
    output: &std::path::Path,
) -> Result<()> {
    let start = Instant::now();
    let bar = progress_bar(&format!("building shard {shard}/{shards}"), 1000);
    let (subtrees, stats) = build_subtrees(
        args,
        scene,
        tracer,
        params,
        ids,
        Some((shard, shards)),
        &bar,
    )?;
    bar.finish_and_clear();
    let count = subtrees.len();
    let part = codec::V5dPart {
        top_levels: params.fixed_levels(scene),
        shard,
        shards,
        coding: args.coding,
        subtrees: subtrees
            .into_iter()
            .map(|(index, tree)| {
                // Any coding reads back the same tree; the merge codes the
                // whole one as asked.
                let mut file = vis5d::builder::to_file(scene, tree, params, Some(Coding::Parent));
                set_ids(&mut file, ids);
                (index, file)
            })
            .collect(),
    };
    let bytes = codec::write_part(&part);
    if !args.dry_run {
        vis5d::atomic_write::write_atomic(output, &bytes)
            .with_context(|| format!("{}: cannot write the part", output.display()))?;
    }
    let seconds = start.elapsed().as_secs_f64();
    let mut out = io::stdout().lock();
    if args.json {
        let report = serde_json::json!({
            "file": args.file.display().to_string(),
            "shard": shard,
            "shards": shards,
            "top_levels": params.fixed_levels(scene),
            "subtrees": count,
            "rays_cast": stats.rays(),
            "seconds": seconds,
            "written": (!args.dry_run).then(|| output.display().to_string()),
            "bytes": bytes.len(),
        });
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
    } else {
        writeln!(
            out,
            "shard {shard}/{shards}: {count} of the {} subtrees, {} rays, {seconds:.2} s{}",
            1u64 << params.fixed_levels(scene),
            stats.rays(),
            if args.dry_run {
                String::new()
            } else {
                format!("; wrote {} ({} bytes)", output.display(), bytes.len())
            }
        )?;
    }
    Ok(())
}

/// The flag behind a parameter of the builder or the bake, as their
/// errors name it.
fn build_flag(name: &str) -> String {
    match name {
        "min_cell_fraction" => "--min-cell".to_owned(),
        "min_angle_fraction" => "--min-angle".to_owned(),
        "view_grow" => "--grow".to_owned(),
        "view_box" => "--view-box".to_owned(),
        "max_depth (plus the angular cuts)" => "--max-depth".to_owned(),
        other => flag(other),
    }
}

/// Where the tree goes (`-o`, else beside the model), checked before any
/// work (unless `--dry-run`), and the memory of a verification view.
fn checked_output(args: &BuildArgs) -> Result<PathBuf> {
    let output = args.output.clone().unwrap_or_else(|| match args.shard {
        Some((i, _)) => args.file.with_extension(format!("part{i}.v5dpart")),
        None => args.file.with_extension("v5d"),
    });
    if !args.dry_run {
        // Fail before the build, not after it.
        let mut inputs = vec![args.file.as_path()];
        inputs.extend(args.ids.as_deref());
        inputs.extend(args.flags.as_deref());
        check_output(&output, "tree", &inputs)?;
    }
    if args.verify_views > 0 {
        memory::check(
            u64::from(args.verify_resolution).pow(2) * 48,
            "--verify-resolution",
            "render smaller verification views",
        )?;
    }
    Ok(output)
}

/// `--view-box` in the scene's local frame, if given.
fn local_view_box(args: &BuildArgs, scene: &Scene) -> Result<Option<vis5d::geom::Aabb>> {
    let Some(b) = args.view_box else {
        return Ok(None);
    };
    let local = b.to_local(&scene.frame());
    if !(local.min.is_finite() && local.max.is_finite()) {
        bail!(
            "--view-box: the box reaches too far from the scene (its coordinates relative \
             to the scene must fit in f32, about 3e38)"
        );
    }
    Ok(Some(local))
}

/// `max_nodes`, lowered to what the memory budget holds of the tree's
/// nodes (a set of bits per object, and bookkeeping).
fn node_budget(scene: &Scene, max_nodes: u64) -> u64 {
    let node_bytes = 2 * (scene.objects().len().div_ceil(64) as u64 * 8 + 64);
    let by_memory = memory::budget().map_or(u64::MAX, |b| b / node_bytes);
    max_nodes.min(by_memory.max(1))
}

/// The objects' ids with `--ids` applied (checked before the build), or
/// `None` for the scene's own ([`Scene::ids`]: the model's ids, else the
/// default ones). The sidecar's keys are the default ids, whatever the
/// model calls the objects; its ids replace the model's.
fn object_ids(args: &BuildArgs, scene: &vis5d::scene::Scene) -> Result<Option<Vec<String>>> {
    let Some(path) = &args.ids else {
        return Ok(None);
    };
    let bytes = vis5d::input::read_regular(path, 64 << 20)
        .with_context(|| format!("{}: cannot read the ids", path.display()))?;
    let user: std::collections::HashMap<String, String> = serde_json::from_slice(&bytes)
        .with_context(|| {
            format!(
                "{}: expected a JSON object from default ids (names, or name#k where names repeat) to ids",
                path.display()
            )
        })?;
    let defaults = codec::default_ids(scene.objects().iter().map(|o| o.name.as_str()));
    let mut ids = scene.ids();
    codec::replace_ids(&defaults, &mut ids, &user)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(Some(ids))
}

/// Puts `ids` (when given) into the file's object table.
pub(crate) fn set_ids(file: &mut codec::V5dFile, ids: Option<&[String]>) {
    if let Some(ids) = ids {
        for (o, id) in file.objects.iter_mut().zip(ids) {
            o.id = id.clone();
        }
    }
}

/// Writes `file` to `output` atomically, after checking that it decodes
/// to the same tree.
fn write_tree(file: &codec::V5dFile, output: &std::path::Path) -> Result<Written> {
    let bytes = codec::write_file(file);
    // Encode -> decode must be the identity: check before writing.
    let back = codec::read_file(&bytes, codec::ReadLimits::default())
        .map_err(|e| anyhow::anyhow!("internal error: the coded tree does not decode: {e}"))?;
    if back.tree != file.tree {
        bail!("internal error: the coded tree decodes to another tree");
    }
    if back.slices != file.slices {
        bail!("internal error: the slices decode to other slices");
    }
    vis5d::atomic_write::write_atomic(output, &bytes)
        .with_context(|| format!("{}: cannot write the tree", output.display()))?;
    Ok(Written {
        path: output.display().to_string(),
        bytes: bytes.len(),
        coding: file.coding.name().to_owned(),
    })
}

/// What `build --conservative` reports.
#[derive(Serialize)]
struct BakeReport {
    method: &'static str,
    file: String,
    objects: usize,
    triangles: usize,
    view_box: [World; 2],
    #[serde(skip_serializing_if = "Option::is_none")]
    frame_origin: Option<[f64; 3]>,
    /// The scene's up axis.
    up: String,
    threads: usize,
    rasteriser: String,
    triangle_budget: u64,
    #[serde(flatten)]
    tree: ShapeReport,
    oracle_cells: u64,
    cells_split: u64,
    leaves_over_budget: u64,
    oracle_ms_per_cell: f64,
    seconds: BakeSeconds,
    pixel_error: Option<PixelErrorReport>,
    coding_sizes: Vec<CodingSize>,
    slices: Option<SliceReport>,
    written: Option<Written>,
}

#[derive(Serialize)]
struct BakeSeconds {
    load: f64,
    occluders: f64,
    bake: f64,
    verify: f64,
}

/// Runs `vis5d build --conservative`.
fn run_conservative(args: &BuildArgs) -> Result<()> {
    let mut params = BakeParams {
        triangle_budget: args.triangle_budget,
        max_depth: args.max_depth.unwrap_or(BakeParams::default().max_depth),
        min_cell_fraction: args.min_cell,
        // The bake cuts at middles only: one bit codes them.
        grid_bits: 1,
        view_box: None,
        view_grow: args.grow,
        max_nodes: args.max_nodes,
        try_cuts: args.try_cuts,
        stall_levels: args.stall_levels,
    };
    let bake_flag = |e: BakeError| match &e {
        BakeError::Parameter { name, .. } => anyhow::anyhow!("{}: {e}", build_flag(name)),
        _ => e.into(),
    };
    params.validate().map_err(bake_flag)?;
    let output = checked_output(args)?;
    let (scene, load_seconds) = load_scene_up(&args.file, args.up)?;
    let scene = crate::common::with_flags(args.flags.as_deref(), scene)?;
    let ids = object_ids(args, &scene)?;
    if let Some(local) = local_view_box(args, &scene)? {
        params.view_box = Some(local);
        params
            .validate()
            .map_err(|e| anyhow::anyhow!("--view-box: {e} (in the scene's local frame)"))?;
    }
    params.max_nodes = node_budget(&scene, params.max_nodes);
    let rasteriser = if args.gpu {
        gpu_else_cpu()
    } else {
        Rasteriser::cpu()
    };
    let start = Instant::now();
    let oracle_params = OracleParams {
        sweep_planes: args.sweep_planes.into(),
        sweep_patches: args.sweep_patches.into(),
        sweep_reach: args.sweep_reach.into(),
        shaft_budget: args.shaft_budget as usize,
        seal_voxels: args.seal_voxels as usize,
        ..OracleParams::default()
    };
    let oracle = Oracle::new(&scene, oracle_params, rasteriser)?;
    let occluder_seconds = start.elapsed().as_secs_f64();
    let bar = progress_bar("baking", 1000);
    let gpu_warning = GpuWarning::default();
    let (tree, stats) = vis5d::conservative::bake(&oracle, &params, &|f| {
        bar.set_position((f * 1000.0) as u64);
        gpu_warning.poll(oracle.rasteriser());
    })
    .map_err(|e| match e {
        BakeError::TooManyNodes { .. } if params.max_nodes < args.max_nodes => anyhow::anyhow!(
            "{e} (the memory budget, {}, holds {} nodes of this scene)",
            memory::human(memory::budget().unwrap_or(0)),
            params.max_nodes
        ),
        e => bake_flag(e),
    })?;
    bar.finish_and_clear();
    gpu_warning.finish(oracle.rasteriser());
    tree.validate()
        .map_err(|e| anyhow::anyhow!("internal error: the baked tree is inconsistent: {e}"))?;
    let slices = tree_slices(args, &scene, &tree, Some(&oracle), true)?;
    let summary = vis5d::builder::summarize(&tree, &scene);
    let start = Instant::now();
    let verify = (args.verify_views > 0).then(|| {
        let tracer = Tracer::new(&scene);
        let v = VerifyParams {
            views: args.verify_views,
            resolution: args.verify_resolution,
            ..VerifyParams::default()
        };
        vis5d::builder::pixel_error(&scene, &tracer, &tree, &v)
    });
    let verify_seconds = start.elapsed().as_secs_f64();
    let coding_sizes = coding_sizes(&tree);
    let text = params.to_text(&oracle);
    let written = if args.dry_run {
        None
    } else {
        let mut file = vis5d::builder::file_with_params(&scene, tree, text, args.coding);
        file.slices = slices.as_ref().map(|(s, _)| s.clone());
        set_ids(&mut file, ids.as_deref());
        Some(write_tree(&file, &output)?)
    };
    let b = params.root_box(&scene);
    let frame = scene.frame();
    let report = BakeReport {
        method: vis5d::codec::METHOD_CONSERVATIVE,
        file: args.file.display().to_string(),
        objects: scene.objects().len(),
        triangles: scene.triangles().len(),
        view_box: [World(frame, b.min), World(frame, b.max)],
        frame_origin: (!frame.at_world_origin()).then(|| frame.origin.to_array()),
        up: frame.up.to_string(),
        threads: rayon::current_num_threads(),
        rasteriser: oracle.rasteriser().name(),
        triangle_budget: params.budget(&scene),
        tree: summary.into(),
        oracle_cells: stats.cells,
        cells_split: stats.split,
        leaves_over_budget: stats.over_budget_leaves,
        oracle_ms_per_cell: stats.oracle_time.as_secs_f64() * 1e3 / stats.cells.max(1) as f64,
        seconds: BakeSeconds {
            load: load_seconds,
            occluders: occluder_seconds,
            bake: stats.seconds,
            verify: verify_seconds,
        },
        pixel_error: verify.as_ref().map(|v| pixel_error_report(v, args, &scene)),
        coding_sizes,
        slices: slices.map(|(_, r)| r),
        written,
    };
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
    } else {
        print_bake(&mut out, &report)?;
    }
    Ok(())
}

fn print_bake(out: &mut impl Write, r: &BakeReport) -> io::Result<()> {
    writeln!(
        out,
        "{}: {} objects, {} triangles (conservative bake)",
        r.file, r.objects, r.triangles
    )?;
    print_shape(out, r.view_box, &r.tree)?;
    writeln!(
        out,
        "  oracle           {} cells ({:.1} ms each, {}), {} cut over the budget of {} triangles, {} leaves still over it",
        r.oracle_cells,
        r.oracle_ms_per_cell,
        r.rasteriser,
        r.cells_split,
        r.triangle_budget,
        r.leaves_over_budget
    )?;
    let s = &r.seconds;
    writeln!(
        out,
        "  seconds          load {:.3}, occluders {:.3}, bake {:.3} ({} threads), verify {:.3}",
        s.load, s.occluders, s.bake, r.threads, s.verify
    )?;
    print_tail(
        out,
        r.pixel_error.as_ref(),
        &r.coding_sizes,
        r.slices.as_ref(),
        r.written.as_ref(),
    )
}

fn pixel_error_report(v: &PixelError, args: &BuildArgs, scene: &Scene) -> PixelErrorReport {
    PixelErrorReport {
        views: v.views,
        resolution: args.verify_resolution,
        hit_pixels: v.hit_pixels,
        missing_pixels: v.missing_pixels,
        fraction: v.fraction(),
        worst_view: v.worst_view,
        missing_objects: v
            .missing_objects
            .iter()
            .map(|&(o, n)| (scene.objects()[o as usize].name.clone(), n))
            .collect(),
    }
}

fn build_report(
    args: &BuildArgs,
    params: &BuildParams,
    scene: &Scene,
    s: TreeSummary,
    stats: &BuildStats,
    verify: Option<&PixelError>,
    [load, bvh, verify_seconds]: [f64; 3],
) -> BuildReport {
    let b = params.root_box(scene);
    let frame = scene.frame();
    let threads = rayon::current_num_threads();
    let d = stats.decisions;
    BuildReport {
        file: args.file.display().to_string(),
        objects: scene.objects().len(),
        triangles: scene.triangles().len(),
        view_box: [World(frame, b.min), World(frame, b.max)],
        frame_origin: (!frame.at_world_origin()).then(|| frame.origin.to_array()),
        up: frame.up.to_string(),
        threads,
        seed: params.seed,
        top_levels: params.fixed_levels(scene),
        tree: s.into(),
        rays_cast: stats.rays(),
        cell_rays: stats.cell_rays,
        object_rays: stats.object_rays,
        edge_rays: stats.edge_rays,
        rays_rejected: stats.rejected,
        rays_per_second: stats.rays() as f64 / stats.seconds.max(1e-9),
        decisions: DecisionReport {
            proven_by_hit: d.proven_by_hit,
            sprt_invisible: d.sprt_invisible,
            decided_by_ancestors: d.decided_by_ancestors,
            cap_reached: d.cap_reached,
            geometry_invisible: d.geometry_invisible,
            rejection_kept: d.rejection_kept,
            retested: d.retested,
            retest_found: d.retest_found,
            edge_found: d.edge_found,
        },
        seconds: StageSeconds {
            load,
            bvh,
            build: stats.seconds,
            tracing: stats.trace_seconds,
            tracing_share: stats.trace_seconds / (stats.seconds * threads as f64).max(1e-9),
            verify: verify_seconds,
        },
        pixel_error: verify.map(|v| pixel_error_report(v, args, scene)),
        coding_sizes: Vec::new(),
        slices: None,
        written: None,
    }
}

fn print_build(out: &mut impl Write, r: &BuildReport) -> io::Result<()> {
    writeln!(
        out,
        "{}: {} objects, {} triangles",
        r.file, r.objects, r.triangles
    )?;
    print_shape(out, r.view_box, &r.tree)?;
    writeln!(
        out,
        "  rays             {} cast ({} cell, {} object samples, {} edge), {} samples rejected, {:.2} M/s",
        r.rays_cast,
        r.cell_rays,
        r.object_rays,
        r.edge_rays,
        r.rays_rejected,
        r.rays_per_second / 1e6
    )?;
    let d = &r.decisions;
    writeln!(
        out,
        "  decisions        {} proven by a hit, {} invisible by SPRT ({} on ancestors' samples alone),",
        d.proven_by_hit, d.sprt_invisible, d.decided_by_ancestors
    )?;
    writeln!(
        out,
        "                   {} invisible by geometry,",
        d.geometry_invisible
    )?;
    writeln!(
        out,
        "                   {} kept at the ray cap, {} kept after rejections,",
        d.cap_reached, d.rejection_kept
    )?;
    writeln!(
        out,
        "                   {} retested in leaves, {} of them found visible, {} found by edge rays",
        d.retested, d.retest_found, d.edge_found
    )?;
    let s = &r.seconds;
    writeln!(
        out,
        "  seconds          load {:.3}, bvh {:.3}, build {:.3} ({:.0}% tracing, {} threads), verify {:.3}",
        s.load,
        s.bvh,
        s.build,
        100.0 * s.tracing_share,
        r.threads,
        s.verify
    )?;
    print_tail(
        out,
        r.pixel_error.as_ref(),
        &r.coding_sizes,
        r.slices.as_ref(),
        r.written.as_ref(),
    )
}

/// The pixel error, the coded sizes and what was written.
fn print_tail(
    out: &mut impl Write,
    pixel_error: Option<&PixelErrorReport>,
    coding_sizes: &[CodingSize],
    slices: Option<&SliceReport>,
    written: Option<&Written>,
) -> io::Result<()> {
    if let Some(s) = slices {
        writeln!(
            out,
            "  slices           {} an axis, {} pieces; {} leaf objects with hidden slices ({} oracle cells, {:.3} s)",
            s.slices, s.pieces, s.entries, s.oracle_cells, s.seconds
        )?;
    }
    if let Some(p) = pixel_error {
        writeln!(
            out,
            "  pixel error      {:.4}% of {} hit pixels in {} views of {}x{} (worst view {:.3}%)",
            100.0 * p.fraction,
            p.hit_pixels,
            p.views,
            p.resolution,
            p.resolution,
            100.0 * p.worst_view
        )?;
        for (name, n) in p.missing_objects.iter().take(5) {
            writeln!(out, "                   {n} pixels of {name:?} missing")?;
        }
    }
    let sizes: Vec<String> = coding_sizes
        .iter()
        .map(|c| format!("{} {} B", c.coding, c.bytes))
        .collect();
    writeln!(out, "  coded tree       {}", sizes.join(", "))?;
    match written {
        Some(w) => writeln!(
            out,
            "  wrote            {} ({} bytes, {} coding)",
            w.path, w.bytes, w.coding
        )?,
        None => writeln!(out, "  nothing written (--dry-run)")?,
    }
    Ok(())
}
