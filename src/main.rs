//! The `vis5d` command-line tool: glue between the flags and the library.
//! Flags are parsed by clap into one struct per subcommand, checked, then
//! handed to the library; errors are reported once, here, with `anyhow`.

use std::io::{self, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use vis5d::builder::{BuildParams, BuildStats, PixelError, VerifyParams};
use vis5d::codec::{self, Coding, code_size};
use vis5d::geom::Aabb;
use vis5d::query::{Pvs, View};
use vis5d::scene::procedural::{self, SceneKind};
use vis5d::scene::{self, Scene};
use vis5d::sprt::SprtParams;
use vis5d::trace::Tracer;
use vis5d::tree::{TreeSummary, VisTree};

mod cli_oracle;
mod cli_report;

/// Precomputed from-region visibility for static 3D scenes.
///
/// vis5d finds which objects of a scene can be seen from which regions of
/// view space (positions x directions), so that a renderer draws only
/// those. Scenes are OBJ, glTF or GLB files; objects are OBJ `o` groups
/// (else `g` groups) or glTF nodes with a mesh.
#[derive(Parser, Debug)]
#[command(name = "vis5d", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Load a scene and print a summary of its objects and triangles.
    ///
    /// Checks the file as the builder will see it: polygons triangulated,
    /// zero-area triangles dropped, groups without triangles dropped,
    /// repeated object names reported. Bad input (syntax errors, indices out
    /// of range, NaN or infinite coordinates, no triangles) is an error that
    /// names the file and, for OBJ, the line.
    Info(InfoArgs),
    /// Build the 5D visibility tree of a scene (papers/003).
    ///
    /// Casts rays from random points of 5D view cells (a box of positions
    /// times a range of directions) to random points on the objects,
    /// decides each object's visibility with the beta-function SPRT, and
    /// splits cells where the split's effectiveness E(A, B) is high. Prints
    /// the tree's shape, its sets, the rays cast and the decisions made.
    /// `--verify-views N` then renders N random views and reports the
    /// pixel error: pixels showing an object missing from their leaf's set.
    /// The tree is written to a .v5d file (next to the model unless `-o`
    /// says otherwise), atomically: an interrupted build leaves no partial
    /// file.
    Build(BuildArgs),
    /// Print a .v5d file's header, its tree's shape and the size each of
    /// the three set codings would take.
    Stat(StatArgs),
    /// Answer view queries from a .v5d file: the objects visible from a
    /// position (or a box of positions) looking along a direction.
    ///
    /// Prints the names of the potentially visible objects. `--views FILE`
    /// answers many views at once: a JSON list of {"pos": [x,y,z], "dir":
    /// [x,y,z], "fov": degrees} (square field of view, up = +z unless the
    /// direction is vertical).
    Query(QueryArgs),
    /// Run the conservative extended-projection oracle (papers/001) for one
    /// view cell.
    ///
    /// Prints the objects it cannot prove hidden from any point of the
    /// cell (a box of viewpoints, all directions): a superset of the
    /// visible ones. Six projection planes around the cell collect the
    /// occlusion of convex occluders (whole convex objects, merged
    /// coplanar polygons, triangles) into Depth Maps; object boxes are
    /// tested against them. Prints the planes, the timings and the
    /// objects.
    Oracle(cli_oracle::OracleArgs),
    /// Cross-check a built tree against the oracle.
    ///
    /// For the leaves' spatial cells (all, or `--sample N` of them) runs the
    /// oracle, restricts its set to each leaf's directions, and reports:
    /// violations (objects a ray of the leaf hits that the oracle calls
    /// hidden: must be none, else the command fails and names them);
    /// suspects (objects the oracle keeps and the leaf lacks), each
    /// resolved by a burst of aimed rays into a confirmed miss of the
    /// sampler (with the visible fraction found) or not found; and the
    /// mean sizes of the oracle's, the sampled and the ground-truth sets.
    /// `--json` gives every leaf's detail.
    Check(cli_oracle::CheckArgs),
    /// Compare visibility methods on a scene against a ray-cast ground
    /// truth, and write a report page.
    ///
    /// For a set of views (random ones in the tree's view box, or a camera
    /// path from `--views`), renders ID buffers by casting one ray per
    /// pixel, then measures for each method (view-frustum culling, the lazy
    /// occlusion grid of Hey et al. with lazy and busy updates, the vis5d
    /// tree, the extended-projection oracle of a cell around the eye) the
    /// objects and triangles it draws, the pixels whose object it
    /// misses, the set errors Q_u and Q_o against the objects seen, and its
    /// time. Writes DIR/index.html (tables and SVG plots), DIR/report.json
    /// (every figure) and DIR/report.md.
    Report(cli_report::ReportArgs),
    /// Generate a procedural test scene and write it as OBJ.
    ///
    /// Kinds: apartment (two furnished rooms joined by a door, ~170 objects,
    /// ~3,000 triangles), office (twelve offices along a corridor), city
    /// (blocks of buildings along streets), forest (trees of a trunk and
    /// many small leaf triangles), machine (a closed casing with a
    /// ventilation grating and many internal parts). The same kind, seed and
    /// replication always give the same file.
    Scene(SceneArgs),
}

#[derive(Args, Debug)]
struct InfoArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
    /// Print the summary as JSON (with every object) instead of text.
    #[arg(long)]
    json: bool,
    /// List every object (index, name, triangles, area, bounds).
    #[arg(long)]
    objects: bool,
}

#[derive(Args, Debug)]
struct BuildArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
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
    /// The positions to build for, as x0,y0,z0,x1,y1,z1 [default: the
    /// scene's bounding box].
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", value_parser = parse_box)]
    view_box: Option<Aabb>,
    /// Grow the view box by this fraction of its diagonal on every side.
    #[arg(long, default_value_t = 0.0)]
    grow: f32,
    /// Seed of every random stream: the same seed gives the same tree,
    /// whatever the thread count.
    #[arg(long, default_value_t = BuildParams::default().seed)]
    seed: u64,
    /// Threads [default: all cores].
    #[arg(long)]
    threads: Option<usize>,
    /// SPRT: the visible fraction separating visible from invisible.
    #[arg(long, default_value_t = BuildParams::default().sprt.s_thresh)]
    s_thresh: f64,
    /// SPRT: odds above which an object is visible (the paper's A).
    #[arg(long, default_value_t = BuildParams::default().sprt.accept)]
    accept: f64,
    /// SPRT: odds below which an object is invisible (the paper's B).
    #[arg(long, default_value_t = BuildParams::default().sprt.reject)]
    reject: f64,
    /// SPRT: the prior Beta(a, b) on the visible fraction, as a,b.
    #[arg(long, value_name = "A,B", value_parser = parse_pair,
          default_value = "1,50")]
    prior: (f64, f64),
    /// SPRT: rays after which an undecided object is kept as visible.
    #[arg(long, default_value_t = BuildParams::default().sprt.max_rays)]
    max_rays: u32,
    /// Internal nodes declare an object invisible only after this many
    /// times the misses the SPRT needs (their verdict holds for every cell
    /// below).
    #[arg(long, default_value_t = BuildParams::default().internal_miss_factor)]
    internal_miss_factor: u32,
    /// Uniform cell rays cached per cell to score splits.
    #[arg(long, default_value_t = BuildParams::default().cache_rays)]
    cache_rays: u32,
    /// Split only when the effectiveness E(A, B) exceeds this.
    #[arg(long, default_value_t = BuildParams::default().split_threshold)]
    split_threshold: f64,
    /// The deepest a leaf may be.
    #[arg(long, default_value_t = BuildParams::default().max_depth)]
    max_depth: u32,
    /// The smallest cell in x, y, z, as a fraction of the root's extent.
    #[arg(long, default_value_t = BuildParams::default().min_cell_fraction)]
    min_cell: f32,
    /// The smallest cell in theta and phi, as a fraction of 2 pi and pi.
    #[arg(long, default_value_t = BuildParams::default().min_angle_fraction)]
    min_angle: f32,
    /// Split a cell only if its set holds at least this many triangles
    /// (the paper: 500).
    #[arg(long, default_value_t = BuildParams::default().min_visible_triangles)]
    min_visible_triangles: u64,
    /// Split x, y, z only, then cut each final cell into
    /// --angular-leaves angular intervals.
    #[arg(long)]
    spatial_only: bool,
    /// With --spatial-only: angular intervals per final cell (a power of
    /// two; the paper used 8).
    #[arg(long, default_value_t = 1)]
    angular_leaves: u32,
    /// Candidate split values per angular dimension.
    #[arg(long, default_value_t = BuildParams::default().angular_candidates)]
    angular_candidates: u32,
    /// Split values lie on a 2^q grid of the node's range.
    #[arg(long, default_value_t = BuildParams::default().grid_bits)]
    grid_bits: u32,
    /// Rejected samples per object and cell after which it is kept as
    /// visible.
    #[arg(long, default_value_t = BuildParams::default().rejection_budget)]
    rejection_budget: u32,
    /// After building, render this many random views and report the pixel
    /// error.
    #[arg(long, default_value_t = 0)]
    verify_views: u32,
    /// Pixels per side of each verification view.
    #[arg(long, default_value_t = 64)]
    verify_resolution: u32,
}

/// Parses `x0,y0,z0,x1,y1,z1`.
fn parse_box(s: &str) -> Result<Aabb, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<Result<_, _>>()?;
    if v.len() != 6 {
        return Err(format!(
            "expected 6 numbers x0,y0,z0,x1,y1,z1, got {}",
            v.len()
        ));
    }
    let b = Aabb::new(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
    if !(b.min.is_finite() && b.max.is_finite() && b.min.cmplt(b.max).all()) {
        return Err("the box needs finite corners with x0 < x1, y0 < y1, z0 < z1".into());
    }
    Ok(b)
}

/// Parses `a,b`.
fn parse_pair(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or("expected two numbers a,b")?;
    let p = |x: &str| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}"));
    Ok((p(a)?, p(b)?))
}

#[derive(Args, Debug)]
struct StatArgs {
    /// The .v5d file.
    file: PathBuf,
    /// Print as JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
struct QueryArgs {
    /// The .v5d file.
    file: PathBuf,
    /// The eye position, x,y,z.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true, required_unless_present_any = ["views", "box"])]
    pos: Option<Vec3>,
    /// A box of eye positions instead of a point, x0,y0,z0,x1,y1,z1.
    #[arg(id = "box", long = "box", value_name = "X0,Y0,Z0,X1,Y1,Z1", value_parser = parse_box, allow_hyphen_values = true, conflicts_with = "pos")]
    positions: Option<Aabb>,
    /// The viewing direction, x,y,z.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true, required_unless_present = "views")]
    dir: Option<Vec3>,
    /// The up direction [default: +z, or +y when looking straight up or
    /// down].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    up: Option<Vec3>,
    /// The field of view in degrees, horizontal and vertical.
    #[arg(long, default_value_t = 90.0)]
    fov: f32,
    /// Answer every view of this JSON file instead.
    #[arg(long, value_name = "VIEWS.json", conflicts_with_all = ["pos", "box", "dir"])]
    views: Option<PathBuf>,
    /// The scene the file should have been built for: refuse the file if
    /// its geometry fingerprint differs.
    #[arg(long, value_name = "MODEL")]
    scene: Option<PathBuf>,
    /// Print as JSON: a list of names, or with --views a list of lists.
    #[arg(long)]
    json: bool,
}

/// Parses `x,y,z`.
fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Vec3::new(x, y, z)),
        [_, _, _] => Err("the coordinates must be finite".into()),
        _ => Err(format!("expected 3 numbers x,y,z, got {}", v.len())),
    }
}

#[derive(Args, Debug)]
struct SceneArgs {
    /// What to generate: apartment, office, city, forest or machine.
    kind: SceneKind,
    /// Where to write the OBJ file (written atomically).
    #[arg(short, long, value_name = "FILE.obj")]
    output: PathBuf,
    /// Seed of the random layout.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Number of copies: apartments and offices are stacked into a block
    /// (3 per floor), the other kinds tiled on the ground. `--replicate 18`
    /// of the apartment is the apartment block of papers/003 sec. 8.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    replicate: u32,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if matches!(cli.command, Command::Oracle(_) | Command::Check(_))
        && std::env::var_os("XDG_RUNTIME_DIR").is_none()
    {
        // Mesa's Vulkan drivers print an "error" to stderr when this is
        // unset (it is, in containers and CI), though nothing is wrong.
        // SAFETY: no other thread exists yet.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    let result = match cli.command {
        Command::Info(args) => info(&args),
        Command::Build(args) => build(&args),
        Command::Stat(args) => stat(&args),
        Command::Query(args) => query(&args),
        Command::Oracle(args) => cli_oracle::oracle(&args),
        Command::Check(args) => cli_oracle::check(&args),
        Command::Report(args) => cli_report::report(&args),
        Command::Scene(args) => generate_scene(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain()
        .filter_map(|c| c.downcast_ref::<io::Error>())
        .any(|e| e.kind() == io::ErrorKind::BrokenPipe)
}

/// Loads a scene with a progress bar on a terminal.
fn load_scene(path: &Path) -> Result<(Scene, f64)> {
    let bar = if io::stderr().is_terminal() {
        let bar = ProgressBar::new(0).with_style(
            ProgressStyle::with_template("loading {msg} [{bar:30}] {bytes}/{total_bytes} {eta}")
                .expect("the template is valid")
                .progress_chars("=> "),
        );
        bar.set_message(path.display().to_string());
        bar
    } else {
        ProgressBar::hidden()
    };
    let start = Instant::now();
    let result = scene::load_with_progress(path, &mut |done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    Ok((result?, start.elapsed().as_secs_f64()))
}

/// One object in `info --json`.
#[derive(Serialize)]
struct ObjectInfo<'a> {
    index: usize,
    name: &'a str,
    triangles: usize,
    area: f64,
    bounds: [[f32; 3]; 2],
}

/// The summary printed by `info`.
#[derive(Serialize)]
struct SceneInfo<'a> {
    file: String,
    format: String,
    objects: usize,
    triangles: usize,
    bounds: [[f32; 3]; 2],
    surface_area: f64,
    load_seconds: f64,
    dropped_degenerate_triangles: usize,
    dropped_empty_objects: &'a [String],
    skipped_non_triangles: usize,
    duplicate_names: Vec<DuplicateName<'a>>,
    object_list: Vec<ObjectInfo<'a>>,
}

#[derive(Serialize)]
struct DuplicateName<'a> {
    name: &'a str,
    count: usize,
}

fn info(args: &InfoArgs) -> Result<()> {
    let (scene, seconds) = load_scene(&args.file)?;
    let b = scene.bounds();
    let report = scene.report();
    let summary = SceneInfo {
        file: args.file.display().to_string(),
        format: scene.format().to_string(),
        objects: scene.objects().len(),
        triangles: scene.triangles().len(),
        bounds: [b.min.to_array(), b.max.to_array()],
        surface_area: scene.objects().iter().map(|o| o.area).sum(),
        load_seconds: seconds,
        dropped_degenerate_triangles: report.dropped_degenerate,
        dropped_empty_objects: &report.dropped_empty_objects,
        skipped_non_triangles: report.skipped_non_triangles,
        duplicate_names: report
            .duplicate_names
            .iter()
            .map(|(name, count)| DuplicateName {
                name,
                count: *count,
            })
            .collect(),
        object_list: scene
            .objects()
            .iter()
            .enumerate()
            .map(|(index, o)| ObjectInfo {
                index,
                name: &o.name,
                triangles: o.triangle_count(),
                area: o.area,
                bounds: [o.bounds.min.to_array(), o.bounds.max.to_array()],
            })
            .collect(),
    };
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, &summary)?;
        writeln!(out)?;
        return Ok(());
    }
    print_info(&mut out, &summary, args.objects)?;
    Ok(())
}

fn fmt_vec(v: [f32; 3]) -> String {
    format!("({}, {}, {})", v[0], v[1], v[2])
}

fn print_info(out: &mut impl Write, s: &SceneInfo, all_objects: bool) -> io::Result<()> {
    let [min, max] = s.bounds;
    let size = [max[0] - min[0], max[1] - min[1], max[2] - min[2]];
    writeln!(out, "{} ({})", s.file, s.format)?;
    writeln!(out, "  objects          {}", s.objects)?;
    writeln!(out, "  triangles        {}", s.triangles)?;
    writeln!(
        out,
        "  bounds           {} .. {}",
        fmt_vec(min),
        fmt_vec(max)
    )?;
    writeln!(
        out,
        "  size             {} x {} x {}",
        size[0], size[1], size[2]
    )?;
    writeln!(out, "  surface area     {:.6}", s.surface_area)?;
    writeln!(out, "  loaded in        {:.3} s", s.load_seconds)?;
    writeln!(
        out,
        "  dropped          {} zero-area triangles, {} groups without triangles",
        s.dropped_degenerate_triangles,
        s.dropped_empty_objects.len()
    )?;
    writeln!(
        out,
        "  skipped          {} lines and points",
        s.skipped_non_triangles
    )?;
    if s.duplicate_names.is_empty() {
        writeln!(out, "  duplicate names  none")?;
    } else {
        let total: usize = s.duplicate_names.iter().map(|d| d.count).sum();
        writeln!(
            out,
            "  duplicate names  {} names shared by {} objects (objects are told apart by index):",
            s.duplicate_names.len(),
            total
        )?;
        for d in s
            .duplicate_names
            .iter()
            .take(if all_objects { usize::MAX } else { 10 })
        {
            writeln!(out, "    {:?} x{}", d.name, d.count)?;
        }
        if !all_objects && s.duplicate_names.len() > 10 {
            writeln!(out, "    ... (--objects lists them all)")?;
        }
    }
    let mut listed: Vec<&ObjectInfo> = s.object_list.iter().collect();
    if all_objects {
        writeln!(out, "  objects:")?;
    } else {
        listed.sort_by_key(|o| std::cmp::Reverse(o.triangles));
        listed.truncate(5);
        writeln!(out, "  largest objects (--objects lists all):")?;
    }
    for o in listed {
        writeln!(
            out,
            "    #{:<6} {:>9} tris  area {:<12.4} {:?}",
            o.index, o.triangles, o.area, o.name
        )?;
    }
    Ok(())
}

fn generate_scene(args: &SceneArgs) -> Result<()> {
    if scene::SceneFormat::from_path(&args.output) != Some(scene::SceneFormat::Obj) {
        bail!("{}: the output must be an .obj file", args.output.display());
    }
    let start = Instant::now();
    let s = procedural::generate(args.kind, args.seed, args.replicate);
    let header = vec![
        format!(
            "vis5d procedural scene: {} --seed {} --replicate {}",
            args.kind, args.seed, args.replicate
        ),
        format!(
            "{} objects, {} triangles; units metres, z up",
            s.objects().len(),
            s.triangles().len()
        ),
    ];
    scene::write_obj_file(&s, &header, &args.output)
        .with_context(|| format!("{}: cannot write the scene", args.output.display()))?;
    eprintln!(
        "wrote {}: {} {} objects, {} triangles ({:.2} s)",
        args.output.display(),
        args.kind,
        s.objects().len(),
        s.triangles().len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

impl BuildArgs {
    fn params(&self) -> BuildParams {
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
            split_threshold: self.split_threshold,
            max_depth: self.max_depth,
            min_cell_fraction: self.min_cell,
            min_angle_fraction: self.min_angle,
            min_visible_triangles: self.min_visible_triangles,
            spatial_only: self.spatial_only,
            angular_leaves: self.angular_leaves,
            angular_candidates: self.angular_candidates,
            grid_bits: self.grid_bits,
            rejection_budget: self.rejection_budget,
            view_box: self.view_box,
            view_grow: self.grow,
            seed: self.seed,
        }
    }
}

/// Everything `build` reports.
#[derive(Serialize)]
struct BuildReport {
    file: String,
    objects: usize,
    triangles: usize,
    view_box: [[f32; 3]; 2],
    threads: usize,
    seed: u64,
    #[serde(flatten)]
    tree: ShapeReport,
    rays_cast: u64,
    cell_rays: u64,
    object_rays: u64,
    rays_rejected: u64,
    rays_per_second: f64,
    decisions: DecisionReport,
    seconds: StageSeconds,
    pixel_error: Option<PixelErrorReport>,
    coding_sizes: Vec<CodingSize>,
    written: Option<Written>,
}

/// A tree's shape and set sizes, as `build` and `stat` report them.
#[derive(Serialize)]
struct ShapeReport {
    nodes: usize,
    leaves: usize,
    depth: u32,
    mean_leaf_objects: f64,
    max_leaf_objects: usize,
    mean_leaf_triangles: f64,
    max_leaf_triangles: u64,
    measure_weighted_leaf_objects: f64,
}

impl From<TreeSummary> for ShapeReport {
    fn from(s: TreeSummary) -> Self {
        Self {
            nodes: s.nodes,
            leaves: s.leaves,
            depth: s.depth,
            mean_leaf_objects: s.mean_leaf_objects,
            max_leaf_objects: s.max_leaf_objects,
            mean_leaf_triangles: s.mean_leaf_triangles,
            max_leaf_triangles: s.max_leaf_triangles,
            measure_weighted_leaf_objects: s.measure_weighted_objects,
        }
    }
}

/// Prints the view box and the tree's shape, for `build` and `stat`.
fn print_shape(out: &mut impl Write, [min, max]: [[f32; 3]; 2], t: &ShapeReport) -> io::Result<()> {
    writeln!(
        out,
        "  view box         {} .. {}",
        fmt_vec(min),
        fmt_vec(max)
    )?;
    writeln!(
        out,
        "  tree             {} nodes, {} leaves, depth {}",
        t.nodes, t.leaves, t.depth
    )?;
    writeln!(
        out,
        "  leaf sets        mean {:.1} objects ({:.0} triangles), max {} objects ({} triangles)",
        t.mean_leaf_objects, t.mean_leaf_triangles, t.max_leaf_objects, t.max_leaf_triangles
    )?;
    writeln!(
        out,
        "                   {:.1} objects for a random view ray (measure-weighted)",
        t.measure_weighted_leaf_objects
    )
}

/// The size of a tree in one coding.
#[derive(Serialize)]
struct CodingSize {
    coding: String,
    structure_bits: u64,
    set_bits: u64,
    bytes: u64,
}

fn coding_sizes(tree: &VisTree) -> Vec<CodingSize> {
    Coding::ALL
        .iter()
        .map(|&c| {
            let s = code_size(tree, c);
            CodingSize {
                coding: c.name().to_owned(),
                structure_bits: s.structure_bits,
                set_bits: s.set_bits,
                bytes: s.bytes(),
            }
        })
        .collect()
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
    cap_reached: u64,
    geometry_invisible: u64,
    rejection_kept: u64,
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

fn build(args: &BuildArgs) -> Result<()> {
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .context("cannot set up the thread pool")?;
    }
    let params = args.params();
    params
        .check()
        .map_err(|e| anyhow::anyhow!("invalid build parameters: {e}"))?;
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| args.file.with_extension("v5d"));
    if !args.dry_run {
        // Fail before the build, not after it.
        let dir = output
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        if !dir.is_dir() {
            bail!(
                "{}: cannot write the tree there: {} is not a folder",
                output.display(),
                dir.display()
            );
        }
    }
    let (scene, load_seconds) = load_scene(&args.file)?;
    let start = Instant::now();
    let tracer = Tracer::new(&scene);
    let bvh_seconds = start.elapsed().as_secs_f64();

    let bar = progress_bar("building", 1000);
    let (tree, stats) = vis5d::builder::build(&scene, &tracer, &params, &|f| {
        bar.set_position((f * 1000.0) as u64)
    })
    .map_err(|e| anyhow::anyhow!("invalid build parameters: {e}"))?;
    bar.finish_and_clear();
    tree.validate()
        .map_err(|e| anyhow::anyhow!("internal error: the built tree is inconsistent: {e}"))?;
    let summary = vis5d::builder::summarize(&tree, &scene);

    let start = Instant::now();
    let verify = (args.verify_views > 0).then(|| {
        let v = VerifyParams {
            views: args.verify_views,
            resolution: args.verify_resolution.max(1),
            ..VerifyParams::default()
        };
        vis5d::builder::pixel_error(&scene, &tracer, &tree, &v)
    });
    let verify_seconds = start.elapsed().as_secs_f64();
    let sizes = coding_sizes(&tree);
    let written = if args.dry_run {
        None
    } else {
        let file = vis5d::builder::to_file(&scene, tree.clone(), &params, args.coding);
        let bytes = codec::write_file(&file);
        // Encode -> decode must be the identity: check before writing.
        let back = codec::read_file(&bytes, codec::ReadLimits::default())
            .map_err(|e| anyhow::anyhow!("internal error: the coded tree does not decode: {e}"))?;
        if back.tree != tree {
            bail!("internal error: the coded tree decodes to another tree");
        }
        vis5d::atomic_write::write_atomic(&output, &bytes)
            .with_context(|| format!("{}: cannot write the tree", output.display()))?;
        Some(Written {
            path: output.display().to_string(),
            bytes: bytes.len(),
            coding: file.coding.name().to_owned(),
        })
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

/// A progress bar on a terminal, hidden otherwise.
fn progress_bar(what: &str, len: u64) -> ProgressBar {
    if !io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len).with_style(
        ProgressStyle::with_template(
            "{msg} [{bar:30}] {percent}% of view space {elapsed} (eta {eta})",
        )
        .expect("the template is valid")
        .progress_chars("=> "),
    );
    bar.set_message(what.to_owned());
    bar
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
    let threads = rayon::current_num_threads();
    let d = stats.decisions;
    BuildReport {
        file: args.file.display().to_string(),
        objects: scene.objects().len(),
        triangles: scene.triangles().len(),
        view_box: [b.min.to_array(), b.max.to_array()],
        threads,
        seed: params.seed,
        tree: s.into(),
        rays_cast: stats.rays(),
        cell_rays: stats.cell_rays,
        object_rays: stats.object_rays,
        rays_rejected: stats.rejected,
        rays_per_second: stats.rays() as f64 / stats.seconds.max(1e-9),
        decisions: DecisionReport {
            proven_by_hit: d.proven_by_hit,
            sprt_invisible: d.sprt_invisible,
            cap_reached: d.cap_reached,
            geometry_invisible: d.geometry_invisible,
            rejection_kept: d.rejection_kept,
        },
        seconds: StageSeconds {
            load,
            bvh,
            build: stats.seconds,
            tracing: stats.trace_seconds,
            tracing_share: stats.trace_seconds / (stats.seconds * threads as f64).max(1e-9),
            verify: verify_seconds,
        },
        pixel_error: verify.map(|v| PixelErrorReport {
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
        }),
        coding_sizes: Vec::new(),
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
        "  rays             {} cast ({} cell, {} object samples), {} samples rejected, {:.2} M/s",
        r.rays_cast,
        r.cell_rays,
        r.object_rays,
        r.rays_rejected,
        r.rays_per_second / 1e6
    )?;
    let d = &r.decisions;
    writeln!(
        out,
        "  decisions        {} proven by a hit, {} invisible by SPRT, {} invisible by geometry,",
        d.proven_by_hit, d.sprt_invisible, d.geometry_invisible
    )?;
    writeln!(
        out,
        "                   {} kept at the ray cap, {} kept after rejections",
        d.cap_reached, d.rejection_kept
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
    if let Some(p) = &r.pixel_error {
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
    let sizes: Vec<String> = r
        .coding_sizes
        .iter()
        .map(|c| format!("{} {} B", c.coding, c.bytes))
        .collect();
    writeln!(out, "  coded tree       {}", sizes.join(", "))?;
    match &r.written {
        Some(w) => writeln!(
            out,
            "  wrote            {} ({} bytes, {} coding)",
            w.path, w.bytes, w.coding
        )?,
        None => writeln!(out, "  nothing written (--dry-run)")?,
    }
    Ok(())
}

/// `stat`'s report.
#[derive(Serialize)]
struct StatReport {
    file: String,
    file_bytes: usize,
    version: u16,
    coding: String,
    grid_bits: u32,
    objects: usize,
    fingerprint: String,
    root_cell: [[f32; 5]; 2],
    params: Vec<(String, String)>,
    #[serde(flatten)]
    tree: ShapeReport,
    coding_sizes: Vec<CodingSize>,
}

fn read_v5d(path: &Path) -> Result<(Vec<u8>, codec::V5dFile)> {
    let bytes = std::fs::read(path)
        .with_context(|| format!("{}: cannot read the .v5d file", path.display()))?;
    let file = codec::read_file(&bytes, codec::ReadLimits::default())
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok((bytes, file))
}

fn stat(args: &StatArgs) -> Result<()> {
    let (bytes, file) = read_v5d(&args.file)?;
    let tree = &file.tree;
    let triangles: Vec<u64> = file.objects.iter().map(|o| o.triangles as u64).collect();
    let summary = tree.summarize(&triangles);
    let root = tree.root_cell();
    let report = StatReport {
        file: args.file.display().to_string(),
        file_bytes: bytes.len(),
        version: codec::VERSION,
        coding: file.coding.name().to_owned(),
        grid_bits: tree.grid_bits(),
        objects: file.objects.len(),
        fingerprint: format!("{:016x}", file.fingerprint),
        root_cell: [root.lo, root.hi],
        params: file
            .params
            .lines()
            .filter_map(|l| l.split_once('='))
            .map(|(k, v)| (k.to_owned(), v.to_owned()))
            .collect(),
        tree: summary.into(),
        coding_sizes: coding_sizes(tree),
    };
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
        return Ok(());
    }
    let r = &report;
    writeln!(
        out,
        "{}: .v5d version {}, {} bytes",
        r.file, r.version, r.file_bytes
    )?;
    writeln!(
        out,
        "  coding           {} (q = {} bits per split value)",
        r.coding, r.grid_bits
    )?;
    writeln!(out, "  objects          {}", r.objects)?;
    writeln!(out, "  scene            fingerprint {}", r.fingerprint)?;
    let space = [
        [root.lo[0], root.lo[1], root.lo[2]],
        [root.hi[0], root.hi[1], root.hi[2]],
    ];
    print_shape(&mut out, space, &r.tree)?;
    writeln!(out, "  coded tree size  structure bits + set bits = bytes")?;
    for c in &r.coding_sizes {
        let mark = if c.coding == r.coding {
            "  (this file)"
        } else {
            ""
        };
        writeln!(
            out,
            "    {:<8} {:>10} + {:>12} = {:>10} B{mark}",
            c.coding, c.structure_bits, c.set_bits, c.bytes
        )?;
    }
    writeln!(out, "  build parameters")?;
    for (k, v) in &r.params {
        writeln!(out, "    {k:<22} {v}")?;
    }
    Ok(())
}

/// One view of `query --views`.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ViewSpec {
    pos: [f32; 3],
    dir: [f32; 3],
    #[serde(default = "default_fov")]
    fov: f32,
}

fn default_fov() -> f32 {
    90.0
}

/// Reads a views file: a JSON list of `{"pos": [x,y,z], "dir": [x,y,z],
/// "fov": degrees}` (square field of view, up = +z unless `dir` is
/// vertical).
fn read_views(path: &Path) -> Result<Vec<View>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the views", path.display()))?;
    let specs: Vec<ViewSpec> = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: expected a JSON list of {{\"pos\": [x,y,z], \"dir\": [x,y,z], \"fov\": degrees}}",
            path.display()
        )
    })?;
    specs
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let (pos, dir) = (Vec3::from_array(v.pos), Vec3::from_array(v.dir));
            let ok = pos.is_finite()
                && dir.is_finite()
                && dir != Vec3::ZERO
                && v.fov > 0.0
                && v.fov < 180.0;
            if !ok {
                bail!(
                    "{}: view {i} needs finite pos, a non-zero dir and 0 < fov < 180",
                    path.display()
                );
            }
            Ok(View::square(pos, dir, v.fov))
        })
        .collect()
}

fn query(args: &QueryArgs) -> Result<()> {
    let pvs = Pvs::load(&args.file)?;
    if let Some(model) = &args.scene {
        let (scene, _) = load_scene(model)?;
        pvs.check_fingerprint(scene.fingerprint())
            .map_err(|e| anyhow::anyhow!("{}: {e}", args.file.display()))?;
    }
    let views: Vec<View> = match &args.views {
        Some(path) => read_views(path)?,
        None => {
            let dir = args.dir.expect("clap requires --dir without --views");
            if dir == Vec3::ZERO {
                bail!("--dir must not be the zero vector");
            }
            if !(args.fov > 0.0 && args.fov < 180.0) {
                bail!("--fov must be between 0 and 180 degrees");
            }
            let (pos, radius) = match (args.pos, args.positions) {
                (_, Some(b)) => (b.center(), 0.0),
                (Some(p), None) => (p, 0.0),
                (None, None) => unreachable!("clap requires --pos or --box"),
            };
            let mut v = View::square(pos, dir, args.fov);
            if let Some(up) = args.up {
                v.up = up;
            }
            v.radius = radius;
            vec![v]
        }
    };
    let mut set = pvs.new_set();
    let mut answers: Vec<Vec<&str>> = Vec::with_capacity(views.len());
    for v in &views {
        match args.positions {
            Some(b) => {
                let r = vis5d::query::frustum_angles(v.dir, v.up, v.fov_x, v.fov_y);
                let mut acc = pvs.new_set();
                for &(t0, t1, p0, p1) in r.boxes() {
                    pvs.query_range(&b, (t0, t1), (p0, p1), &mut set);
                    acc.union_with(&set);
                }
                set = acc;
            }
            None => pvs.query_view(v, &mut set),
        }
        answers.push(set.iter().map(|o| pvs.objects()[o].name.as_str()).collect());
    }
    let mut out = io::stdout().lock();
    if args.json {
        if args.views.is_some() {
            serde_json::to_writer(&mut out, &answers)?;
        } else {
            serde_json::to_writer(&mut out, &answers[0])?;
        }
        writeln!(out)?;
    } else if args.views.is_some() {
        for (i, names) in answers.iter().enumerate() {
            writeln!(out, "# view {i}: {} objects", names.len())?;
            for n in names {
                writeln!(out, "{n}")?;
            }
        }
    } else {
        for n in &answers[0] {
            writeln!(out, "{n}")?;
        }
    }
    Ok(())
}
