//! `vis5d scene`: write a procedural test scene, or a model tiled into a
//! bigger world, as OBJ.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use glam::DVec3;
use vis5d::scene;

use crate::common::{check_output, load_scene_up, parse_point};
use crate::memory;

/// Memory per generated triangle: its corners, area table entry and
/// grouping while generating, and its OBJ text while writing.
const BYTES_PER_TRIANGLE: u64 = 256;
use vis5d::scene::procedural::{self, SceneKind};

#[derive(Args, Debug)]
pub struct SceneArgs {
    /// What to generate: apartment, office, city, forest, machine,
    /// thicket or grove (or nothing, with `--tile`).
    #[arg(required_unless_present = "tile")]
    kind: Option<SceneKind>,
    /// Instead of a procedural scene, copy this model (.obj, .gltf or
    /// .glb) `--replicate` times side by side on the ground, in a square
    /// grid with a gap of a tenth of its size between copies (copy k of
    /// an object is named `name#k`): a bigger world made of a real one,
    /// for measuring how builds scale. `--up` says which axis is up in it.
    #[arg(long, value_name = "MODEL", conflicts_with_all = ["kind", "seed"])]
    tile: Option<PathBuf>,
    /// The up axis of the `--tile` model in its file: x, y or z.
    #[arg(long, value_name = "AXIS", default_value = "z", requires = "tile")]
    up: vis5d::geom::Up,
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
    /// Move the scene by x,y,z (world units): put it where a georeferenced
    /// model would be (UTM coordinates are near 500000,5000000,0), to try
    /// vis5d far from the origin.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true)]
    offset: Option<DVec3>,
}

/// Runs `vis5d scene`.
pub fn run(args: &SceneArgs) -> Result<()> {
    if scene::SceneFormat::from_path(&args.output) != Some(scene::SceneFormat::Obj) {
        bail!("{}: the output must be an .obj file", args.output.display());
    }
    check_output(
        &args.output,
        "scene",
        &args.tile.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    let Some(kind) = args.kind else {
        let model = args.tile.as_ref().expect("clap requires a kind or --tile");
        return tile(args, model);
    };
    // The copies' triangles, their tables and their text, from one copy.
    let one = procedural::generate(kind, args.seed, 1).triangles().len() as u64;
    memory::check(
        one * u64::from(args.replicate) * BYTES_PER_TRIANGLE,
        "--replicate",
        "make fewer copies",
    )?;
    let start = Instant::now();
    let mut s = procedural::generate(kind, args.seed, args.replicate);
    if let Some(offset) = args.offset {
        s = s.translated(offset, &args.output)?;
    }
    let header = vec![
        format!(
            "vis5d procedural scene: {} --seed {} --replicate {}{}",
            kind,
            args.seed,
            args.replicate,
            offset_flag(args.offset)
        ),
        format!(
            "{} objects, {} triangles; units metres, z up",
            s.objects().len(),
            s.triangles().len()
        ),
    ];
    scene::write_obj_file(&s, &header, &args.output)
        .with_context(|| format!("{}: cannot write the scene", args.output.display()))?;
    say!(
        "wrote {}: {} {} objects, {} triangles ({:.2} s)",
        args.output.display(),
        kind,
        s.objects().len(),
        s.triangles().len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `vis5d scene --tile MODEL`: the model copied `--replicate` times.
fn tile(args: &SceneArgs, model: &Path) -> Result<()> {
    let (one, _) = load_scene_up(model, args.up)?;
    memory::check(
        one.triangles().len() as u64 * u64::from(args.replicate) * BYTES_PER_TRIANGLE,
        "--replicate",
        "make fewer copies",
    )?;
    let start = Instant::now();
    let mut s = one
        .tiled(args.replicate, &args.output)
        .with_context(|| format!("{}: cannot tile it", model.display()))?;
    drop(one);
    if let Some(offset) = args.offset {
        s = s.translated(offset, &args.output)?;
    }
    let header = vec![
        format!(
            "vis5d scene --tile {} --replicate {}{}",
            model.display(),
            args.replicate,
            offset_flag(args.offset)
        ),
        format!(
            "{} objects, {} triangles; {} up as in the model",
            s.objects().len(),
            s.triangles().len(),
            args.up
        ),
    ];
    scene::write_obj_file(&s, &header, &args.output)
        .with_context(|| format!("{}: cannot write the scene", args.output.display()))?;
    say!(
        "wrote {}: {} x{}, {} objects, {} triangles ({:.2} s)",
        args.output.display(),
        model.display(),
        args.replicate,
        s.objects().len(),
        s.triangles().len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// ` --offset x,y,z` for the header, or nothing.
fn offset_flag(offset: Option<DVec3>) -> String {
    offset.map_or(String::new(), |o| {
        format!(" --offset {},{},{}", o.x, o.y, o.z)
    })
}
