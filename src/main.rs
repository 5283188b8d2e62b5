//! The `vis5d` command-line tool: glue between the flags and the library.
//! Flags are parsed by clap into one struct per subcommand, checked, then
//! handed to the library; errors are reported once, here, with `anyhow`.

use std::io::{self, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use vis5d::scene::procedural::{self, SceneKind};
use vis5d::scene::{self, Scene};

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
    let result = match cli.command {
        Command::Info(args) => info(&args),
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
