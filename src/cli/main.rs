//! The `vis5d` command-line tool: glue between the flags and the library.
//!
//! `main` parses the flags (clap), hands each command its own struct
//! (one file per command, `info.rs` .. `scene.rs`), and maps the outcome to
//! an exit code: 0 when done, 1 when `vis5d check` finds violations, 2 for
//! usage and runtime errors. Each command turns its flags into the
//! library's validated parameters before any work starts. Errors are
//! printed once, here; a closed pipe on stdout is not an error.

/// `eprintln!` that never panics: when stderr cannot be written (closed,
/// full), the message is lost, not the run.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

mod build;
mod check;
mod checkpoint;
mod common;
mod info;
mod memory;
mod merge;
mod oracle;
mod query;
mod report;
mod report_page;
mod scene;
mod stat;
mod trace;
mod view;

use std::io;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The exit code of `vis5d check` when it finds violations.
const EXIT_VIOLATIONS: u8 = 1;
/// The exit code of usage and runtime errors (clap's for usage errors).
const EXIT_ERROR: u8 = 2;

/// Precomputed from-region visibility for static 3D scenes.
///
/// vis5d finds which objects of a scene can be seen from which regions of
/// view space (positions x directions), so that a renderer draws only
/// those. Scenes are OBJ, glTF or GLB files; objects are OBJ `o` groups
/// (else `g` groups) or glTF nodes with a mesh.
#[derive(Parser, Debug)]
#[command(
    name = "vis5d",
    version,
    about,
    long_about,
    after_help = "Exit status: 0 when done; 1 when `vis5d check` finds violations; 2 for usage \
                  and runtime errors (bad flags, unreadable or invalid input, a failed write)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Let a glTF model read buffer files outside its own folder (absolute
    /// paths, `..`, links leading out). By default a model may name only
    /// files inside its folder, so that a model from elsewhere cannot make
    /// vis5d read other files as geometry.
    #[arg(long, global = true)]
    allow_outside_paths: bool,
    /// The most memory a run may use (such as 8G or 512M) [default: what
    /// the system says is available]. Work whose size is known before it
    /// starts (pixel buffers, ray batches, scene copies, the tree's node
    /// budget) is checked against it, and refused with how much it needs.
    #[arg(long, global = true, value_name = "SIZE", value_parser = memory::parse_size)]
    max_memory: Option<u64>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Load a scene and print a summary of its objects and triangles.
    ///
    /// Checks the file as the builder will see it: polygons triangulated,
    /// zero-area triangles dropped, groups without triangles listed as
    /// empty objects (never visible), repeated object names reported. Bad input (syntax errors, indices out
    /// of range, NaN or infinite coordinates, no triangles) is an error that
    /// names the file and, for OBJ, the line.
    Info(info::InfoArgs),
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
    Build(build::BuildArgs),
    /// Print a .v5d file's header, its tree's shape and the size each of
    /// the three set codings would take.
    Stat(stat::StatArgs),
    /// Answer view queries from a .v5d file: the objects visible from a
    /// position (or a box of positions) looking along a direction.
    ///
    /// Prints the names of the potentially visible objects. `--views FILE`
    /// answers many views at once: a JSON list of {"pos": [x,y,z], "dir":
    /// [x,y,z]}, each optionally with "fov" (square, degrees) or "vfov"
    /// (degrees) and "aspect", and "up": [x,y,z] (default: the up axis the
    /// tree was built with).
    Query(query::QueryArgs),
    /// Run a conservative oracle for one view cell: extended projections
    /// (papers/001, the default) or occluder shrinking (papers/004).
    ///
    /// Prints the objects it cannot prove hidden from any point of the
    /// cell (a box of viewpoints, all directions): a superset of the
    /// visible ones. `--method extended`: six projection planes around the
    /// cell collect the occlusion of convex occluders (whole convex
    /// objects, merged coplanar polygons, triangles) and cuts of solids
    /// into Depth Maps; object boxes are tested against them. `--method
    /// shrink`: every closed solid is shrunk by half the cell's diagonal
    /// and the objects are tested from the cell's centre against all of
    /// them at once, in a cube map. Prints what each step did, the
    /// timings and the objects.
    Oracle(oracle::OracleArgs),
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
    /// `--json` gives every leaf's detail. Exits with 1 when there are
    /// violations.
    Check(check::CheckArgs),
    /// Compare visibility methods on a scene against a ray-cast ground
    /// truth, and write a report page.
    ///
    /// For a set of views (random ones in the tree's view box, or a camera
    /// path from `--views`), renders ID buffers by casting one ray per
    /// pixel, then measures for each method (view-frustum culling, the lazy
    /// occlusion grid of Hey et al. with lazy and busy updates, the vis5d
    /// tree, a conservative tree with `--conservative`, the
    /// extended-projection oracle of a cell around the eye) the
    /// objects and triangles it draws, the pixels whose object it
    /// misses, the set errors Q_u and Q_o against the objects seen, and its
    /// time. Writes DIR/index.html (tables and SVG plots), DIR/report.json
    /// (every figure) and DIR/report.md.
    Report(report::ReportArgs),
    /// Generate a procedural test scene (or tile a model) and write it as OBJ.
    ///
    /// Kinds: apartment (two furnished rooms joined by a door, ~170 objects,
    /// ~3,000 triangles), office (twelve offices along a corridor), city
    /// (blocks of buildings along streets), forest (trees of a trunk and
    /// many small leaf triangles), machine (a closed casing with a
    /// ventilation grating and many internal parts), thicket (a dense
    /// forest: 256 trees 2.5 m apart, crowns of leaf triangles down to half
    /// a metre), grove (a dense forest with a trail through it, whose
    /// crowns are closed shells of overlapping leaf triangles). The same
    /// kind, seed and replication always give the same file. `--tile
    /// MODEL --replicate N` instead copies a model N times
    /// side by side on the ground: a bigger world made of a real one.
    Scene(scene::SceneArgs),
    /// Time the project's ray tracer: rays per second on random rays or
    /// on the rays a real build traces.
    ///
    /// `--kind random` casts rays from points uniform in the scene's box
    /// in directions uniform on the sphere; `--kind builder` records the
    /// first `--rays` rays that a default build of the scene traces (cell
    /// rays, and object samples as segments ending at their surface point)
    /// on one thread. Traces them all (closest hit within each ray's
    /// length) in passes for at least `--min-seconds`, and prints the best
    /// pass's rays per second. `--write-rays` and `--write-triangles`
    /// write the rays and the scene in the flat formats of notes/trace.md,
    /// so that another ray caster can be timed on exactly the same rays
    /// (scripts/compare-embree.sh does, with Embree).
    Trace(trace::TraceArgs),
    /// Join the parts of a sharded build into one .v5d file.
    ///
    /// `vis5d build MODEL --top-levels K --shard I/N -o PART` builds shard
    /// I of N (the fixed top's subtrees dealt to it); `vis5d merge PART...
    /// -o FILE.v5d` checks that the parts are every shard of one build
    /// (the same scene, parameters, coding and split, each shard once,
    /// every subtree once) and writes the file a single `vis5d build MODEL
    /// --top-levels K` with the same parameters writes, byte for byte.
    Merge(merge::MergeArgs),
    /// Fly through a scene in the web browser, drawing what a tree says.
    ///
    /// Starts a local web server and prints its address. The page draws
    /// the scene (WebGL, three.js shipped inside vis5d: no network
    /// needed); fly with the mouse (drag to look) and W A S D, Q E. Each
    /// frame it asks the server for the set of the camera's view and
    /// hides the rest; an overlay shows objects and triangles drawn, the
    /// leaf's cell as a wire box, and (key C) a check that renders every
    /// object's id and paints red any visible object the set lacks. With
    /// several --pvs files, key T (or the list) switches between them. The
    /// JSON API the page uses (/api/info, /api/scene.glb, /api/query,
    /// /api/cell) is documented in the README.
    View(view::ViewArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    memory::set_max_memory(cli.max_memory);
    common::set_load_options(vis5d::scene::LoadOptions {
        allow_outside_paths: cli.allow_outside_paths,
        ..Default::default()
    });
    if matches!(
        cli.command,
        Command::Oracle(_) | Command::Check(_) | Command::Report(_)
    ) && std::env::var_os("XDG_RUNTIME_DIR").is_none()
    {
        // Mesa's Vulkan drivers print an "error" to stderr when this is
        // unset (it is, in containers and CI), though nothing is wrong.
        // SAFETY: no other thread exists yet.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    let result = match cli.command {
        Command::Info(args) => info::run(&args),
        Command::Build(args) => build::run(&args),
        Command::Stat(args) => stat::run(&args),
        Command::Query(args) => query::run(&args),
        Command::Oracle(args) => oracle::run(&args),
        Command::Check(args) => match check::run(&args) {
            Ok(check::Outcome::Clean) => Ok(()),
            Ok(check::Outcome::Violations) => return ExitCode::from(EXIT_VIOLATIONS),
            Err(e) => Err(e),
        },
        Command::Report(args) => report::run(&args),
        Command::Scene(args) => scene::run(&args),
        Command::Trace(args) => trace::run(&args),
        Command::Merge(args) => merge::run(&args),
        Command::View(args) => view::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            say!("error: {e:#}");
            ExitCode::from(EXIT_ERROR)
        }
    }
}

/// Whether the error is a write to a closed pipe (`vis5d ... | head`),
/// in text or in JSON.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<io::Error>()
            .map(io::Error::kind)
            .or_else(|| {
                c.downcast_ref::<serde_json::Error>()
                    .and_then(serde_json::Error::io_error_kind)
            })
            == Some(io::ErrorKind::BrokenPipe)
    })
}
