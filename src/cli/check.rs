//! `vis5d check`: a built tree cross-checked against the oracle.

use std::io::{self, Write};
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use serde::Serialize;
use vis5d::bitset::ObjectSet;
use vis5d::geom::Aabb;
use vis5d::oracle::{self, CheckParams, LeafCheck, Oracle, Suspect};
use vis5d::trace::Tracer;

use crate::common::{World, load_scene_up, progress_bar, read_v5d};
use crate::memory;
use crate::oracle::{GpuWarning, OracleFlags};

/// How a check ended (errors aside).
pub enum Outcome {
    /// No violation: the oracle held against every ray.
    Clean,
    /// Violations were found (printed, and named on stderr).
    Violations,
}

/// A missed object's visible fraction is only summarised when this many
/// aimed rays were accepted (a fraction from 1 ray of 1 says little).
const MIN_RAYS_FOR_FRACTION: u32 = 32;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// The scene file (.obj, .gltf or .glb) the tree was built for.
    model: PathBuf,
    /// The .v5d file to check.
    pvs: PathBuf,
    /// Check this many leaves, picked at random (seeded) [1 or more;
    /// default: all].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    sample: Option<u64>,
    /// Ray draws aimed at each object in question (suspects, and objects
    /// the leaf keeps but the oracle hides) [1 to 1,000,000].
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    burst: u32,
    /// Uniform rays of each leaf cell for its ground-truth set [1 to
    /// 1,000,000].
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    truth_rays: u32,
    /// Seed of the leaf sample and the rays.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    flags: OracleFlags,
    /// Print every leaf's detail as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct ViolationJson<'a> {
    object: u32,
    name: &'a str,
    /// World coordinates.
    ray_origin: World,
    ray_dir: [f32; 3],
}

#[derive(Serialize)]
struct SuspectJson<'a> {
    object: u32,
    name: &'a str,
    confirmed_miss: bool,
    rays: u32,
    hits: u32,
    visible_fraction: f64,
}

#[derive(Serialize)]
struct LeafJson<'a> {
    node: usize,
    /// (x, y, z, theta, phi), x, y and z in the scene's local frame
    /// (world = local + `frame_origin`).
    cell: [[f32; 5]; 2],
    oracle_all_directions: usize,
    oracle: usize,
    sampled: usize,
    truth: usize,
    sampled_only: usize,
    violations: Vec<ViolationJson<'a>>,
    suspects: Vec<SuspectJson<'a>>,
}

#[derive(Serialize)]
struct CheckJson<'a> {
    model: String,
    pvs: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    frame_origin: Option<[f64; 3]>,
    objects: usize,
    tree_leaves: usize,
    leaves_checked: usize,
    oracle_cells: usize,
    oracle_seconds: f64,
    oracle_ms_per_cell: f64,
    ray_seconds: f64,
    violations: usize,
    suspects: usize,
    confirmed_misses: usize,
    max_missed_fraction: f64,
    mean_oracle_all_directions: f64,
    mean_oracle: f64,
    mean_sampled: f64,
    mean_truth: f64,
    mean_sampled_only: f64,
    leaves: Vec<LeafJson<'a>>,
}

/// Runs `vis5d check`.
pub fn run(args: &CheckArgs) -> Result<Outcome> {
    let params = args.flags.params()?;
    // Each thread holds one leaf's ground-truth rays and their hits.
    memory::check(
        u64::from(args.truth_rays.max(args.burst)) * 48 * rayon::current_num_threads() as u64,
        "--truth-rays and --burst",
        "cast fewer rays per leaf",
    )?;
    let (_, file) = read_v5d(&args.pvs)?;
    let (scene, _) = load_scene_up(&args.model, file.frame.up)?;
    let frame = scene.frame();
    if file.fingerprint != scene.fingerprint() {
        anyhow::bail!(
            "{} was built for another scene than {} (geometry fingerprint {:016x}, the scene's is {:016x}){}; rebuild it",
            args.pvs.display(),
            args.model.display(),
            file.fingerprint,
            scene.fingerprint(),
            crate::common::up_hint(file.frame.up, scene.frame().up)
        );
    }
    // The objects' flags as the tree was built with them.
    let flags: Vec<_> = file.objects.iter().map(|o| o.flags).collect();
    let scene = scene.with_flags(&flags);
    let tracer = Tracer::new(&scene);
    let oracle = Oracle::new(&scene, params, args.flags.rasteriser())?;
    let check_params = CheckParams {
        sample: args.sample.map(|n| n.min(usize::MAX as u64) as usize),
        burst: args.burst,
        truth_rays: args.truth_rays,
        seed: args.seed,
    };
    let bar = progress_bar("check", 0);
    let progress = |stage: &str, done: usize, total: usize| {
        bar.set_message(stage.to_string());
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let gpu_warning = GpuWarning::default();
    let mut run = |cell: &Aabb, hidden: Option<&ObjectSet>| {
        let visible = oracle.cell(cell, hidden).visible;
        gpu_warning.poll(oracle.rasteriser());
        visible
    };
    let report = oracle::check_tree(
        &oracle,
        &tracer,
        &file.tree,
        &check_params,
        &mut run,
        &progress,
    );
    bar.finish_and_clear();
    gpu_warning.finish(oracle.rasteriser());
    let name = |o: u32| scene.objects()[o as usize].name.as_str();
    let n = report.leaves.len().max(1) as f64;
    let mean =
        |f: &dyn Fn(&LeafCheck) -> usize| report.leaves.iter().map(f).sum::<usize>() as f64 / n;
    let suspects: Vec<&Suspect> = report.leaves.iter().flat_map(|l| &l.suspects).collect();
    let json = CheckJson {
        model: args.model.display().to_string(),
        frame_origin: (!frame.at_world_origin()).then(|| frame.origin.to_array()),
        pvs: args.pvs.display().to_string(),
        objects: scene.objects().len(),
        tree_leaves: report.tree_leaves,
        leaves_checked: report.leaves.len(),
        oracle_cells: report.oracle_cells,
        oracle_seconds: report.oracle_time.as_secs_f64(),
        oracle_ms_per_cell: 1e3 * report.oracle_time.as_secs_f64()
            / report.oracle_cells.max(1) as f64,
        ray_seconds: report.ray_time.as_secs_f64(),
        violations: report.violations().count(),
        suspects: suspects.len(),
        confirmed_misses: suspects.iter().filter(|s| s.confirmed()).count(),
        max_missed_fraction: suspects
            .iter()
            .filter(|s| s.rays >= MIN_RAYS_FOR_FRACTION)
            .map(|s| s.visible_fraction())
            .fold(0.0, f64::max),
        mean_oracle_all_directions: mean(&|l| l.oracle_all),
        mean_oracle: mean(&|l| l.oracle),
        mean_sampled: mean(&|l| l.sampled),
        mean_truth: mean(&|l| l.truth),
        mean_sampled_only: mean(&|l| l.sampled_only),
        leaves: report
            .leaves
            .iter()
            .map(|l| LeafJson {
                node: l.node,
                cell: [l.cell.lo, l.cell.hi],
                oracle_all_directions: l.oracle_all,
                oracle: l.oracle,
                sampled: l.sampled,
                truth: l.truth,
                sampled_only: l.sampled_only,
                violations: l
                    .violations
                    .iter()
                    .map(|v| ViolationJson {
                        object: v.object,
                        name: name(v.object),
                        ray_origin: World(frame, v.ray.origin),
                        ray_dir: v.ray.dir.to_array(),
                    })
                    .collect(),
                suspects: l
                    .suspects
                    .iter()
                    .map(|s| SuspectJson {
                        object: s.object,
                        name: name(s.object),
                        confirmed_miss: s.confirmed(),
                        rays: s.rays,
                        hits: s.hits,
                        visible_fraction: s.visible_fraction(),
                    })
                    .collect(),
            })
            .collect(),
    };
    // The outcome does not depend on the printing: a closed pipe on stdout
    // (`vis5d check ... | head`) must not turn violations into success.
    let printed = print_summary(
        args,
        &json,
        &oracle.rasteriser().name(),
        oracle.params().resolution,
    );
    if json.violations > 0 {
        let list: Vec<String> = report
            .violations()
            .take(20)
            .map(|(l, v)| {
                format!(
                    "{} (leaf {}, ray from {} along {:?})",
                    crate::common::printable(name(v.object)),
                    l.node,
                    World(frame, v.ray.origin),
                    v.ray.dir.to_array()
                )
            })
            .collect();
        say!(
            "error: {} violations: objects hit by a ray of their leaf that the oracle calls hidden (the oracle is wrong): {}",
            json.violations,
            list.join("; ")
        );
        return Ok(Outcome::Violations);
    }
    printed?;
    Ok(Outcome::Clean)
}

/// Prints the check's summary (or its JSON) on stdout.
fn print_summary(
    args: &CheckArgs,
    json: &CheckJson,
    rasteriser: &str,
    resolution: usize,
) -> Result<()> {
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer(&mut out, json)?;
        writeln!(out)?;
    } else {
        writeln!(
            out,
            "{} against {}: {} of {} leaves checked, {} objects",
            json.pvs, json.model, json.leaves_checked, json.tree_leaves, json.objects
        )?;
        writeln!(
            out,
            "  oracle           {} spatial cells in {:.2} s ({:.1} ms per cell, {}, {}x{} depth maps)",
            json.oracle_cells,
            json.oracle_seconds,
            json.oracle_ms_per_cell,
            rasteriser,
            resolution,
            resolution
        )?;
        writeln!(out, "  rays             {:.2} s", json.ray_seconds)?;
        writeln!(
            out,
            "  set sizes        oracle {:.1} ({:.1} before the leaf's directions), sampled {:.1}, ground truth {:.1} ({} rays a leaf), per leaf",
            json.mean_oracle,
            json.mean_oracle_all_directions,
            json.mean_sampled,
            json.mean_truth,
            args.truth_rays
        )?;
        writeln!(
            out,
            "  sampled only     {:.2} objects a leaf: kept by the sampler, proved hidden by the oracle, hit by none of {} aimed rays",
            json.mean_sampled_only, args.burst
        )?;
        writeln!(
            out,
            "  suspects         {} (the oracle keeps, the leaf lacks): {} confirmed misses (largest visible fraction {:.4} where {}+ aimed rays were accepted), {} not found",
            json.suspects,
            json.confirmed_misses,
            json.max_missed_fraction,
            MIN_RAYS_FOR_FRACTION,
            json.suspects - json.confirmed_misses
        )?;
        writeln!(out, "  violations       {}", json.violations)?;
    }
    Ok(())
}
