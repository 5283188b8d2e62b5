//! `vis5d report`: the methods side by side on the user's scene, as a page
//! (`index.html`, tables and SVG plots, no JavaScript), `report.json` with
//! every figure and `report.md`. The experiment is the library's
//! [`vis5d::report::run`]; this file turns the flags into its parameters,
//! loads the inputs and writes the outputs (`report_page.rs`).

use std::io::{self, Write};
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use vis5d::builder::{self, BuildParams};
use vis5d::codec;
use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
use vis5d::query::{Pvs, View};
use vis5d::render::random_views;
use vis5d::report::{self, ReportError, ReportParams};
use vis5d::shrink::{ShrinkOracle, ShrinkParams};
use vis5d::trace::Tracer;

use crate::common::{
    ViewDefaults, check_output, flag, load_scene_up, progress_bar, read_v5d, read_views,
};
use crate::memory;
use crate::oracle::GpuWarning;
use crate::report_page::{self, Page, TreeSource, share};

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
    /// The scene's up axis in its file: x, y or z (glTF and most game
    /// engines: y). Local z follows it: directions are parametrised by
    /// their angle from it (phi) and about it (theta), floorless buildings
    /// stand on it. Trees given with --pvs and --conservative must have been built with the same.
    #[arg(long, value_name = "AXIS", default_value = "z")]
    up: vis5d::geom::Up,
    /// The folder to write index.html, report.json and report.md into
    /// (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// A tree built for the scene; without it, one is built with the
    /// default parameters (and its build time and rays are reported).
    #[arg(long, value_name = "FILE.v5d")]
    pvs: Option<PathBuf>,
    /// A conservative tree of the scene (`vis5d build --conservative`), to
    /// report beside the sampled one as "conservative tree".
    #[arg(long, value_name = "FILE.v5d")]
    conservative: Option<PathBuf>,
    /// The views: a JSON list as for `vis5d query --views` (a camera
    /// path); without it, `--random` views.
    #[arg(long, value_name = "VIEWS.json")]
    views: Option<PathBuf>,
    /// How many random views (eye uniform in the tree's view box,
    /// direction uniform) when no `--views` file is given [1 to 100,000].
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    random: u32,
    /// Field of view of the random views, degrees [above 0, below 180].
    #[arg(long, default_value_t = 90.0, allow_hyphen_values = true)]
    fov: f32,
    /// Seed of the random views.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Pixels on a side of the ground-truth images [1 to 8192; the memory
    /// a view needs is checked first].
    #[arg(long, default_value_t = 512)]
    resolution: u32,
    /// Size of the oracle's cell around each eye, as a share of the
    /// scene's diagonal (a cube) [above 0, finite].
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true)]
    oracle_cell: f32,
    /// Leave the oracle out (it is the slowest method).
    #[arg(long)]
    no_oracle: bool,
    /// Leave occluder shrinking (papers/004) out; it runs for the same
    /// cell as the oracle, and a row "oracle and shrinking" shows what
    /// neither proves hidden.
    #[arg(long)]
    no_shrink: bool,
    /// Slices (papers/004 sec. 3) for the oracle's and the shrinking's
    /// rows: every object cut into N slices an axis; the hidden slices of
    /// each kept object are culled too, and the triangles drawn at slice
    /// granularity are reported beside those at object granularity [0
    /// (off) to 255].
    #[arg(long, default_value_t = 0)]
    slices: usize,
    /// Rasterise the oracle's depth maps and the shrinking's cube maps on
    /// the CPU even when a GPU adapter exists (the default uses the GPU
    /// through wgpu, and the CPU when there is none).
    #[arg(long)]
    cpu: bool,
    /// Cell size of the lazy occlusion grid, in pixels (papers/002 used
    /// 32 x 32) [1 to the resolution].
    #[arg(long, default_value_t = 32)]
    grid_cell: u32,
    /// Pictures of the first N views beside the page (`images/`, PNG):
    /// the scene in flat shades by object, the pixels of the objects the
    /// vis5d tree dropped in red, each shown small on the page and full
    /// size on a click [0 (none) to 1000].
    #[arg(long, default_value_t = 8)]
    pictures: usize,
}

impl ReportArgs {
    /// The experiment's parameters, checked, with the other flags.
    fn params(&self) -> Result<ReportParams> {
        if !(self.fov > 0.0 && self.fov < 180.0) {
            bail!("--fov must be between 0 and 180 degrees");
        }

        let params = ReportParams {
            resolution: self.resolution,
            grid_cell: self.grid_cell,
            oracle_cell: self.oracle_cell,
            slices: self.slices,
            pictures: self.pictures,
        };
        params.validate().map_err(|e| match &e {
            ReportError::Parameter { name, .. } => anyhow!("{}: {e}", flag(name)),
            _ => e.into(),
        })?;
        // A view's ground truth (rays and hits), the lazy grid's buffer,
        // and the ID buffers kept for the pictures (8 bytes a pixel, and
        // 3 for the picture being painted).
        memory::check(
            u64::from(self.resolution).pow(2) * (64 + 11 * self.pictures as u64),
            "--resolution and --pictures",
            "render smaller views, or fewer pictures",
        )?;
        Ok(params)
    }
}

/// The `.v5d` at `path`, refused unless it was built for `scene`.
fn read_tree_for(
    path: &std::path::Path,
    scene: &vis5d::scene::Scene,
    args: &ReportArgs,
) -> Result<codec::V5dFile> {
    let (_, file) = read_v5d(path)?;
    if file.fingerprint != scene.fingerprint() {
        bail!(
            "{} was built for another scene than {} (geometry fingerprint differs){}; rebuild it",
            path.display(),
            args.file.display(),
            crate::common::up_hint(file.frame.up, scene.frame().up)
        );
    }
    Ok(file)
}

/// Runs `vis5d report`.
pub fn run(args: &ReportArgs) -> Result<()> {
    let params = args.params()?;
    // Fail before the work on an output folder that cannot take the files
    // or would overwrite an input.
    if args.output.exists() {
        if !args.output.is_dir() {
            bail!(
                "{}: cannot write the report there: it is not a folder",
                args.output.display()
            );
        }
        let mut inputs = vec![args.file.as_path()];
        inputs.extend(args.pvs.as_deref());
        inputs.extend(args.conservative.as_deref());
        inputs.extend(args.views.as_deref());
        for name in report_page::OUTPUTS {
            check_output(&args.output.join(name), "report", &inputs)?;
        }
    }
    // A camera path is read (and checked) before the work.
    let path_views = args
        .views
        .as_deref()
        .map(|p| read_views(p, ViewDefaults::default()))
        .transpose()?;
    let (scene, _) = load_scene_up(&args.file, args.up)?;
    let tracer = Tracer::new(&scene);
    // The tree: given or built.
    let (file, tree) = match &args.pvs {
        Some(path) => {
            let file = read_tree_for(path, &scene, args)?;
            let source = TreeSource {
                source: path.display().to_string(),
                build_seconds: None,
                rays: None,
            };
            (file, source)
        }
        None => {
            let build_params = BuildParams::default();
            let bar = progress_bar("building the tree", 1000);
            let start = Instant::now();
            let (tree, stats) = builder::build(&scene, &tracer, &build_params, &|f| {
                bar.set_position((f * 1000.0) as u64)
            })?;
            bar.finish_and_clear();
            let source = TreeSource {
                source: "built with the default parameters".to_string(),
                build_seconds: Some(start.elapsed().as_secs_f64()),
                rays: Some(stats.rays()),
            };
            (builder::to_file(&scene, tree, &build_params, None), source)
        }
    };
    let pvs = Pvs::from_bytes(&codec::write_file(&file)).context("the tree")?;
    let conservative = match &args.conservative {
        Some(path) => {
            let c = read_tree_for(path, &scene, args)?;
            if !codec::params_say_conservative(&c.params) {
                bail!(
                    "{}: not a conservative tree (build one with vis5d build --conservative)",
                    path.display()
                );
            }
            Some(Pvs::from_bytes(&codec::write_file(&c)).context("the conservative tree")?)
        }
        None => None,
    };
    let views: Vec<View> = match path_views {
        // The camera path is in world coordinates; the report works in the
        // scene's local frame.
        Some(views) => {
            let local: Vec<View> = views.iter().map(|v| v.local(&scene.frame())).collect();
            if let Some(i) = local.iter().position(|v| !v.position.is_finite()) {
                bail!(
                    "view {i}: its position is too far from the scene (relative to it, \
                     coordinates must fit in f32, about 3e38)"
                );
            }
            local
        }
        None => random_views(
            &pvs.root_cell().space(),
            args.random as usize,
            args.fov,
            args.seed,
        ),
    };
    if views.is_empty() {
        bail!("no views to report on");
    }
    let oracle = if args.no_oracle {
        None
    } else {
        let rasteriser = if args.cpu {
            Rasteriser::cpu()
        } else {
            let r = Rasteriser::best();
            if let Some(why) = r.cpu_reason() {
                say!("note: {why}; the oracle uses the CPU rasteriser");
            }
            r
        };
        Some(Oracle::new(&scene, OracleParams::default(), rasteriser)?)
    };
    let shrink = if args.no_shrink {
        None
    } else {
        // Its cube maps on the GPU too (a device of its own), unless
        // `--cpu` (a missing adapter was noted above, or is silent when
        // the oracle is off).
        let rasteriser = if args.cpu {
            Rasteriser::cpu()
        } else {
            Rasteriser::best()
        };
        Some(ShrinkOracle::with_rasteriser(
            &scene,
            ShrinkParams::default(),
            rasteriser,
        )?)
    };
    let bar = progress_bar("views", views.len() as u64);
    let gpu_warning = GpuWarning::default();
    let experiment = report::run(
        &scene,
        &tracer,
        report::Trees {
            tree: &pvs,
            conservative: conservative.as_ref(),
        },
        report::Oracles {
            oracle: oracle.as_ref(),
            shrink: shrink.as_ref(),
        },
        &views,
        &params,
        &|done| {
            bar.set_position(done as u64);
            if let Some(oracle) = &oracle {
                gpu_warning.poll(oracle.rasteriser());
            }
        },
    )?;
    bar.finish_and_clear();
    if let Some(oracle) = &oracle {
        gpu_warning.finish(oracle.rasteriser());
    }
    if let Some(shrink) = &shrink {
        GpuWarning::default().finish(shrink.rasteriser());
    }
    // The top-down map of the tree, with the pictures: the eyes joined
    // when they are a camera path.
    let map = (params.pictures > 0).then(|| {
        let eyes: Vec<_> = views.iter().map(|v| v.position).collect();
        report::map(
            &scene,
            &tracer,
            &file.tree,
            &eyes,
            args.views.is_some(),
            params.resolution.max(512),
        )
    });
    let summaries = report_page::write(
        &args.output,
        &Page {
            scene_name: args.file.display().to_string(),
            scene: &scene,
            views: &views,
            params: &params,
            experiment: &experiment,
            file: &file,
            tree,
            map: map.as_ref(),
        },
    )?;
    let mut out = io::stdout().lock();
    writeln!(
        out,
        "wrote {} (index.html, report.json, report.md): {} views, {} methods",
        args.output.display(),
        views.len(),
        summaries.len()
    )?;
    for (name, s) in &summaries {
        writeln!(
            out,
            "  {:<20} {:>8.1} objects per view, geometry ratio {}, pixel error {} (worst view {}), {} distinct objects missed",
            name,
            s.mean_objects,
            s.geometry_ratio.map_or("n/a".into(), |g| format!("{g:.2}")),
            share(s.mean_pixel_error),
            share(s.worst_pixel_error),
            s.distinct_missed_objects
        )?;
    }
    Ok(())
}
