//! `vis5d trace`: rays per second of the project's tracer, on random rays
//! or on the rays a real build traces, and those rays written out so that
//! another ray caster can be timed on exactly the same work
//! (`scripts/compare-embree.sh`, notes/trace.md).

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use serde::Serialize;
use vis5d::builder::{BuildParams, record_rays};
use vis5d::raylog::{self, RAY_BYTES, TRIANGLE_BYTES};
use vis5d::trace::{Hit, Ray, Tracer};

use crate::common::{check_output, load_scene_up, progress_bar};
use crate::memory;

#[derive(Args, Debug)]
pub struct TraceArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
    /// How many rays to trace.
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(1..=100_000_000))]
    rays: u64,
    /// Which rays: random (origins uniform in the scene's box, directions
    /// uniform on the sphere, infinite) or builder (the first rays a
    /// default build of the scene traces: cell rays, and object samples as
    /// segments ending at their surface point).
    #[arg(long, value_enum, default_value_t = Kind::Random)]
    kind: Kind,
    /// Seed of the random rays, or of the build whose rays are taken.
    #[arg(long, default_value_t = BuildParams::default().seed)]
    seed: u64,
    /// Threads to trace with [default: all cores]. (The builder's rays are
    /// recorded on one thread, so that they come in the same order.)
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// The scene's up axis in its file: x, y or z (as for `vis5d build`,
    /// whose rays depend on it).
    #[arg(long, value_name = "AXIS", default_value = "z")]
    up: vis5d::geom::Up,
    /// Write the rays here, in the ray file format of notes/trace.md
    /// (per ray seven little-endian f32: origin, unit direction, tmax).
    #[arg(long, value_name = "FILE")]
    write_rays: Option<PathBuf>,
    /// Write the scene's triangles here (nine little-endian f32 each, in
    /// the rays' coordinates), for another ray caster to build on.
    #[arg(long, value_name = "FILE")]
    write_triangles: Option<PathBuf>,
    /// Time passes over the rays until this many seconds have gone (at
    /// least three passes).
    #[arg(long, default_value_t = 1.0, value_parser = parse_seconds)]
    min_seconds: f64,
    /// Print the result as JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// Which rays `vis5d trace` casts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
enum Kind {
    /// Uniform origins in the scene's box, uniform directions.
    Random,
    /// The first rays of a real build.
    Builder,
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if (0.0..=3600.0).contains(&v) {
        Ok(v)
    } else {
        Err("must be 0 to 3600".into())
    }
}

/// `trace`'s report.
#[derive(Serialize)]
struct TraceReport {
    scene: String,
    triangles: usize,
    kind: Kind,
    seed: u64,
    rays: usize,
    /// Rays that hit a triangle within their `tmax`.
    hits: usize,
    threads: usize,
    /// Seconds to build the tracer's BVH.
    bvh_seconds: f64,
    /// Seconds to make the rays (for builder rays, the recording build).
    ray_seconds: f64,
    passes: usize,
    best_pass_seconds: f64,
    median_pass_seconds: f64,
    /// Rays over the best pass's time.
    rays_per_second: f64,
    /// Rays over the median pass's time.
    median_rays_per_second: f64,
}

pub fn run(args: &TraceArgs) -> Result<()> {
    let n = usize::try_from(args.rays).context("--rays is too large for this machine")?;
    for (path, what) in [
        (&args.write_rays, "--write-rays"),
        (&args.write_triangles, "--write-triangles"),
    ] {
        if let Some(path) = path {
            check_output(path, what, &[&args.file])?;
        }
    }
    if let (Some(a), Some(b)) = (&args.write_rays, &args.write_triangles)
        && (a == b || vis5d::atomic_write::same_file(a, b))
    {
        anyhow::bail!(
            "--write-rays and --write-triangles name the same file, {}",
            a.display()
        );
    }
    // The rays as made and as traced (32 bytes each, and as much again
    // while the recording grows), their hits (16) and the written copy.
    memory::check(
        (args.rays).saturating_mul(3 * 32 + 16 + RAY_BYTES as u64),
        "--rays",
        "trace fewer rays",
    )?;
    let (scene, _) = load_scene_up(&args.file, args.up)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.map_or(0, usize::from))
        .build()
        .context("cannot set up the thread pool")?;
    let start = Instant::now();
    let tracer = pool.install(|| Tracer::new(&scene));
    let bvh_seconds = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let made = match args.kind {
        Kind::Random => raylog::random_rays(&scene.bounds(), n, args.seed),
        Kind::Builder => {
            let one = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .context("cannot set up the thread pool")?;
            let params = BuildParams {
                seed: args.seed,
                ..BuildParams::default()
            };
            let bar = progress_bar("recording the build's rays", 1000);
            let rays = one
                .install(|| {
                    record_rays(&scene, &tracer, &params, n, &|f| {
                        bar.set_position((f * 1000.0) as u64)
                    })
                })
                .context("the recording build failed")?;
            bar.finish_and_clear();
            rays
        }
    };
    let ray_seconds = start.elapsed().as_secs_f64();
    // What is timed is what is written: unit directions, tmax scaled.
    let rays: Vec<Ray> = made.iter().filter_map(raylog::portable).collect();
    if rays.is_empty() {
        anyhow::bail!("{}: no rays to trace", args.file.display());
    }

    let mut hits: Vec<Option<Hit>> = vec![None; rays.len()];
    // A first pass to warm the caches, then timed passes.
    pool.install(|| tracer.closest_hits_into(&rays, &mut hits));
    let mut passes = Vec::new();
    let timing = Instant::now();
    while passes.len() < 3 || timing.elapsed().as_secs_f64() < args.min_seconds {
        let start = Instant::now();
        pool.install(|| tracer.closest_hits_into(&rays, &mut hits));
        passes.push(start.elapsed().as_secs_f64());
    }
    let mut sorted = passes.clone();
    sorted.sort_by(f64::total_cmp);
    let (best, median) = (sorted[0], sorted[sorted.len() / 2]);
    let report = TraceReport {
        scene: args.file.display().to_string(),
        triangles: tracer.triangle_count(),
        kind: args.kind,
        seed: args.seed,
        rays: rays.len(),
        hits: hits.iter().flatten().count(),
        threads: pool.current_num_threads(),
        bvh_seconds,
        ray_seconds,
        passes: passes.len(),
        best_pass_seconds: best,
        median_pass_seconds: median,
        rays_per_second: rays.len() as f64 / best,
        median_rays_per_second: rays.len() as f64 / median,
    };
    if let Some(path) = &args.write_rays {
        write_with(path, |w| raylog::write_rays(w, &rays))?;
    }
    if let Some(path) = &args.write_triangles {
        write_with(path, |w| raylog::write_triangles(w, &scene))?;
    }
    print_report(args, &report)
}

/// Writes a file whole, atomically: an interrupted run leaves no partial
/// file.
fn write_with(path: &Path, write: impl FnOnce(&mut Vec<u8>) -> io::Result<()>) -> Result<()> {
    let mut bytes = Vec::new();
    write(&mut bytes)
        .and_then(|()| vis5d::atomic_write::write_atomic(path, &bytes))
        .with_context(|| format!("cannot write {}", path.display()))
}

fn print_report(args: &TraceArgs, r: &TraceReport) -> Result<()> {
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, r)?;
        writeln!(out)?;
        return Ok(());
    }
    let kind = match r.kind {
        Kind::Random => "random rays",
        Kind::Builder => "rays of a build",
    };
    writeln!(
        out,
        "scene    {}: {} triangles (BVH built in {:.3} s)",
        r.scene, r.triangles, r.bvh_seconds
    )?;
    writeln!(
        out,
        "rays     {} {kind} (seed {}, made in {:.3} s), {} hit ({:.1}%)",
        r.rays,
        r.seed,
        r.ray_seconds,
        r.hits,
        100.0 * r.hits as f64 / r.rays as f64
    )?;
    writeln!(
        out,
        "traced   {:.3} Mrays/s on {} thread{} (best of {} passes, {:.4} s; median {:.3} Mrays/s)",
        r.rays_per_second / 1e6,
        r.threads,
        if r.threads == 1 { "" } else { "s" },
        r.passes,
        r.best_pass_seconds,
        r.median_rays_per_second / 1e6
    )?;
    if let Some(p) = &args.write_rays {
        writeln!(
            out,
            "wrote    {} ({} bytes)",
            p.display(),
            r.rays * RAY_BYTES
        )?;
    }
    if let Some(p) = &args.write_triangles {
        writeln!(
            out,
            "wrote    {} ({} bytes)",
            p.display(),
            r.triangles * TRIANGLE_BYTES
        )?;
    }
    Ok(())
}
