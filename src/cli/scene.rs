//! `vis5d scene`: write a procedural test scene as OBJ.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use glam::DVec3;
use vis5d::scene;

use crate::common::{check_output, parse_point};
use crate::memory;

/// Memory per generated triangle: its corners, area table entry and
/// grouping while generating, and its OBJ text while writing.
const BYTES_PER_TRIANGLE: u64 = 256;
use vis5d::scene::procedural::{self, SceneKind};

#[derive(Args, Debug)]
pub struct SceneArgs {
    /// What to generate: apartment, office, city, forest, machine or
    /// thicket.
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
    check_output(&args.output, "scene", &[])?;
    // The copies' triangles, their tables and their text, from one copy.
    let one = procedural::generate(args.kind, args.seed, 1)
        .triangles()
        .len() as u64;
    memory::check(
        one * u64::from(args.replicate) * BYTES_PER_TRIANGLE,
        "--replicate",
        "make fewer copies",
    )?;
    let start = Instant::now();
    let mut s = procedural::generate(args.kind, args.seed, args.replicate);
    if let Some(offset) = args.offset {
        s = s.translated(offset, &args.output)?;
    }
    let header = vec![
        format!(
            "vis5d procedural scene: {} --seed {} --replicate {}{}",
            args.kind,
            args.seed,
            args.replicate,
            args.offset.map_or(String::new(), |o| format!(
                " --offset {},{},{}",
                o.x, o.y, o.z
            ))
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
        args.kind,
        s.objects().len(),
        s.triangles().len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
