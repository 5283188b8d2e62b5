//! `vis5d oracle`: the extended-projection oracle for one cell.

use std::io::{self, Write};
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Result, anyhow};
use clap::Args;
use serde::Serialize;
use vis5d::bitset::ObjectSet;
use vis5d::geom::Aabb;
use vis5d::oracle::oracle_check::{self, CheckParams};
use vis5d::oracle::oracle_gpu::GpuRasteriser;
use vis5d::oracle::oracle_plane::cpu_rasterise;
use vis5d::oracle::{CellReport, Oracle, OracleParams};
use vis5d::trace::Tracer;

use crate::{load_scene, parse_box};

/// Settings shared by `oracle` and `check`.
#[derive(Args, Debug, Clone)]
pub struct OracleFlags {
    /// Depth Map pixels on a side (a power of two; the paper found 256
    /// best).
    #[arg(long, default_value_t = 256)]
    pub resolution: usize,
    /// How far each projection plane reaches beyond the cell's face, in
    /// multiples of its distance from the face (the paper used 1.5).
    #[arg(long, default_value_t = 1.5)]
    pub extension: f64,
    /// The most occluders drawn into one Depth Map (the largest first).
    #[arg(long, default_value_t = 4096)]
    pub max_occluders: usize,
    /// Projection planes per face of the cell: the best position, then
    /// those that hide most objects the others do not.
    #[arg(long, default_value_t = 2)]
    pub planes_per_face: usize,
    /// Rasterise the Depth Maps on the CPU even when a GPU adapter exists
    /// (the default uses the GPU through wgpu, and the CPU when there is
    /// none).
    #[arg(long)]
    pub cpu: bool,
}

/// Where Depth Maps are rasterised.
pub enum Backend {
    /// The CPU reference.
    Cpu,
    /// wgpu, with the CPU as a fallback should a map fail.
    Gpu(Box<GpuRasteriser>, std::sync::atomic::AtomicBool),
}

impl Backend {
    /// The GPU unless `cpu` is set or no adapter exists (then says so on
    /// stderr).
    pub fn open(cpu: bool) -> Backend {
        if cpu {
            return Backend::Cpu;
        }
        match GpuRasteriser::new() {
            Ok(g) => Backend::Gpu(Box::new(g), std::sync::atomic::AtomicBool::new(false)),
            Err(e) => {
                eprintln!("note: {e}; using the CPU rasteriser");
                Backend::Cpu
            }
        }
    }

    /// "CPU" or the adapter's name.
    pub fn name(&self) -> String {
        match self {
            Backend::Cpu => "CPU".into(),
            Backend::Gpu(g, _) => format!("GPU: {}", g.adapter_name()),
        }
    }

    /// The oracle for one cell on this backend.
    pub fn cell(
        &self,
        oracle: &Oracle,
        cell: &Aabb,
        parent_hidden: Option<&ObjectSet>,
    ) -> CellReport {
        match self {
            Backend::Cpu => oracle.cell(cell, parent_hidden),
            Backend::Gpu(g, warned) => oracle.cell_with(cell, parent_hidden, &mut |n, occ| match g.rasterise(n, occ) {
                Ok(map) => map,
                Err(e) => {
                    if !warned.swap(true, std::sync::atomic::Ordering::Relaxed) {
                        eprintln!("warning: the GPU failed ({e}); this map and any other that fails use the CPU");
                    }
                    cpu_rasterise(n, occ)
                }
            }),
        }
    }
}

impl OracleFlags {
    /// The oracle settings these flags give.
    pub fn params(&self) -> Result<OracleParams> {
        let p = OracleParams {
            resolution: self.resolution,
            extension: self.extension,
            max_occluders: self.max_occluders,
            planes_per_face: self.planes_per_face,
            ..OracleParams::default()
        };
        p.validate().map_err(|e| anyhow!("{e}"))?;
        Ok(p)
    }
}

#[derive(Args, Debug)]
pub struct OracleArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
    /// The view cell: a box of viewpoints, x0,y0,z0,x1,y1,z1.
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", value_parser = parse_box, allow_hyphen_values = true)]
    cell: Aabb,
    #[command(flatten)]
    flags: OracleFlags,
    /// Print as JSON: the objects, the planes and the timings.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct PlaneJson {
    face: &'static str,
    position: f64,
    occluders: usize,
    slices: usize,
    filled_pixels: usize,
    hidden: usize,
}

#[derive(Serialize)]
struct OracleJson<'a> {
    scene: String,
    cell: [[f32; 3]; 2],
    objects: usize,
    occluders: usize,
    potentially_visible: Vec<&'a str>,
    hidden: usize,
    touching_cell: usize,
    resolution: usize,
    backend: String,
    planes: Vec<PlaneJson>,
    seconds: Seconds,
}

#[derive(Serialize)]
struct Seconds {
    load: f64,
    prepare: f64,
    select: f64,
    rasterise: f64,
    test: f64,
    cell: f64,
}

pub fn oracle(args: &OracleArgs) -> Result<()> {
    let params = args.flags.params()?;
    let (scene, load) = load_scene(&args.file)?;
    let start = Instant::now();
    let oracle = Oracle::new(&scene, params).map_err(|e| anyhow!("{e}"))?;
    let prepare = start.elapsed().as_secs_f64();
    let backend = Backend::open(args.flags.cpu);
    let report: CellReport = backend.cell(&oracle, &args.cell, None);
    let names: Vec<&str> = report
        .visible
        .iter()
        .map(|i| scene.objects()[i].name.as_str())
        .collect();
    let t = report.times;
    let json = OracleJson {
        scene: args.file.display().to_string(),
        cell: [args.cell.min.to_array(), args.cell.max.to_array()],
        objects: scene.objects().len(),
        occluders: oracle.occluder_count(),
        hidden: scene.objects().len() - names.len(),
        potentially_visible: names,
        touching_cell: report.touching,
        resolution: oracle.params().resolution,
        backend: backend.name(),
        planes: report
            .planes
            .iter()
            .map(|p| PlaneJson {
                face: p.face,
                position: p.position,
                occluders: p.occluders,
                slices: p.slices,
                filled_pixels: p.filled,
                hidden: p.hidden,
            })
            .collect(),
        seconds: Seconds {
            load,
            prepare,
            select: t.select.as_secs_f64(),
            rasterise: t.rasterise.as_secs_f64(),
            test: t.test.as_secs_f64(),
            cell: t.total().as_secs_f64(),
        },
    };
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer(&mut out, &json)?;
        writeln!(out)?;
        return Ok(());
    }
    let c = oracle.occluder_counts();
    writeln!(
        out,
        "{}: {} objects, {} occluders ({} convex solids, {} polygons, {} triangles), {} objects to slice",
        json.scene,
        json.objects,
        json.occluders,
        c.solids,
        c.polygons,
        c.triangles,
        oracle.solid_count()
    )?;
    writeln!(out, "cell {:?} .. {:?}", json.cell[0], json.cell[1])?;
    let pixels = (json.resolution * json.resolution) as f64;
    for p in &json.planes {
        writeln!(
            out,
            "  plane {} at {:.4}: {} occluders, {} solids cut, {:.1}% of {}x{} pixels filled, {} objects hidden",
            p.face,
            p.position,
            p.occluders,
            p.slices,
            100.0 * p.filled_pixels as f64 / pixels,
            json.resolution,
            json.resolution,
            p.hidden
        )?;
    }
    writeln!(
        out,
        "potentially visible: {} of {} objects ({:.1}% proved hidden; {} touch the cell)",
        json.potentially_visible.len(),
        json.objects,
        100.0 * json.hidden as f64 / json.objects.max(1) as f64,
        json.touching_cell
    )?;
    let s = &json.seconds;
    writeln!(
        out,
        "time: load {:.3} s, prepare {:.3} s, cell {:.3} s (select {:.3}, rasterise {:.3}, test {:.3}); depth maps on the {}",
        s.load, s.prepare, s.cell, s.select, s.rasterise, s.test, json.backend
    )?;
    for n in &json.potentially_visible {
        writeln!(out, "{n}")?;
    }
    Ok(())
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
    /// Check this many leaves, picked at random (seeded) [default: all].
    #[arg(long, value_name = "N")]
    sample: Option<usize>,
    /// Ray draws aimed at each object in question (suspects, and objects
    /// the leaf keeps but the oracle hides).
    #[arg(long, default_value_t = 1000)]
    burst: u32,
    /// Uniform rays of each leaf cell for its ground-truth set.
    #[arg(long, default_value_t = 4096)]
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
    ray_origin: [f32; 3],
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

pub fn check(args: &CheckArgs) -> Result<()> {
    let params = args.flags.params()?;
    if args.sample == Some(0) {
        anyhow::bail!("--sample must be at least 1");
    }
    let (scene, _) = load_scene(&args.model)?;
    let (_, file) = crate::read_v5d(&args.pvs)?;
    if file.fingerprint != scene.fingerprint() {
        anyhow::bail!(
            "{} was built for another scene than {} (geometry fingerprint {:016x}, the scene's is {:016x}); rebuild it",
            args.pvs.display(),
            args.model.display(),
            file.fingerprint,
            scene.fingerprint()
        );
    }
    let tracer = Tracer::new(&scene);
    let oracle = Oracle::new(&scene, params).map_err(|e| anyhow!("{e}"))?;
    let check_params = CheckParams {
        sample: args.sample,
        burst: args.burst,
        truth_rays: args.truth_rays,
        seed: args.seed,
    };
    let bar = crate::progress_bar("check", 0);
    let progress = |stage: &str, done: usize, total: usize| {
        bar.set_message(stage.to_string());
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let backend = Backend::open(args.flags.cpu);
    let mut run =
        |cell: &Aabb, hidden: Option<&ObjectSet>| backend.cell(&oracle, cell, hidden).visible;
    let report = oracle_check::check(
        &oracle,
        &tracer,
        &file.tree,
        &check_params,
        &mut run,
        &progress,
    );
    bar.finish_and_clear();
    let name = |o: u32| scene.objects()[o as usize].name.as_str();
    let n = report.leaves.len().max(1) as f64;
    let mean = |f: &dyn Fn(&oracle_check::LeafCheck) -> usize| {
        report.leaves.iter().map(f).sum::<usize>() as f64 / n
    };
    let suspects: Vec<&oracle_check::Suspect> =
        report.leaves.iter().flat_map(|l| &l.suspects).collect();
    let json = CheckJson {
        model: args.model.display().to_string(),
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
                        ray_origin: v.ray.origin.to_array(),
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
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer(&mut out, &json)?;
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
            backend.name(),
            oracle.params().resolution,
            oracle.params().resolution
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
    if json.violations > 0 {
        let list: Vec<String> = report
            .violations()
            .take(20)
            .map(|(l, v)| {
                format!(
                    "{} (leaf {}, ray from {:?} along {:?})",
                    name(v.object),
                    l.node,
                    v.ray.origin.to_array(),
                    v.ray.dir.to_array()
                )
            })
            .collect();
        anyhow::bail!(
            "{} violations: objects hit by a ray of their leaf that the oracle calls hidden (the oracle is wrong): {}",
            json.violations,
            list.join("; ")
        );
    }
    Ok(())
}
