//! `vis5d report`: the methods side by side on the user's scene, as a page
//! (`index.html`, tables and SVG plots, no JavaScript), `report.json` with
//! every figure and `report.md`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use plotters::prelude::*;
use serde::Serialize;
use vis5d::bitset::ObjectSet;
use vis5d::builder::{self, BuildParams};
use vis5d::codec::{self, Coding, code_size};
use vis5d::geom::Aabb;
use vis5d::lazy_grid::{GridParams, LazyGrid};
use vis5d::oracle::{Oracle, OracleParams};
use vis5d::query::{Pvs, View};
use vis5d::render::{Camera, random_views};
use vis5d::report::{ViewMetrics, ViewTruth, frustum_set, truth};
use vis5d::scene::Scene;
use vis5d::trace::Tracer;

use crate::{load_scene, progress_bar, read_v5d, read_views};

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
    /// The folder to write index.html, report.json and report.md into
    /// (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// A tree built for the scene; without it, one is built with the
    /// default parameters (and its build time and rays are reported).
    #[arg(long, value_name = "FILE.v5d")]
    pvs: Option<PathBuf>,
    /// The views: a JSON list as for `vis5d query --views` (a camera
    /// path); without it, `--random` views.
    #[arg(long, value_name = "VIEWS.json")]
    views: Option<PathBuf>,
    /// How many random views (eye uniform in the tree's view box,
    /// direction uniform) when no `--views` file is given.
    #[arg(long, default_value_t = 50)]
    random: usize,
    /// Field of view of the random views, degrees.
    #[arg(long, default_value_t = 90.0)]
    fov: f32,
    /// Seed of the random views.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Pixels on a side of the ground-truth images.
    #[arg(long, default_value_t = 512)]
    resolution: u32,
    /// Size of the oracle's cell around each eye, as a share of the
    /// scene's diagonal (a cube).
    #[arg(long, default_value_t = 0.01)]
    oracle_cell: f32,
    /// Leave the oracle out (it is the slowest method).
    #[arg(long)]
    no_oracle: bool,
    /// Cell size of the lazy occlusion grid, in pixels (papers/002 used
    /// 32 x 32).
    #[arg(long, default_value_t = 32)]
    grid_cell: u32,
}

/// One method's figures over the views. Q_u, Q_o and the pixel error
/// are means over the views that show something (undefined otherwise).
#[derive(Serialize)]
struct MethodSummary {
    mean_objects: f64,
    max_objects: usize,
    mean_triangles: f64,
    max_triangles: u64,
    /// Triangles after frustum culling over triangles drawn, summed over
    /// the views (the papers' geometry ratio); `None` when the method
    /// draws no triangle at all.
    geometry_ratio: Option<f64>,
    mean_pixel_error: f64,
    worst_pixel_error: f64,
    /// The view with the worst pixel error (its index).
    worst_view: usize,
    /// Misses summed over the views (an object missed in 3 views counts 3).
    missed_objects: usize,
    /// Distinct objects missed in some view.
    distinct_missed_objects: usize,
    views_with_misses: usize,
    mean_q_u: f64,
    mean_q_o: f64,
    mean_ms_per_view: f64,
}

#[derive(Serialize)]
struct ViewJson {
    objects: usize,
    triangles: u64,
    missing_pixels: u64,
    /// Missing pixels over hit pixels; `None` when nothing is hit.
    pixel_error: Option<f64>,
    missed_objects: usize,
    /// The objects seen but not drawn.
    missed: Vec<u32>,
    q_u: Option<f64>,
    q_o: Option<f64>,
    ms: f64,
}

#[derive(Serialize)]
struct MethodJson {
    name: &'static str,
    description: &'static str,
    summary: MethodSummary,
    per_view: Vec<ViewJson>,
}

#[derive(Serialize)]
struct TruthJson {
    pos: [f32; 3],
    dir: [f32; 3],
    fov_degrees: f32,
    seen_objects: usize,
    hit_pixels: u64,
    seen: Vec<(u32, u64)>,
}

#[derive(Serialize)]
struct CodingJson {
    coding: &'static str,
    bytes: u64,
}

#[derive(Serialize)]
struct TreeJson {
    source: String,
    build_seconds: Option<f64>,
    rays: Option<u64>,
    leaves: usize,
    nodes: usize,
    mean_leaf_objects: f64,
    leaf_set_sizes: Vec<usize>,
    codings: Vec<CodingJson>,
}

/// The lazy grid's costs for one view, lazy and busy (papers/002 Fig. 8).
#[derive(Serialize)]
struct GridCost {
    lazy_pixel_queries: u64,
    busy_pixel_queries: u64,
    lazy_cell_updates: u64,
    busy_cell_updates: u64,
    boxes_tested: u64,
    lazy_ms: f64,
    busy_ms: f64,
}

#[derive(Serialize)]
struct ReportJson {
    scene: String,
    objects: usize,
    triangles: usize,
    resolution: u32,
    truth_ms_per_view: f64,
    views: Vec<TruthJson>,
    methods: Vec<MethodJson>,
    tree: TreeJson,
    oracle_cell: Option<f32>,
    grid_cell_pixels: u32,
    grid_costs: Vec<GridCost>,
}

struct Method {
    name: &'static str,
    description: &'static str,
    per_view: Vec<ViewMetrics>,
    /// Per view, the objects seen but not drawn.
    missed: Vec<Vec<u32>>,
}

impl Method {
    fn new(name: &'static str, description: &'static str) -> Self {
        Self {
            name,
            description,
            per_view: Vec::new(),
            missed: Vec::new(),
        }
    }

    /// Records the set `drawn` of one view, taking `seconds`.
    fn record(&mut self, scene: &Scene, truth: &ViewTruth, drawn: &ObjectSet, seconds: f64) {
        self.per_view
            .push(ViewMetrics::of(scene, truth, drawn, seconds));
        self.missed.push(
            truth
                .seen
                .iter()
                .map(|&(o, _)| o)
                .filter(|&o| !drawn.contains(o as usize))
                .collect(),
        );
    }
}

pub fn report(args: &ReportArgs) -> Result<()> {
    if args.resolution == 0 || args.resolution > 8192 {
        bail!("--resolution must be between 1 and 8192");
    }
    if !(args.fov > 0.0 && args.fov < 180.0) {
        bail!("--fov must be between 0 and 180 degrees");
    }
    if args.grid_cell == 0 || args.grid_cell > args.resolution {
        bail!("--grid-cell must be between 1 and the resolution");
    }
    if args.views.is_none() && args.random == 0 {
        bail!("--random must be at least 1 (or give --views)");
    }
    if !(args.oracle_cell.is_finite() && args.oracle_cell > 0.0) {
        bail!("--oracle-cell must be a positive share of the scene's diagonal");
    }
    let (scene, _) = load_scene(&args.file)?;
    let tracer = Tracer::new(&scene);
    // The tree: given or built.
    let (file, source, build_seconds, rays) = match &args.pvs {
        Some(path) => {
            let (_, file) = read_v5d(path)?;
            if file.fingerprint != scene.fingerprint() {
                bail!(
                    "{} was built for another scene than {} (geometry fingerprint differs); rebuild it",
                    path.display(),
                    args.file.display()
                );
            }
            (file, path.display().to_string(), None, None)
        }
        None => {
            let params = BuildParams::default();
            let bar = progress_bar("building the tree", 1000);
            let start = Instant::now();
            let (tree, stats) = builder::build(&scene, &tracer, &params, &|f| {
                bar.set_position((f * 1000.0) as u64)
            })
            .map_err(|e| anyhow!("{e}"))?;
            bar.finish_and_clear();
            let seconds = start.elapsed().as_secs_f64();
            let file = builder::to_file(&scene, tree, &params, None);
            (
                file,
                "built with the default parameters".to_string(),
                Some(seconds),
                Some(stats.rays()),
            )
        }
    };
    let pvs = Pvs::from_bytes(&codec::write_file(&file)).map_err(|e| anyhow!("the tree: {e}"))?;
    let views: Vec<View> = match &args.views {
        Some(path) => read_views(path)?,
        None => random_views(&pvs.root_cell().space(), args.random, args.fov, args.seed),
    };
    if views.is_empty() {
        bail!("no views to report on");
    }
    let oracle = if args.no_oracle {
        None
    } else {
        Some(Oracle::new(&scene, OracleParams::default()).map_err(|e| anyhow!("{e}"))?)
    };
    let half = 0.5 * args.oracle_cell * scene.bounds().diagonal();
    let n = scene.objects().len();
    let mut methods = vec![
        Method::new(
            "frustum",
            "view-frustum culling: objects whose bounding box meets the frustum",
        ),
        Method::new(
            "vis5d",
            "the vis5d tree (.v5d) queried per view, then view-frustum culling",
        ),
        Method::new(
            "lazy grid",
            "the lazy occlusion grid of papers/002: an occlusion buffer with a grid of cells updated lazily, object boxes front to back (online, from the eye)",
        ),
    ];
    if oracle.is_some() {
        methods.push(Method::new(
            "oracle",
            "the extended-projection oracle of a cube around the eye, within the frustum",
        ));
    }
    let grid = LazyGrid::new(&scene);
    let mut grid_costs: Vec<GridCost> = Vec::with_capacity(views.len());
    let mut truths: Vec<ViewTruth> = Vec::with_capacity(views.len());
    let mut truth_seconds = 0.0;
    let bar = progress_bar("views", views.len() as u64);
    let (mut set, mut frustum) = (ObjectSet::new(n), ObjectSet::new(n));
    for (i, view) in views.iter().enumerate() {
        let camera = Camera::new(view, args.resolution, args.resolution)
            .ok_or_else(|| anyhow!("view {i} is degenerate (zero direction or up along it)"))?;
        let start = Instant::now();
        let t = truth(&scene, &tracer, &camera);
        truth_seconds += start.elapsed().as_secs_f64();
        let start = Instant::now();
        frustum_set(&scene, &camera, &mut frustum);
        let s = start.elapsed().as_secs_f64();
        methods[0].record(&scene, &t, &frustum, s);
        // The tree's answer holds what any leaf the frustum's directions
        // meet can see, also outside the frustum; a renderer culls those
        // with the frustum anyway, so the method is both.
        let start = Instant::now();
        pvs.query_view(view, &mut set);
        set.intersect_with(&frustum);
        let s = start.elapsed().as_secs_f64() + methods[0].per_view[i].seconds;
        methods[1].record(&scene, &t, &set, s);
        let start = Instant::now();
        let lazy = grid.cull(
            &camera,
            &GridParams {
                cell_pixels: args.grid_cell,
                lazy: true,
            },
            &mut set,
        );
        let s = start.elapsed().as_secs_f64();
        methods[2].record(&scene, &t, &set, s);
        let start = Instant::now();
        let busy = grid.cull(
            &camera,
            &GridParams {
                cell_pixels: args.grid_cell,
                lazy: false,
            },
            &mut set,
        );
        grid_costs.push(GridCost {
            lazy_pixel_queries: lazy.pixel_queries,
            busy_pixel_queries: busy.pixel_queries,
            lazy_cell_updates: lazy.cell_updates,
            busy_cell_updates: busy.cell_updates,
            boxes_tested: lazy.boxes_tested,
            lazy_ms: 1e3 * s,
            busy_ms: 1e3 * start.elapsed().as_secs_f64(),
        });
        if let Some(oracle) = &oracle {
            let start = Instant::now();
            let cell = Aabb::new(view.position - half, view.position + half);
            let mut kept = oracle.cell(&cell, None).visible;
            kept.intersect_with(&frustum);
            let s = start.elapsed().as_secs_f64() + methods[0].per_view[i].seconds;
            methods[3].record(&scene, &t, &kept, s);
        }
        truths.push(t);
        bar.set_position(i as u64 + 1);
    }
    bar.finish_and_clear();
    let summary = vis5d::builder::summarize(&file.tree, &scene);
    let leaf_set_sizes: Vec<usize> = file
        .tree
        .leaves()
        .iter()
        .map(|l| file.tree.nodes()[l.node].set.count())
        .collect();
    let report = ReportJson {
        scene: args.file.display().to_string(),
        objects: n,
        triangles: scene.triangles().len(),
        resolution: args.resolution,
        truth_ms_per_view: 1e3 * truth_seconds / views.len() as f64,
        views: views
            .iter()
            .zip(&truths)
            .map(|(v, t)| TruthJson {
                pos: v.position.to_array(),
                dir: v.dir.to_array(),
                fov_degrees: v.fov_y.to_degrees(),
                seen_objects: t.seen.len(),
                hit_pixels: t.hit_pixels,
                seen: t.seen.clone(),
            })
            .collect(),
        methods: methods
            .iter()
            .map(|m| MethodJson {
                name: m.name,
                description: m.description,
                summary: summarise(&m.per_view, &methods[0].per_view, &m.missed),
                per_view: m
                    .per_view
                    .iter()
                    .zip(&m.missed)
                    .map(|(v, missed)| ViewJson {
                        objects: v.objects,
                        triangles: v.triangles,
                        missing_pixels: v.missing_pixels,
                        pixel_error: (v.seen > 0).then_some(v.pixel_error),
                        missed_objects: v.missed_objects,
                        missed: missed.clone(),
                        q_u: (v.seen > 0).then_some(v.q_u),
                        q_o: (v.seen > 0).then_some(v.q_o),
                        ms: 1e3 * v.seconds,
                    })
                    .collect(),
            })
            .collect(),
        tree: TreeJson {
            source,
            build_seconds,
            rays,
            leaves: summary.leaves,
            nodes: summary.nodes,
            mean_leaf_objects: summary.mean_leaf_objects,
            leaf_set_sizes,
            codings: Coding::ALL
                .iter()
                .map(|&c| CodingJson {
                    coding: c.name(),
                    bytes: code_size(&file.tree, c).bytes(),
                })
                .collect(),
        },
        oracle_cell: oracle.as_ref().map(|_| 2.0 * half),
        grid_cell_pixels: args.grid_cell,
        grid_costs,
    };
    write_report(&args.output, &report, &truths, &scene)?;
    println!(
        "wrote {} (index.html, report.json, report.md): {} views, {} methods",
        args.output.display(),
        views.len(),
        report.methods.len()
    );
    for m in &report.methods {
        println!(
            "  {:<10} {:>8.1} objects per view, geometry ratio {}, pixel error {} (worst view {}), {} distinct objects missed",
            m.name,
            m.summary.mean_objects,
            m.summary
                .geometry_ratio
                .map_or("n/a".into(), |g| format!("{g:.2}")),
            share(m.summary.mean_pixel_error),
            share(m.summary.worst_pixel_error),
            m.summary.distinct_missed_objects
        );
    }
    Ok(())
}

fn summarise(views: &[ViewMetrics], frustum: &[ViewMetrics], missed: &[Vec<u32>]) -> MethodSummary {
    let n = views.len().max(1) as f64;
    let defined: Vec<&ViewMetrics> = views.iter().filter(|v| v.seen > 0).collect();
    let d = defined.len().max(1) as f64;
    let frustum_tris: u64 = frustum.iter().map(|v| v.triangles).sum();
    let tris: u64 = views.iter().map(|v| v.triangles).sum();
    let mut distinct: Vec<u32> = missed.iter().flatten().copied().collect();
    distinct.sort_unstable();
    distinct.dedup();
    let (worst_view, worst) = views
        .iter()
        .enumerate()
        .map(|(i, v)| (i, v.pixel_error))
        .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    MethodSummary {
        mean_objects: views.iter().map(|v| v.objects).sum::<usize>() as f64 / n,
        max_objects: views.iter().map(|v| v.objects).max().unwrap_or(0),
        mean_triangles: tris as f64 / n,
        max_triangles: views.iter().map(|v| v.triangles).max().unwrap_or(0),
        geometry_ratio: (tris > 0).then(|| frustum_tris as f64 / tris as f64),
        mean_pixel_error: defined.iter().map(|v| v.pixel_error).sum::<f64>() / d,
        worst_pixel_error: worst,
        worst_view,
        missed_objects: views.iter().map(|v| v.missed_objects).sum(),
        distinct_missed_objects: distinct.len(),
        views_with_misses: views.iter().filter(|v| v.missed_objects > 0).count(),
        mean_q_u: defined.iter().map(|v| v.q_u).sum::<f64>() / d,
        mean_q_o: defined.iter().map(|v| v.q_o).sum::<f64>() / d,
        mean_ms_per_view: 1e3 * views.iter().map(|v| v.seconds).sum::<f64>() / n,
    }
}

/// A share for people: "0" when exactly zero, else three significant
/// digits (so that a small non-zero value never reads as zero).
fn share(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x >= 0.01 {
        format!("{x:.3}")
    } else {
        format!("{x:.2e}")
    }
}

const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(90, 90, 90),
];

/// A line plot of one figure per view, one line per series.
fn line_plot(
    title: &str,
    y_label: &str,
    series: &[(&str, Vec<f64>)],
    y_decimals: usize,
    y_min_top: f64,
) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 340)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("plot: {e}"))?;
        let views = series.iter().map(|s| s.1.len()).max().unwrap_or(1).max(2);
        let top = series
            .iter()
            .flat_map(|s| s.1.iter().copied())
            .fold(0.0f64, f64::max)
            .max(y_min_top)
            * 1.3;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d(0f64..(views - 1) as f64, 0f64..top)
            .map_err(|e| anyhow!("plot: {e}"))?;
        chart
            .configure_mesh()
            .x_desc("view")
            .y_desc(y_label)
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.y_decimals$}"))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|e| anyhow!("plot: {e}"))?;
        for (k, (name, ys)) in series.iter().enumerate() {
            let colour = COLOURS[k % COLOURS.len()];
            chart
                .draw_series(
                    ys.iter()
                        .enumerate()
                        .map(|(i, &y)| Circle::new((i as f64, y), 2, colour.filled())),
                )
                .map_err(|e| anyhow!("plot: {e}"))?;
            chart
                .draw_series(LineSeries::new(
                    ys.iter().enumerate().map(|(i, &y)| (i as f64, y)),
                    colour.stroke_width(1),
                ))
                .map_err(|e| anyhow!("plot: {e}"))?
                .label(*name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| anyhow!("plot: {e}"))?;
        root.present().map_err(|e| anyhow!("plot: {e}"))?;
    }
    Ok(svg)
}

/// A bar chart of labelled values.
fn bar_plot(title: &str, y_label: &str, bars: &[(String, f64)]) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 340)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("plot: {e}"))?;
        let top = bars.iter().map(|b| b.1).fold(0.0f64, f64::max).max(1e-9) * 1.1;
        let n = bars.len().max(1);
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(72)
            .build_cartesian_2d(0f64..n as f64, 0f64..top)
            .map_err(|e| anyhow!("plot: {e}"))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .y_label_formatter(&|y| format!("{y:.0}"))
            .y_desc(y_label)
            .draw()
            .map_err(|e| anyhow!("plot: {e}"))?;
        chart
            .draw_series(bars.iter().enumerate().map(|(i, b)| {
                Rectangle::new(
                    [(i as f64 + 0.15, 0.0), (i as f64 + 0.85, b.1)],
                    COLOURS[i % COLOURS.len()].filled(),
                )
            }))
            .map_err(|e| anyhow!("plot: {e}"))?;
        chart
            .draw_series(bars.iter().enumerate().map(|(i, b)| {
                Text::new(
                    format!("{}: {:.0}", b.0, b.1),
                    (i as f64 + 0.2, b.1 + top * 0.07),
                    ("sans-serif", 14).into_font(),
                )
            }))
            .map_err(|e| anyhow!("plot: {e}"))?;
        root.present().map_err(|e| anyhow!("plot: {e}"))?;
    }
    Ok(svg)
}

/// A histogram of counts.
fn histogram(title: &str, x_label: &str, values: &[usize]) -> Result<String> {
    let max = values.iter().copied().max().unwrap_or(0);
    let bins = 30usize;
    let width = (max / bins + 1).max(1);
    let mut counts = vec![0usize; max / width + 1];
    for &v in values {
        counts[v / width] += 1;
    }
    let bars: Vec<(String, f64)> = counts
        .iter()
        .enumerate()
        .map(|(i, &c)| (format!("{}", i * width), c as f64))
        .collect();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 300)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("plot: {e}"))?;
        let top = bars.iter().map(|b| b.1).fold(0.0f64, f64::max).max(1.0) * 1.1;
        let x_max = (counts.len() * width) as f64;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d(0f64..x_max, 0f64..top)
            .map_err(|e| anyhow!("plot: {e}"))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc("leaves")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.0}"))
            .draw()
            .map_err(|e| anyhow!("plot: {e}"))?;
        chart
            .draw_series(counts.iter().enumerate().map(|(i, &c)| {
                Rectangle::new(
                    [
                        ((i * width) as f64, 0.0),
                        (((i + 1) * width) as f64, c as f64),
                    ],
                    COLOURS[0].filled(),
                )
            }))
            .map_err(|e| anyhow!("plot: {e}"))?;
        root.present().map_err(|e| anyhow!("plot: {e}"))?;
    }
    Ok(svg)
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn write_report(dir: &Path, r: &ReportJson, truths: &[ViewTruth], _scene: &Scene) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    let json = serde_json::to_vec_pretty(r)?;
    let write = |name: &str, bytes: &[u8]| {
        let path = dir.join(name);
        vis5d::atomic_write::write_atomic(&path, bytes)
            .with_context(|| format!("{}: cannot write", path.display()))
    };
    write("report.json", &json)?;
    // The tables, shared by the Markdown and the page.
    let mut rows: Vec<[String; 11]> = Vec::new();
    for m in &r.methods {
        let s = &m.summary;
        rows.push([
            m.name.to_string(),
            format!("{:.1}", s.mean_objects),
            s.max_objects.to_string(),
            format!("{:.0}", s.mean_triangles),
            s.max_triangles.to_string(),
            s.geometry_ratio.map_or("n/a".into(), |g| format!("{g:.2}")),
            share(s.mean_pixel_error),
            if s.worst_pixel_error > 0.0 {
                format!("{} (view {})", share(s.worst_pixel_error), s.worst_view)
            } else {
                "0".into()
            },
            format!(
                "{} in {} of {} views ({} distinct)",
                s.missed_objects,
                s.views_with_misses,
                r.views.len(),
                s.distinct_missed_objects
            ),
            format!("{} / {}", share(s.mean_q_u), share(s.mean_q_o)),
            format!("{:.3}", s.mean_ms_per_view),
        ]);
    }
    let head = [
        "method",
        "objects / view",
        "max",
        "triangles / view",
        "max",
        "geometry ratio",
        "pixel error",
        "worst view",
        "missed objects",
        "Q_u / Q_o",
        "ms / view",
    ];
    let blind = r.views.iter().filter(|v| v.seen_objects == 0).count();
    let (lazy_q, busy_q): (u64, u64) = r.grid_costs.iter().fold((0, 0), |a, c| {
        (a.0 + c.lazy_pixel_queries, a.1 + c.busy_pixel_queries)
    });
    let legend = format!(
        "Geometry ratio: triangles after view-frustum culling over the method's, summed over the views. \
         Pixel error: the share of a view's hit pixels whose object the method does not draw, averaged over the \
         {} views that show something ({} show nothing); worst view: the largest, and which view. Missed objects: \
         objects seen but not drawn, counted per view (an object missed in 3 views counts 3), and how many distinct. \
         Q_u = |S_E \\ S_A| / |S_E| and Q_o = |S_A \\ S_E| / |S_E| (S_E the objects seen, S_A those drawn), averaged \
         like the pixel error. ms / view: the method's time per view; for the tree and the oracle it includes the \
         frustum test, for the lazy grid it is the lazy pass alone (the busy pass is timed in report.json). The ground \
         truth took {:.0} ms per view. Lazy occlusion grid ({} x {} pixel cells): {} pixel-level queries with lazy \
         updates, {} with busy ones ({}).{}",
        r.views.len() - blind,
        blind,
        r.truth_ms_per_view,
        r.grid_cell_pixels,
        r.grid_cell_pixels,
        lazy_q,
        busy_q,
        if busy_q == 0 {
            "n/a".to_string()
        } else {
            format!("{:.1}%", 100.0 * lazy_q as f64 / busy_q as f64)
        },
        match r.oracle_cell {
            Some(c) => format!(" The oracle's cell: a cube of {c:.3} scene units around the eye."),
            None => String::new(),
        }
    );
    let seen_mean =
        truths.iter().map(|t| t.seen.len()).sum::<usize>() as f64 / truths.len().max(1) as f64;
    let mut md = String::new();
    writeln!(md, "# vis5d report: {}", r.scene)?;
    writeln!(
        md,
        "\n{} objects, {} triangles; {} views at {}x{} pixels; ground truth: {:.1} objects seen per view ({:.1} ms per view).\n",
        r.objects,
        r.triangles,
        r.views.len(),
        r.resolution,
        r.resolution,
        seen_mean,
        r.truth_ms_per_view
    )?;
    writeln!(md, "| {} |", head.join(" | "))?;
    writeln!(md, "|{}", "---|".repeat(head.len()))?;
    for row in &rows {
        writeln!(md, "| {} |", row.join(" | "))?;
    }
    writeln!(md, "\n{legend}")?;
    writeln!(md, "\n## The tree\n")?;
    // One sentence about the tree, for both pages.
    let tree_line = format!(
        "{}: {} leaves, {} nodes, {:.1} objects per leaf on average{}.",
        r.tree.source,
        r.tree.leaves,
        r.tree.nodes,
        r.tree.mean_leaf_objects,
        match (r.tree.build_seconds, r.tree.rays) {
            (Some(s), Some(n)) => format!("; built in {s:.2} s with {n} rays"),
            _ => String::new(),
        }
    );
    writeln!(md, "{tree_line}\n")?;
    writeln!(md, "| coding | bytes |\n|---|---:|")?;
    for c in &r.tree.codings {
        writeln!(md, "| {} | {} |", c.coding, c.bytes)?;
    }
    writeln!(md, "\n## Methods\n")?;
    for m in &r.methods {
        writeln!(md, "- **{}**: {}", m.name, m.description)?;
    }
    write("report.md", md.as_bytes())?;
    // The page.
    let mut series: Vec<(&str, Vec<f64>)> = r
        .methods
        .iter()
        .map(|m| {
            (
                m.name,
                m.per_view.iter().map(|v| v.objects as f64).collect(),
            )
        })
        .collect();
    series.push((
        "seen (truth)",
        truths.iter().map(|t| t.seen.len() as f64).collect(),
    ));
    let objects_plot = line_plot("Objects drawn per view", "objects", &series, 0, 1.0)?;
    let error_series: Vec<(&str, Vec<f64>)> = r
        .methods
        .iter()
        .map(|m| {
            (
                m.name,
                m.per_view
                    .iter()
                    .map(|v| 100.0 * v.pixel_error.unwrap_or(0.0))
                    .collect(),
            )
        })
        .collect();
    let error_plot = line_plot(
        "Pixel error per view",
        "missing pixels (%)",
        &error_series,
        3,
        0.01,
    )?;
    let grid_plot = line_plot(
        "Pixel-level queries of the occlusion grid per view",
        "pixel queries",
        &[
            (
                "lazy update",
                r.grid_costs
                    .iter()
                    .map(|c| c.lazy_pixel_queries as f64)
                    .collect(),
            ),
            (
                "busy update",
                r.grid_costs
                    .iter()
                    .map(|c| c.busy_pixel_queries as f64)
                    .collect(),
            ),
        ],
        0,
        1.0,
    )?;
    let leaf_plot = histogram(
        "Objects per leaf of the tree",
        "objects in the leaf's set",
        &r.tree.leaf_set_sizes,
    )?;
    let code_plot = bar_plot(
        "Coded size of the tree's sets",
        "bytes",
        &r.tree
            .codings
            .iter()
            .map(|c| (c.coding.to_string(), c.bytes as f64))
            .collect::<Vec<_>>(),
    )?;
    let mut html = String::new();
    writeln!(
        html,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>vis5d report: {}</title>",
        html_escape(&r.scene)
    )?;
    writeln!(
        html,
        "<style>body{{font-family:sans-serif;max-width:64rem;margin:2rem auto;padding:0 1rem;color:#222}}\
         table{{border-collapse:collapse;margin:1rem 0}}th,td{{border:1px solid #ccc;padding:.3rem .6rem;text-align:right}}\
         th:first-child,td:first-child{{text-align:left}}figure{{margin:1.5rem 0}}figcaption{{color:#555;font-size:.9rem}}.legend{{color:#444;font-size:.9rem}}</style></head><body>"
    )?;
    writeln!(html, "<h1>vis5d report: {}</h1>", html_escape(&r.scene))?;
    writeln!(
        html,
        "<p>{} objects, {} triangles; {} views at {}&times;{} pixels; the ground truth (one ray per pixel) sees {:.1} objects per view.</p>",
        r.objects,
        r.triangles,
        r.views.len(),
        r.resolution,
        r.resolution,
        seen_mean
    )?;
    writeln!(
        html,
        "<table><tr>{}</tr>",
        head.iter()
            .map(|h| format!("<th>{h}</th>"))
            .collect::<String>()
    )?;
    for row in &rows {
        writeln!(
            html,
            "<tr>{}</tr>",
            row.iter()
                .map(|c| format!("<td>{}</td>", html_escape(c)))
                .collect::<String>()
        )?;
    }
    writeln!(
        html,
        "</table><p class=\"legend\">{}</p><ul>",
        html_escape(&legend)
    )?;
    for m in &r.methods {
        writeln!(
            html,
            "<li><b>{}</b>: {}</li>",
            m.name,
            html_escape(m.description)
        )?;
    }
    writeln!(html, "</ul>")?;
    let figure = |html: &mut String, id: &str, svg: &str, caption: &str| {
        writeln!(
            html,
            "<figure id=\"{id}\">{svg}<figcaption>{caption}</figcaption></figure>"
        )
    };
    figure(
        &mut html,
        "objects",
        &objects_plot,
        "Objects each method draws per view, and the objects the view really shows.",
    )?;
    figure(
        &mut html,
        "pixel-error",
        &error_plot,
        "Share of the view's hit pixels whose object the method does not draw (lines at zero overlap).",
    )?;
    figure(
        &mut html,
        "grid",
        &grid_plot,
        "The lazy occlusion grid's pixel-level queries, lazy against busy cell updates (papers/002 Fig. 8): the same sets, at different cost.",
    )?;
    writeln!(html, "<h2>The tree</h2><p>{}</p>", html_escape(&tree_line))?;
    writeln!(html, "<table><tr><th>coding</th><th>bytes</th></tr>")?;
    for c in &r.tree.codings {
        writeln!(html, "<tr><td>{}</td><td>{}</td></tr>", c.coding, c.bytes)?;
    }
    writeln!(html, "</table>")?;
    figure(
        &mut html,
        "leaves",
        &leaf_plot,
        "How many objects the tree's leaves hold.",
    )?;
    figure(
        &mut html,
        "codings",
        &code_plot,
        "The tree's sets coded three ways (papers/003 sec. 6).",
    )?;
    writeln!(html, "</body></html>")?;
    write("index.html", html.as_bytes())?;
    Ok(())
}
