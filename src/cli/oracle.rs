//! `vis5d oracle`: a conservative oracle for one cell (extended
//! projections or occluder shrinking), and the oracle flags `vis5d check`
//! shares.

use std::io::{self, Write};
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Result, anyhow};
use clap::{Args, ValueEnum};
use serde::Serialize;
use vis5d::oracle::{CellReport, Oracle, OracleError, OracleParams, Rasteriser};
use vis5d::shrink::{ShrinkError, ShrinkOracle, ShrinkParams};

use crate::common::{WorldBox, flag, load_scene_up, parse_box, printable};

/// Settings shared by `oracle` and `check`.
#[derive(Args, Debug, Clone)]
pub struct OracleFlags {
    /// Depth Map pixels on a side (a power of two; the paper found 256
    /// best) [4 to 4096].
    #[arg(long, default_value_t = 256)]
    pub resolution: usize,
    /// How far each projection plane reaches beyond the cell's face, in
    /// multiples of its distance from the face (the paper used 1.5) [0 or
    /// more, finite].
    #[arg(long, default_value_t = 1.5, allow_hyphen_values = true)]
    pub extension: f64,
    /// The most occluders drawn into one Depth Map (the largest first) [1
    /// to 1,000,000].
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub max_occluders: u32,
    /// Projection planes per face of the cell: the best position, then
    /// those that hide most objects the others do not [1 to 16].
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=16))]
    pub planes_per_face: u8,
    /// Occlusion sweep (papers/001 sec. 5): planes per face spaced
    /// geometrically from the nearest occluder to the farthest, each
    /// holding the previous one reprojected, so that many small occluders
    /// fuse. With the shafts on (the default) it runs only where slices
    /// are culled: the shafts prove nearly every whole object it hides, in
    /// less time [0 to 64; 0 with --sweep-patches 0 turns the sweep off].
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(0..=64))]
    pub sweep_planes: u8,
    /// Occlusion sweep: planes per face at the axis-aligned patches
    /// (floors, slabs, walls, flat roofs) that subtend the largest solid
    /// angles from the cell, each patch drawn whole, holes and all [0 to
    /// 64].
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(0..=64))]
    pub sweep_patches: u8,
    /// Occlusion sweep: each plane takes the reprojections of this many
    /// planes before it, 1, 2, 4, ... planes back (1: the previous one).
    /// Every reprojection loses up to a pixel at the edges of what it
    /// carries; reaching back, an umbra carried through k planes loses
    /// about log2(k) pixels instead of k. The default reaches over a
    /// default sweep; more pays with many sweep planes: a dense forest's
    /// crowns fuse only through thin steps (`vis5d scene grove`:
    /// `--sweep-planes 16 --sweep-reach 5`) [1 to 8].
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=8))]
    pub sweep_reach: u8,
    /// Occludees below object level: an object not proved hidden whole is
    /// tried cluster by cluster, its triangles cut in halves this many
    /// levels deep, and is hidden when every cluster is (1: whole objects
    /// only) [1 to 16].
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u8).range(1..=16))]
    pub occludee_depth: u8,
    /// Shafts: an object the maps did not hide is tried one occluder at a
    /// time (strong occlusion), the cell and the object's box cut in halves
    /// until every part is blocked by one convex occluder or one cut of a
    /// closed (or floorless) solid, or goes on through the one hole such
    /// a cut leaves (a wall's door); at most this many shafts an object [0
    /// (off) to 1,000,000].
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(0..=1_000_000))]
    pub shaft_budget: u32,
    /// Shafts: the most cuts along one path [0 to 32].
    #[arg(long, default_value_t = 24, value_parser = clap::value_parser!(u8).range(0..=32))]
    pub shaft_depth: u8,
    /// Sealed rooms: the free space between the closed solids (walls,
    /// slabs, closed doors and windows) is cut into connected pieces over
    /// a grid of at most about this many voxels, and what no free path
    /// from the cell reaches is hidden; the grid is built once, at the
    /// first cell above every floorless solid's floor [0 (off) to
    /// 268,435,456].
    #[arg(long, default_value_t = 1 << 24,
          value_parser = clap::value_parser!(u32).range(0..=(1 << 28)))]
    pub seal_voxels: u32,
    /// Rasterise the Depth Maps (with `--method shrink`, the cube map) on
    /// the CPU even when a GPU adapter exists (the default uses the GPU
    /// through wgpu, and the CPU when there is none).
    #[arg(long)]
    pub cpu: bool,
}

impl OracleFlags {
    /// The oracle settings these flags give, checked.
    pub fn params(&self) -> Result<OracleParams> {
        let p = OracleParams {
            resolution: self.resolution,
            extension: self.extension,
            max_occluders: self.max_occluders as usize,
            planes_per_face: self.planes_per_face.into(),
            sweep_planes: self.sweep_planes.into(),
            sweep_patches: self.sweep_patches.into(),
            sweep_reach: self.sweep_reach.into(),
            occludee_depth: self.occludee_depth.into(),
            shaft_budget: self.shaft_budget as usize,
            shaft_depth: self.shaft_depth.into(),
            seal_voxels: self.seal_voxels as usize,
            ..OracleParams::default()
        };
        p.validate().map_err(|e| match &e {
            OracleError::Parameter { name, .. } => anyhow!("{}: {e}", flag(name)),
        })?;
        Ok(p)
    }

    /// The rasteriser these flags ask for: the CPU with `--cpu`, else the
    /// GPU where there is one (a note on stderr says why not).
    pub fn rasteriser(&self) -> Rasteriser {
        if self.cpu {
            return Rasteriser::cpu();
        }
        gpu_else_cpu()
    }
}

/// The GPU rasteriser where there is one, else the CPU's (a note on
/// stderr says why).
pub fn gpu_else_cpu() -> Rasteriser {
    let r = Rasteriser::best();
    if let Some(why) = r.cpu_reason() {
        say!("note: {why}; using the CPU rasteriser");
    }
    r
}

/// Says on stderr, once, as soon as a depth map failed on the GPU (and was
/// made on the CPU instead), and at the end how many did.
#[derive(Default)]
pub struct GpuWarning {
    warned: std::sync::atomic::AtomicBool,
}

impl GpuWarning {
    /// Warns if a map has failed since the start and no warning was given;
    /// cheap enough to call after every cell.
    pub fn poll(&self, r: &Rasteriser) {
        if let (1.., Some(first)) = r.gpu_failures()
            && !self.warned.swap(true, std::sync::atomic::Ordering::Relaxed)
        {
            say!(
                "warning: the GPU failed to make a depth map ({first}); this map and any other \
                 that fails are made on the CPU"
            );
        }
    }

    /// At the end: how many maps failed on the GPU, if any.
    pub fn finish(&self, r: &Rasteriser) {
        self.poll(r);
        if let (n @ 1.., _) = r.gpu_failures() {
            say!("warning: {n} depth maps failed on the GPU and were made on the CPU");
        }
    }
}

#[derive(Args, Debug)]
pub struct OracleArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
    /// The scene's up axis in its file: x, y or z (glTF and most game
    /// engines: y). Local z follows it: directions are parametrised by
    /// their angle from it (phi) and about it (theta), floorless buildings
    /// stand on it. Cells and printed points stay in world coordinates.
    #[arg(long, value_name = "AXIS", default_value = "z")]
    up: vis5d::geom::Up,
    /// Objects' flags, as for `vis5d build --flags`: a JSON object from
    /// default ids to lists of flags (`always_visible`: kept;
    /// `never_occluder`: hides nothing), added to those the model gives
    /// (a glTF node's `extras.vis5d.flags`).
    #[arg(long = "flags", value_name = "FLAGS.json")]
    object_flags: Option<PathBuf>,
    /// The view cell: a box of viewpoints, x0,y0,z0,x1,y1,z1 (world
    /// coordinates).
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", value_parser = parse_box, allow_hyphen_values = true)]
    cell: WorldBox,
    /// The method: `extended` (papers/001's extended projections onto
    /// planes around the cell) or `shrink` (papers/004: closed solids
    /// shrunk by half the cell's diagonal, tested from its centre; only
    /// --resolution, the cube map's pixels a side, and --occludee-depth
    /// apply).
    #[arg(long, value_enum, default_value_t = Method::Extended)]
    method: Method,
    /// Slices (papers/004 sec. 3): cut every object into N slices along
    /// each axis and, for each object kept, find the lower part of it
    /// that is proved hidden, as one slice index per axis (`+k` the first
    /// k slices along x or y, `-k` the last k, and the lowest k along z);
    /// prints each and the triangles it culls [0 (off) to 255].
    #[arg(long, default_value_t = 0)]
    slices: usize,
    #[command(flatten)]
    flags: OracleFlags,
    /// Print as JSON: the objects, the planes and the timings.
    #[arg(long)]
    json: bool,
}

/// A conservative from-region method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// Extended projections (papers/001).
    Extended,
    /// Occluder shrinking (papers/004).
    Shrink,
}

#[derive(Serialize)]
struct PlaneJson {
    /// The face in world axes ("+x", "-y", ...).
    face: String,
    position: f64,
    occluders: usize,
    slices: usize,
    filled_pixels: usize,
    hidden: usize,
}

#[derive(Serialize)]
struct OracleJson<'a> {
    #[serde(flatten)]
    common: CellJson<'a>,
    planes: Vec<PlaneJson>,
    sweep_planes: usize,
    sweep_hidden: usize,
    cluster_hidden: usize,
    /// Objects proved hidden only shaft by shaft.
    shaft_hidden: usize,
    /// Objects proved hidden by the free space: no path between the
    /// closed solids leads to them from the cell.
    sealed_hidden: usize,
    /// Closed convex solids the cell reaches into by a whole slab (or
    /// lies in).
    inside_solids: usize,
    /// The part of the cell the projections ran from (world coordinates).
    projected_from: [[f64; 3]; 2],
    seconds: Seconds,
}

/// What both methods answer, in the same fields.
#[derive(Serialize)]
struct CellJson<'a> {
    method: &'static str,
    scene: String,
    /// World coordinates, as given.
    cell: [[f64; 3]; 2],
    objects: usize,
    /// Convex occluders (extended), or solids that can be shrunk.
    occluders: usize,
    potentially_visible: Vec<&'a str>,
    hidden: usize,
    touching_cell: usize,
    resolution: usize,
    backend: String,
    /// With --slices: the kept objects with slices proved hidden.
    slices: Vec<SliceJson<'a>>,
}

impl<'a> CellJson<'a> {
    /// The common answer for `visible`, from either method.
    #[allow(clippy::too_many_arguments)]
    fn new(
        method: &'static str,
        args: &OracleArgs,
        scene: &'a vis5d::scene::Scene,
        visible: &vis5d::bitset::ObjectSet,
        touching: usize,
        occluders: usize,
        resolution: usize,
        backend: String,
        slices: &[Option<vis5d::slices::HiddenSlices>],
    ) -> Self {
        let names: Vec<&str> = visible
            .iter()
            .map(|i| scene.objects()[i].name.as_str())
            .collect();
        Self {
            method,
            scene: args.file.display().to_string(),
            cell: [args.cell.min.to_array(), args.cell.max.to_array()],
            objects: scene.objects().len(),
            occluders,
            hidden: scene.objects().len() - names.len(),
            potentially_visible: names,
            touching_cell: touching,
            resolution,
            backend,
            slices: slice_rows(scene, slices),
        }
    }

    /// The slices found and the line that sums the answer up.
    fn write_verdict(&self, out: &mut impl Write) -> io::Result<()> {
        write_slices(out, &self.slices)?;
        writeln!(
            out,
            "potentially visible: {} of {} objects ({:.1}% proved hidden; {} touch the cell)",
            self.potentially_visible.len(),
            self.objects,
            100.0 * self.hidden as f64 / self.objects.max(1) as f64,
            self.touching_cell
        )
    }

    /// The names of the objects kept, one a line.
    fn write_names(&self, out: &mut impl Write) -> io::Result<()> {
        for n in &self.potentially_visible {
            writeln!(out, "{}", printable(n))?;
        }
        Ok(())
    }
}

/// A kept object's hidden slices.
#[derive(Serialize)]
struct SliceJson<'a> {
    object: &'a str,
    /// Per piece of the object (one for an object of up to 1,024
    /// triangles), the index: [x, y, z] (see --slices).
    indices: Vec<[i16; 3]>,
    triangles: usize,
    culled: usize,
}

/// The kept objects' hidden slices, as JSON rows.
fn slice_rows<'a>(
    scene: &'a vis5d::scene::Scene,
    slices: &[Option<vis5d::slices::HiddenSlices>],
) -> Vec<SliceJson<'a>> {
    slices
        .iter()
        .enumerate()
        .filter_map(|(o, s)| {
            s.as_ref().map(|h| SliceJson {
                object: scene.objects()[o].name.as_str(),
                indices: h
                    .pieces
                    .iter()
                    .map(|(i, _)| [i.x, i.y, i16::from(i.z)])
                    .collect(),
                triangles: scene.objects()[o].triangle_count(),
                culled: h.culled(),
            })
        })
        .collect()
}

/// Prints the slice rows.
fn write_slices(out: &mut impl Write, rows: &[SliceJson]) -> io::Result<()> {
    if rows.is_empty() {
        return Ok(());
    }
    let culled: usize = rows.iter().map(|r| r.culled).sum();
    writeln!(
        out,
        "  slices: {} kept objects partly hidden, {culled} of their triangles culled",
        rows.len()
    )?;
    for r in rows {
        let indices = if r.indices.len() == 1 {
            let i = r.indices[0];
            format!("[{}, {}, {}]", i[0], i[1], i[2])
        } else {
            let partly = r.indices.iter().filter(|i| **i != [0, 0, 0]).count();
            format!("{partly} of {} pieces", r.indices.len())
        };
        writeln!(
            out,
            "    {} {indices}: {} of {} triangles culled",
            printable(r.object),
            r.culled,
            r.triangles
        )?;
    }
    Ok(())
}

/// The scene sliced as `--slices` asks, if it does.
fn sliced_scene(
    scene: &vis5d::scene::Scene,
    args: &OracleArgs,
) -> Result<Option<vis5d::slices::SlicedScene>> {
    if args.slices == 0 {
        return Ok(None);
    }
    vis5d::slices::SlicedScene::new(scene, args.slices)
        .map(Some)
        .map_err(|e| anyhow!("--slices: {e}"))
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

/// Runs `vis5d oracle`.
pub fn run(args: &OracleArgs) -> Result<()> {
    if args.method == Method::Shrink {
        return run_shrink(args);
    }
    let params = args.flags.params()?;
    let (scene, load) = load_scene_up(&args.file, args.up)?;
    let scene = crate::common::with_flags(args.object_flags.as_deref(), scene)?;
    let rasteriser = args.flags.rasteriser();
    let start = Instant::now();
    let oracle = Oracle::new(&scene, params, rasteriser)?;
    let prepare = start.elapsed().as_secs_f64();
    let frame = scene.frame();
    let sliced = sliced_scene(&scene, args)?;
    let report: CellReport = match &sliced {
        Some(s) => oracle.cell_slices(&args.cell.to_local(&frame), None, s),
        None => oracle.cell(&args.cell.to_local(&frame), None),
    };
    GpuWarning::default().finish(oracle.rasteriser());
    let t = report.times;
    let json = OracleJson {
        common: CellJson::new(
            "extended",
            args,
            &scene,
            &report.visible,
            report.touching,
            oracle.occluder_count(),
            oracle.params().resolution,
            oracle.rasteriser().name(),
            &report.slices,
        ),
        planes: report
            .planes
            .iter()
            .map(|p| {
                // The face's local axis, as a world axis (`--up` turns
                // them), and the position in world coordinates: the
                // frame's origin along it added.
                let local = match p.face.as_bytes().get(1) {
                    Some(b'x') => 0,
                    Some(b'y') => 1,
                    _ => 2,
                };
                let world = frame.up.world_axis(local);
                PlaneJson {
                    face: format!("{}{}", &p.face[..1], ["x", "y", "z"][world]),
                    position: p.position + frame.origin[world],
                    occluders: p.occluders,
                    slices: p.slices,
                    filled_pixels: p.filled,
                    hidden: p.hidden,
                }
            })
            .collect(),
        sweep_planes: report.sweep_planes,
        sweep_hidden: report.sweep_hidden,
        cluster_hidden: report.cluster_hidden,
        shaft_hidden: report.shaft_hidden,
        sealed_hidden: report.sealed_hidden,
        inside_solids: report.inside_solids,
        projected_from: [
            frame.to_world(report.projected_from.min).to_array(),
            frame.to_world(report.projected_from.max).to_array(),
        ],
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
        "{}: {} objects, {} occluders ({} convex solids, {} convex shells, {} polygons, {} triangles), {} objects to slice, {} terrains",
        json.common.scene,
        json.common.objects,
        json.common.occluders,
        c.solids,
        c.shells,
        c.polygons,
        c.triangles,
        oracle.solid_count(),
        oracle.terrain_count()
    )?;
    writeln!(
        out,
        "cell {:?} .. {:?}",
        json.common.cell[0], json.common.cell[1]
    )?;
    let pixels = (json.common.resolution * json.common.resolution) as f64;
    for p in &json.planes {
        writeln!(
            out,
            "  plane {} at {:.4}: {} occluders, {} solids cut, {:.1}% of {}x{} pixels filled, {} objects hidden",
            p.face,
            p.position,
            p.occluders,
            p.slices,
            100.0 * p.filled_pixels as f64 / pixels,
            json.common.resolution,
            json.common.resolution,
            p.hidden
        )?;
    }
    if json.sweep_planes > 0 {
        writeln!(
            out,
            "  occlusion sweep: {} planes, {} more objects hidden",
            json.sweep_planes, json.sweep_hidden
        )?;
    }
    if json.inside_solids > 0 {
        let [a, b] = json.projected_from;
        writeln!(
            out,
            "  inside solids: the cell reaches into {} closed solids; projected from {a:?} .. {b:?}, what meets those solids kept",
            json.inside_solids
        )?;
    }
    if json.cluster_hidden > 0 {
        writeln!(
            out,
            "  occludee clusters: {} more objects hidden cluster by cluster",
            json.cluster_hidden
        )?;
    }
    if json.sealed_hidden > 0 {
        writeln!(
            out,
            "  sealed: {} objects no free path from the cell reaches",
            json.sealed_hidden
        )?;
    }
    if json.shaft_hidden > 0 {
        writeln!(
            out,
            "  shafts: {} more objects hidden one occluder at a time",
            json.shaft_hidden
        )?;
    }
    json.common.write_verdict(&mut out)?;
    let s = &json.seconds;
    writeln!(
        out,
        "time: load {:.3} s, prepare {:.3} s, cell {:.3} s (select {:.3}, rasterise {:.3}, test {:.3}); depth maps on the {}",
        s.load, s.prepare, s.cell, s.select, s.rasterise, s.test, json.common.backend
    )?;
    json.common.write_names(&mut out)?;
    Ok(())
}

#[derive(Serialize)]
struct ShrinkJson<'a> {
    #[serde(flatten)]
    common: CellJson<'a>,
    /// The distance the solids were shrunk by.
    erosion: f64,
    solids_drawn: usize,
    faces_drawn: usize,
    /// What shrinking did to the solids' faces.
    faces: FacesJson,
    covered_pixels: usize,
    cluster_hidden: usize,
    seconds: ShrinkSeconds,
}

#[derive(Serialize)]
struct FacesJson {
    input: usize,
    degenerate: usize,
    swept: usize,
    #[serde(rename = "unsafe")]
    unsafe_: usize,
    kept: usize,
}

#[derive(Serialize)]
struct ShrinkSeconds {
    load: f64,
    prepare: f64,
    shrink: f64,
    rasterise: f64,
    test: f64,
    cell: f64,
}

/// `vis5d oracle --method shrink`.
fn run_shrink(args: &OracleArgs) -> Result<()> {
    let params = ShrinkParams {
        resolution: args.flags.resolution,
        occludee_depth: args.flags.occludee_depth.into(),
        ..ShrinkParams::default()
    };
    params.validate().map_err(|e| match &e {
        ShrinkError::Parameter { name, .. } => anyhow!("{}: {e}", flag(name)),
    })?;
    let (scene, load) = load_scene_up(&args.file, args.up)?;
    let scene = crate::common::with_flags(args.object_flags.as_deref(), scene)?;
    let rasteriser = args.flags.rasteriser();
    let start = Instant::now();
    let oracle = ShrinkOracle::with_rasteriser(&scene, params, rasteriser)?;
    if let Some(why) = oracle.cpu_reason() {
        say!("note: {why}; the cube map is drawn on the CPU");
    }
    let prepare = start.elapsed().as_secs_f64();
    let frame = scene.frame();
    let sliced = sliced_scene(&scene, args)?;
    let report = match &sliced {
        Some(s) => oracle.cell_slices(&args.cell.to_local(&frame), s),
        None => oracle.cell(&args.cell.to_local(&frame)),
    };
    GpuWarning::default().finish(oracle.rasteriser());
    let t = report.times;
    let c = report.counts;
    let json = ShrinkJson {
        common: CellJson::new(
            "shrink",
            args,
            &scene,
            &report.visible,
            report.touching,
            oracle.solid_count(),
            oracle.params().resolution,
            oracle.backend(),
            &report.slices,
        ),
        erosion: report.erosion,
        solids_drawn: report.solids_drawn,
        faces_drawn: report.faces_drawn,
        faces: FacesJson {
            input: c.input,
            degenerate: c.degenerate,
            swept: c.swept,
            unsafe_: c.unsafe_,
            kept: c.kept,
        },
        covered_pixels: report.covered,
        cluster_hidden: report.cluster_hidden,
        seconds: ShrinkSeconds {
            load,
            prepare,
            shrink: t.shrink.as_secs_f64(),
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
    writeln!(
        out,
        "{}: {} objects, {} closed solids (or open only at the bottom) to shrink",
        json.common.scene, json.common.objects, json.common.occluders
    )?;
    writeln!(
        out,
        "cell {:?} .. {:?}",
        json.common.cell[0], json.common.cell[1]
    )?;
    let f = &json.faces;
    writeln!(
        out,
        "  shrunk by {:.4}: of {} faces, {} degenerate, {} swept into others (the paper's test), {} not deep enough inside (ours), {} kept",
        json.erosion, f.input, f.degenerate, f.swept, f.unsafe_, f.kept
    )?;
    let pixels = 6 * json.common.resolution * json.common.resolution;
    writeln!(
        out,
        "  from the centre: {} shrunk solids ({} faces) drawn, {:.1}% of 6 x {}x{} pixels covered",
        json.solids_drawn,
        json.faces_drawn,
        100.0 * json.covered_pixels as f64 / pixels as f64,
        json.common.resolution,
        json.common.resolution
    )?;
    if json.cluster_hidden > 0 {
        writeln!(
            out,
            "  occludee clusters: {} objects hidden cluster by cluster",
            json.cluster_hidden
        )?;
    }
    json.common.write_verdict(&mut out)?;
    let s = &json.seconds;
    writeln!(
        out,
        "time: load {:.3} s, prepare {:.3} s, cell {:.3} s (shrink {:.3}, rasterise {:.3}, test {:.3}); cube map on the {}",
        s.load, s.prepare, s.cell, s.shrink, s.rasterise, s.test, json.common.backend
    )?;
    json.common.write_names(&mut out)?;
    Ok(())
}
