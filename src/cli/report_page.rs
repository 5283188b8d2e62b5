//! The report's outputs: `report.json` (every figure), `report.md` (the
//! tables), `index.html` (the tables, SVG plots and pictures, no
//! JavaScript) and `images/` (the pictures as PNG), from an
//! [`Experiment`].

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result, anyhow};
use plotters::prelude::*;
use serde::Serialize;
use vis5d::codec::{Coding, V5dFile, code_size};
use vis5d::query::View;
use vis5d::report::{
    DROPPED, Experiment, GridCost, LAYER_SHADES, Method, MethodSummary, ReportParams,
    drawn_picture, picture,
};
use vis5d::scene::Scene;

use crate::common::World;

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
    /// World coordinates.
    pos: World,
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

/// One picture of a view: its files (relative to the report's folder)
/// and what it shows of the vis5d tree's answer.
#[derive(Serialize)]
struct PictureJson {
    view: usize,
    /// Full size.
    file: String,
    /// The thumbnail on the page.
    small: String,
    small_size: [u32; 2],
    /// Pixels painted red: the objects the tree dropped.
    dropped_pixels: u64,
    /// Objects seen, not drawn.
    dropped_objects: usize,
    /// Objects seen in the view.
    seen_objects: usize,
    /// Objects the tree draws.
    drawn_objects: usize,
    /// Objects drawn but not seen (hidden, or outside the image).
    drawn_hidden: usize,
    /// What each method draws in this view.
    methods: Vec<DrawnJson>,
}

/// A picture of what one method draws in a view ([`drawn_picture`]).
#[derive(Serialize)]
struct DrawnJson {
    method: &'static str,
    file: String,
    size: [u32; 2],
    /// Objects the method draws.
    objects: usize,
    /// The mean number of the method's objects a pixel's ray passes, over
    /// the pixels that see something (1: no overdraw).
    mean_layers: f64,
    /// Pixels whose object the method does not draw (red).
    dropped_pixels: u64,
}

/// The top-down map: its files and what it shows.
#[derive(Serialize)]
struct MapJson {
    file: String,
    small: String,
    small_size: [u32; 2],
    /// The height of the cut through the tree (world up axis, scene
    /// units, in the tree's frame).
    height: f32,
    /// The distinct boxes of positions outlined.
    cells: usize,
    /// The largest set among them (the deepest blue).
    largest_set: usize,
    /// Whether the eyes are joined as a camera path.
    path: bool,
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
    oracle_rasteriser: Option<String>,
    grid_cell_pixels: u32,
    grid_costs: Vec<GridCost>,
    pictures: Vec<PictureJson>,
    map: Option<MapJson>,
}

/// Where the report's tree came from, for the page.
pub struct TreeSource {
    /// A file's path, or how it was built.
    pub source: String,
    /// Seconds to build it, when it was built here.
    pub build_seconds: Option<f64>,
    /// Rays its build cast, when it was built here.
    pub rays: Option<u64>,
}

/// What a report page shows.
pub struct Page<'a> {
    /// The scene's file, as named on the page.
    pub scene_name: String,
    /// The scene.
    pub scene: &'a Scene,
    /// The views, in order.
    pub views: &'a [View],
    /// The experiment's parameters.
    pub params: &'a ReportParams,
    /// What was measured.
    pub experiment: &'a Experiment,
    /// The tree.
    pub file: &'a V5dFile,
    /// Where the tree came from.
    pub tree: TreeSource,
    /// The top-down map of the tree's cells, with the pictures.
    pub map: Option<&'a vis5d::report::Map>,
}

/// Writes `report.json`, `report.md` and `index.html` into `dir` (made if
/// missing). Returns each method's summary, by name, for the caller's
/// summary lines.
pub fn write(dir: &Path, page: &Page) -> Result<Vec<(&'static str, MethodSummary)>> {
    let Page {
        scene_name,
        scene,
        views,
        params,
        experiment: e,
        file,
        tree,
        map,
    } = page;
    let summary = vis5d::builder::summarize(&file.tree, scene);
    let leaf_set_sizes: Vec<usize> = file
        .tree
        .leaves()
        .iter()
        .map(|l| file.tree.nodes()[l.node].set.count())
        .collect();
    let frustum = e.frustum();
    let mut report = ReportJson {
        scene: scene_name.clone(),
        objects: scene.objects().len(),
        triangles: scene.triangles().len(),
        resolution: params.resolution,
        truth_ms_per_view: 1e3 * e.truth_seconds / views.len().max(1) as f64,
        views: views
            .iter()
            .zip(&e.truths)
            .map(|(v, t)| TruthJson {
                pos: World(scene.frame(), v.position),
                dir: scene.frame().dir_to_world(v.dir).to_array(),
                fov_degrees: v.fov_y.to_degrees(),
                seen_objects: t.seen.len(),
                hit_pixels: t.hit_pixels,
                seen: t.seen.clone(),
            })
            .collect(),
        methods: e
            .methods
            .iter()
            .map(|m| MethodJson {
                name: m.method.name(),
                description: m.method.description(),
                summary: m.summary(frustum),
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
            source: tree.source.clone(),
            build_seconds: tree.build_seconds,
            rays: tree.rays,
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
        oracle_cell: e.oracle_cell,
        oracle_rasteriser: e.oracle_rasteriser.clone(),
        grid_cell_pixels: params.grid_cell,
        grid_costs: e.grid_costs.clone(),
        pictures: Vec::new(),
        map: None,
    };
    let mut images = pictures(e, &mut report)?;
    if let Some(m) = map {
        let small = m.picture.shrunk(2 * THUMBNAIL);
        let (file, small_file) = (
            format!("{IMAGES}/map.png"),
            format!("{IMAGES}/map-small.png"),
        );
        images.push((file.clone(), png_bytes(&m.picture)?));
        images.push((small_file.clone(), png_bytes(&small)?));
        report.map = Some(MapJson {
            file,
            small: small_file,
            small_size: [small.width, small.height],
            height: m.height,
            cells: m.cells,
            largest_set: m.largest_set,
            path: m.joined,
        });
    }
    write_files(dir, &report, e, &images)?;
    Ok(report
        .methods
        .into_iter()
        .map(|m| (m.name, m.summary))
        .collect())
}

/// What the pictures show, for both pages.
const PICTURES_LEGEND: &str = "The first views as the ground truth sees them (one ray per pixel), \
     each object in a flat shade of its own, nothing in dark grey, and in red the pixels of the \
     objects the vis5d tree does not draw: what would pop. Click a picture for its full size.";

/// The map's caption.
fn map_caption(m: &MapJson) -> String {
    format!(
        "The view box seen from above, cut at height {:.2} (the eyes' mean): the {} boxes of \
         positions of the tree's leaves there outlined, each tinted blue the more objects its set \
         holds (the deepest blue {} objects; where leaves of other directions overlap, the \
         largest), the scene beneath in darker shades, and the views' eyes in white{}.",
        m.height,
        m.cells,
        m.largest_set,
        if m.path { ", joined in order" } else { "" }
    )
}

/// A picture's title: its view.
fn picture_title(p: &PictureJson) -> String {
    format!("View {}", p.view)
}

/// A picture's caption: the tree's answer for its view.
fn picture_caption(p: &PictureJson) -> String {
    let dropped = match p.dropped_objects {
        0 => "none dropped".to_string(),
        n => format!(
            "{n} dropped ({} pixel{} in red)",
            p.dropped_pixels,
            if p.dropped_pixels == 1 { "" } else { "s" }
        ),
    };
    format!(
        "{} objects seen; the tree draws {}: {dropped}, {} drawn but hidden.",
        p.seen_objects, p.drawn_objects, p.drawn_hidden
    )
}

/// A share for people: "0" when exactly zero, else three significant
/// digits (so that a small non-zero value never reads as zero).
pub fn share(x: f64) -> String {
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

/// The files a report writes into its folder (and its pictures, in
/// [`IMAGES`]).
pub const OUTPUTS: [&str; 3] = ["report.json", "report.md", "index.html"];

/// The folder of the pictures, in the report's.
pub const IMAGES: &str = "images";

/// The longest side of a picture's thumbnail on the page, in pixels.
const THUMBNAIL: u32 = 200;

/// The pictures of the views whose ID buffers the experiment kept: the
/// files' paths (relative to the report's folder) and PNG bytes, full
/// size and thumbnail; their figures go into `r.pictures`.
fn pictures(e: &Experiment, r: &mut ReportJson) -> Result<Vec<(String, Vec<u8>)>> {
    let tree = e
        .method(Method::Tree)
        .ok_or_else(|| anyhow!("internal error: the tree's row did not run"))?;
    let mut files = Vec::new();
    for (view, ids) in e.pictures.iter().enumerate() {
        let dropped = &tree.missed[view];
        let full = picture(ids, dropped);
        let small = full.shrunk(THUMBNAIL);
        let (file, small_file) = (
            format!("{IMAGES}/view-{view:03}.png"),
            format!("{IMAGES}/view-{view:03}-small.png"),
        );
        let metrics = &tree.per_view[view];
        let seen = e.truths[view].seen.len();
        let mut methods = Vec::new();
        if let Some(layers) = e.layers.get(view) {
            for run in &e.methods {
                let Some(set) = run.pictured.get(view) else {
                    continue;
                };
                let (drawn, mean_layers) = drawn_picture(layers, set);
                let file = format!("{IMAGES}/view-{view:03}-{}.png", slug(run.method.name()));
                methods.push(DrawnJson {
                    method: run.method.name(),
                    file: file.clone(),
                    size: [drawn.width, drawn.height],
                    objects: set.count(),
                    mean_layers,
                    dropped_pixels: drawn.count(DROPPED),
                });
                files.push((file, png_bytes(&drawn)?));
            }
        }
        r.pictures.push(PictureJson {
            view,
            file: file.clone(),
            small: small_file.clone(),
            small_size: [small.width, small.height],
            dropped_pixels: full.count(DROPPED),
            dropped_objects: dropped.len(),
            seen_objects: seen,
            drawn_objects: metrics.objects,
            drawn_hidden: metrics.objects - (seen - dropped.len()),
            methods,
        });
        files.push((file, png_bytes(&full)?));
        files.push((small_file, png_bytes(&small)?));
    }
    Ok(files)
}

/// A method's name as a file name's part: lower case, words joined by
/// '-'.
fn slug(name: &str) -> String {
    name.split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(str::to_ascii_lowercase)
        .collect::<Vec<_>>()
        .join("-")
}

/// What the pictures of what each method draws show, for both pages.
const DRAWN_LEGEND: &str = "What each method would draw in the same views, at most 200 pixels a \
     side: each pixel tinted by how many of the method's objects its ray passes, from one (pale \
     yellow: exact visibility draws one) to nine or more (deep purple): the overdraw the set \
     costs; in red the pixels whose object the method does not draw (popping). Under each, the \
     mean number of objects a pixel passes.";

/// One picture of what a method draws, for the markdown page.
fn drawn_caption(d: &DrawnJson) -> String {
    format!(
        "{}: {} objects, {:.2} a pixel{}",
        d.method,
        d.objects,
        d.mean_layers,
        if d.dropped_pixels > 0 {
            format!(", {} pixels dropped", d.dropped_pixels)
        } else {
            String::new()
        }
    )
}

/// `p` as a PNG file (8-bit RGB).
fn png_bytes(p: &vis5d::report::Picture) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, p.width, p.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&p.rgb)?;
    writer.finish()?;
    Ok(out)
}

fn write_files(
    dir: &Path,
    r: &ReportJson,
    e: &Experiment,
    images: &[(String, Vec<u8>)],
) -> Result<()> {
    let truths = &e.truths;
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    let json = serde_json::to_vec_pretty(r)?;
    // The tables, shared by the Markdown and the page.
    let mut rows: Vec<[String; 12]> = Vec::new();
    let seen_per_view =
        r.views.iter().map(|v| v.seen_objects).sum::<usize>() as f64 / r.views.len().max(1) as f64;
    for m in &r.methods {
        let s = &m.summary;
        rows.push([
            m.name.to_string(),
            format!("{:.1}", s.mean_objects),
            if seen_per_view > 0.0 {
                format!("{:.2}", s.mean_objects / seen_per_view)
            } else {
                "n/a".into()
            },
            s.max_objects.to_string(),
            match s.mean_slice_triangles {
                Some(t) => format!(
                    "{:.0} (slices: {t:.0}, {:.0}% fewer)",
                    s.mean_triangles,
                    100.0 * (1.0 - t / s.mean_triangles.max(f64::MIN_POSITIVE))
                ),
                None => format!("{:.0}", s.mean_triangles),
            },
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
        "drawn / seen",
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
        "Drawn / seen: the objects the method draws per view over those the ground truth sees per view, \
         on average (overdraw; 1 is tight). Geometry ratio: triangles after view-frustum culling over the method's, summed over the views. \
         Pixel error: the share of a view's hit pixels whose object the method does not draw, averaged over the \
         {} views that show something ({} show nothing); worst view: the largest, and which view. Missed objects: \
         objects seen but not drawn, counted per view (an object missed in 3 views counts 3), and how many distinct. \
         Q_u = |S_E \\ S_A| / |S_E| and Q_o = |S_A \\ S_E| / |S_E| (S_E the objects seen, S_A those drawn), averaged \
         like the pixel error. ms / view: the method's time per view; for the tree it is the query (culling included), for the oracle it includes the \
         frustum test, for the lazy grid it is the lazy pass alone (the busy pass is timed in report.json). The ground \
         truth took {:.0} ms per view. Lazy occlusion grid ({} x {} pixel cells): {} pixel-level queries with lazy \
         updates, {} with busy ones ({}).{}{}",
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
            Some(c) => format!(
                " The oracle's cell: a cube of {c:.3} scene units around the eye; its depth maps on the {}.",
                r.oracle_rasteriser.as_deref().unwrap_or("CPU")
            ),
            None => String::new(),
        },
        if r.methods
            .iter()
            .any(|m| m.summary.mean_slice_triangles.is_some())
        {
            " Slices (papers/004 sec. 3): for the oracle's and the shrinking's rows, triangles / view \
             also counts them at slice granularity: each kept object's triangles less those in its \
             slices proved hidden."
        } else {
            ""
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
    if let Some(m) = &r.map {
        writeln!(
            md,
            "\n## Map\n\n[The tree from above]({}): {}",
            m.file,
            map_caption(m)
        )?;
    }
    if !r.pictures.is_empty() {
        writeln!(md, "\n## Pictures\n\n{PICTURES_LEGEND}\n")?;
        for p in &r.pictures {
            writeln!(
                md,
                "- [{}]({}): {}",
                picture_title(p),
                p.file,
                picture_caption(p)
            )?;
        }
        if r.pictures.iter().any(|p| !p.methods.is_empty()) {
            writeln!(md, "\n## What each method draws\n\n{DRAWN_LEGEND}\n")?;
            for p in &r.pictures {
                let row: Vec<String> = p
                    .methods
                    .iter()
                    .map(|d| format!("[{}]({})", drawn_caption(d), d.file))
                    .collect();
                writeln!(md, "- {}: {}", picture_title(p), row.join("; "))?;
            }
        }
    }

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
         th:first-child,td:first-child{{text-align:left}}figure{{margin:1.5rem 0}}\
         .pictures{{display:flex;flex-wrap:wrap;gap:1rem}}.pictures figure{{margin:0;width:200px}}.pictures img{{image-rendering:pixelated;border:1px solid #ccc}}figcaption{{color:#555;font-size:.9rem}}.legend{{color:#444;font-size:.9rem}}.swatch{{display:inline-block;width:.9em;height:.9em;margin:0 .2em 0 .6em;vertical-align:middle;border:1px solid #999}}table.drawn td{{text-align:center;font-size:.85rem;vertical-align:top}}table.drawn img{{image-rendering:pixelated;border:1px solid #ccc}}.red{{color:#c00}}</style></head><body>"
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
    if let Some(m) = &r.map {
        writeln!(
            html,
            "<h2>The tree from above</h2><figure id=\"map\"><a href=\"{}\"><img src=\"{}\" \
             width=\"{}\" height=\"{}\" alt=\"the tree's cells from above\"></a><figcaption>{}</figcaption></figure>",
            m.file,
            m.small,
            m.small_size[0],
            m.small_size[1],
            html_escape(&map_caption(m))
        )?;
    }
    if !r.pictures.is_empty() {
        writeln!(
            html,
            "<h2>Pictures</h2><p class=\"legend\">{}</p><div class=\"pictures\">",
            html_escape(PICTURES_LEGEND)
        )?;
        for p in &r.pictures {
            writeln!(
                html,
                "<figure id=\"view-{view}\"><a href=\"{file}\"><img src=\"{small}\" width=\"{w}\" \
                 height=\"{h}\" alt=\"{title}\"></a><figcaption><b>{title}</b>: {caption}</figcaption></figure>",
                view = p.view,
                file = p.file,
                small = p.small,
                w = p.small_size[0],
                h = p.small_size[1],
                title = html_escape(&picture_title(p)),
                caption = html_escape(&picture_caption(p)),
            )?;
        }
        writeln!(html, "</div>")?;
        if let Some(first) = r.pictures.iter().find(|p| !p.methods.is_empty()) {
            let swatch = |c: [u8; 3], label: &str| {
                format!(
                    "<span class=\"swatch\" style=\"background:rgb({},{},{})\"></span>{label} ",
                    c[0], c[1], c[2]
                )
            };
            let mut legend: String = LAYER_SHADES
                .iter()
                .enumerate()
                .map(|(k, &c)| {
                    let label = if k + 1 == LAYER_SHADES.len() {
                        format!("{}+", k + 1)
                    } else {
                        (k + 1).to_string()
                    };
                    swatch(c, &label)
                })
                .collect();
            legend += &swatch(DROPPED, "dropped");
            writeln!(
                html,
                "<h2 id=\"drawn\">What each method draws</h2><p class=\"legend\">{}</p><p class=\"legend\">{legend}</p><table class=\"drawn\"><tr><th>view</th>",
                html_escape(DRAWN_LEGEND)
            )?;
            for d in &first.methods {
                writeln!(html, "<th>{}</th>", html_escape(d.method))?;
            }
            writeln!(html, "</tr>")?;
            for p in &r.pictures {
                writeln!(
                    html,
                    "<tr><td><a href=\"#view-{v}\">{v}</a></td>",
                    v = p.view
                )?;
                for d in &p.methods {
                    writeln!(
                        html,
                        "<td><a href=\"{file}\"><img src=\"{file}\" width=\"{w}\" height=\"{h}\" \
                         alt=\"{alt}\"></a><br>{layers:.2}{dropped}</td>",
                        file = d.file,
                        w = d.size[0].min(120),
                        h = (d.size[1] * d.size[0].min(120)).div_ceil(d.size[0].max(1)),
                        alt = html_escape(&drawn_caption(d)),
                        layers = d.mean_layers,
                        dropped = if d.dropped_pixels > 0 {
                            format!(" <span class=\"red\">{} px</span>", d.dropped_pixels)
                        } else {
                            String::new()
                        }
                    )?;
                }
                writeln!(html, "</tr>")?;
            }
            writeln!(html, "</table>")?;
        }
    }
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
    // The files together: all written before any is replaced.
    if !images.is_empty() {
        let folder = dir.join(IMAGES);
        std::fs::create_dir_all(&folder)
            .with_context(|| format!("{}: cannot create the folder", folder.display()))?;
    }
    let files: Vec<std::path::PathBuf> = OUTPUTS
        .iter()
        .map(|name| dir.join(name))
        .chain(images.iter().map(|(name, _)| dir.join(name)))
        .collect();
    let contents: Vec<&[u8]> = [json.as_slice(), md.as_bytes(), html.as_bytes()]
        .into_iter()
        .chain(images.iter().map(|(_, bytes)| bytes.as_slice()))
        .collect();
    let pairs: Vec<(&Path, &[u8])> = files.iter().map(|p| p.as_path()).zip(contents).collect();
    vis5d::atomic_write::write_atomic_all(&pairs)
        .with_context(|| format!("{}: cannot write the report", dir.display()))?;
    Ok(())
}
