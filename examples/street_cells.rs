//! How tight the oracle is from street cells and room cells, against rays.
//!
//! Street cells (the default) are the figure papers/001 reports for a
//! city (about 96% of the geometry culled from street cells): random
//! ground positions of a scene (a vertical ray from above must land first
//! on an object named like "ground" or "terrain"), a view cell of `SIZE` x
//! `SIZE` x `HEIGHT` m there, 1 m above the ground.
//!
//! Room cells (`--rooms`) are cells inside a building: a random point of
//! the scene's box with a floor below it (a vertical ray down lands on a
//! face turned up) and a ceiling above it (a vertical ray up hits
//! something more than `HEIGHT` + 0.2 m higher); the cell stands 0.3 m
//! above the floor and holds no geometry.
//!
//! Cells anywhere (`--anywhere`) are `SIZE` x `SIZE` x `HEIGHT` boxes at
//! uniform random points of the scene's box, geometry in them or not (the
//! never-wrong campaign, `scripts/oracle-never-wrong.sh`).
//!
//! For each cell it runs the oracle (the CPU rasteriser unless `--gpu`,
//! which draws the shrinking's cube maps on the GPU too)
//! and prints the objects kept, the share of objects and triangles proved
//! hidden, a lower bound of the visible set (objects hit by `--rays`
//! random rays from the cell, 200,000 by default), the ratio of the two,
//! and the time; then the means. `--aimed N` tightens the lower bound:
//! each object kept and not hit by the random rays gets N segments from
//! random points of the cell to random points of its surface, and what
//! they hit first is seen too (reported beside the random rays' figure).
//! An object a ray hits that the oracle
//! hid stops the run: the oracle is conservative or it is wrong. `--list`
//! names the objects kept that no ray saw, with their boxes. `--split K`
//! runs the oracle on K x K sub-cells (cut in x and y) as well, each with
//! the whole cell's hidden objects taken as hidden, and reports their
//! union (still conservative: it is how much smaller cells would gain).
//! `--method shrink` runs the occluder-shrinking oracle (papers/004)
//! instead, `both` keeps what neither proves hidden (its time is the sum);
//! `--split` applies to the extended projections only. `--slices N` cuts
//! every object into N slices an axis (papers/004 sec. 3) and culls the
//! hidden slices of kept objects too (`both`: the index that culls more): it reports the
//! triangles drawn at slice granularity against object granularity, and
//! a ray that hits a culled triangle stops the run.
//!
//! ```text
//! cargo run --release --example street_cells -- scenes/city.obj 20 4
//! cargo run --release --example street_cells -- scenes/office.obj 20 3 --height 2 --rooms --rays 100000
//! ```

use std::process::ExitCode;

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::geom::Aabb;
use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
use vis5d::random::{uniform_direction, uniform_point};
use vis5d::sample::SEGMENT_SLACK;
use vis5d::scene::Scene;
use vis5d::shrink::{ShrinkOracle, ShrinkParams};
use vis5d::slices::SlicedScene;
use vis5d::trace::{Ray, Tracer};

const USAGE: &str = "usage: street_cells MODEL CELLS SIZE [--height H] [--rooms] [--anywhere] [--rays N] [--aimed N] [--split K]\n  [--seed S] [--gpu] [--list] [--method extended|shrink|both] [--slices N]\n  [--sweep-planes N] [--sweep-patches N] [--sweep-reach N] [--sweep-extension X]\n  [--occludee-depth N] [--shaft-budget N] [--shaft-depth N] [--seal-voxels N]\n  [--resolution N] [--planes-per-face N] [--plane-candidates N] [--max-occluders N]";

/// The command line.
struct Args {
    model: String,
    cells: usize,
    size: f32,
    height: f32,
    rooms: bool,
    anywhere: bool,
    rays: usize,
    aimed: usize,
    split: usize,
    seed: u64,
    gpu: bool,
    list: bool,
    params: OracleParams,
    method: String,
    slices: usize,
}

fn parse() -> Result<Args, String> {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    let mut positional = Vec::new();
    let mut args = Args {
        model: String::new(),
        cells: 0,
        size: 0.0,
        height: 1.0,
        rooms: false,
        anywhere: false,
        rays: 200_000,
        aimed: 0,
        split: 1,
        seed: 7,
        gpu: false,
        list: false,
        params: OracleParams::default(),
        method: "extended".into(),
        slices: 0,
    };
    let mut it = raw.into_iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            "--height" => {
                args.height = value("--height")?
                    .parse()
                    .map_err(|_| "--height must be a length")?
            }
            "--rays" => {
                args.rays = value("--rays")?
                    .parse()
                    .map_err(|_| "--rays must be a count")?
            }
            "--aimed" => {
                args.aimed = value("--aimed")?
                    .parse()
                    .map_err(|_| "--aimed must be a count")?
            }
            "--split" => {
                args.split = value("--split")?
                    .parse()
                    .map_err(|_| "--split must be a count")?
            }
            "--seed" => {
                args.seed = value("--seed")?
                    .parse()
                    .map_err(|_| "--seed must be a number")?
            }
            "--sweep-planes" => {
                args.params.sweep_planes = value("--sweep-planes")?
                    .parse()
                    .map_err(|_| "--sweep-planes must be a count")?
            }
            "--sweep-patches" => {
                args.params.sweep_patches = value("--sweep-patches")?
                    .parse()
                    .map_err(|_| "--sweep-patches must be a count")?
            }
            "--sweep-reach" => {
                args.params.sweep_reach = value("--sweep-reach")?
                    .parse()
                    .map_err(|_| "--sweep-reach must be a count")?
            }
            "--sweep-extension" => {
                args.params.sweep_extension = value("--sweep-extension")?
                    .parse()
                    .map_err(|_| "--sweep-extension must be a number")?
            }
            "--occludee-depth" => {
                args.params.occludee_depth = value("--occludee-depth")?
                    .parse()
                    .map_err(|_| "--occludee-depth must be a count")?
            }
            "--shaft-budget" => {
                args.params.shaft_budget = value("--shaft-budget")?
                    .parse()
                    .map_err(|_| "--shaft-budget must be a count")?
            }
            "--resolution" => {
                args.params.resolution = value("--resolution")?
                    .parse()
                    .map_err(|_| "--resolution must be a count")?
            }
            "--planes-per-face" => {
                args.params.planes_per_face = value("--planes-per-face")?
                    .parse()
                    .map_err(|_| "--planes-per-face must be a count")?
            }
            "--plane-candidates" => {
                args.params.plane_candidates = value("--plane-candidates")?
                    .parse()
                    .map_err(|_| "--plane-candidates must be a count")?
            }
            "--max-occluders" => {
                args.params.max_occluders = value("--max-occluders")?
                    .parse()
                    .map_err(|_| "--max-occluders must be a count")?
            }
            "--shaft-depth" => {
                args.params.shaft_depth = value("--shaft-depth")?
                    .parse()
                    .map_err(|_| "--shaft-depth must be a count")?
            }
            "--seal-voxels" => {
                args.params.seal_voxels = value("--seal-voxels")?
                    .parse()
                    .map_err(|_| "--seal-voxels must be a count")?
            }
            "--method" => {
                args.method = value("--method")?;
                if !["extended", "shrink", "both"].contains(&args.method.as_str()) {
                    return Err("--method must be extended, shrink or both".into());
                }
            }
            "--slices" => {
                args.slices = value("--slices")?
                    .parse()
                    .map_err(|_| "--slices must be a count")?
            }
            "--rooms" => args.rooms = true,
            "--anywhere" => args.anywhere = true,
            "--gpu" => args.gpu = true,
            "--list" => args.list = true,
            _ => positional.push(a),
        }
    }
    let [model, cells, size] = positional.try_into().map_err(|_| USAGE.to_string())?;
    args.model = model;
    args.cells = cells.parse().map_err(|_| "CELLS must be a count")?;
    args.size = size.parse().map_err(|_| "SIZE must be a length")?;
    if !(args.size > 0.0 && args.height > 0.0) {
        return Err("SIZE and --height must be positive".into());
    }
    Ok(args)
}

/// Whether some triangle of the scene meets `cell` (a vertex inside it, or
/// an edge of the cell or a diagonal crossing a triangle).
fn holds_geometry(scene: &Scene, tracer: &Tracer, cell: &Aabb) -> bool {
    let inside = |p: Vec3| p.cmpge(cell.min).all() && p.cmple(cell.max).all();
    if scene.triangles().iter().flatten().any(|&p| inside(p)) {
        return true;
    }
    let c: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { cell.min.x } else { cell.max.x },
                if i & 2 == 0 { cell.min.y } else { cell.max.y },
                if i & 4 == 0 { cell.min.z } else { cell.max.z },
            )
        })
        .collect();
    let mut segments = Vec::new();
    for i in 0..8 {
        for j in i + 1..8 {
            segments.push(Ray::segment(c[i], c[j]));
        }
    }
    segments.iter().any(|s| tracer.closest_hit(s).is_some())
}

/// A random cell of the kind asked for, or `None` when this try found no
/// place.
fn pick_cell(scene: &Scene, tracer: &Tracer, args: &Args, rng: &mut Pcg64) -> Option<Aabb> {
    let bounds = scene.bounds();
    let x = bounds.min.x + rng.random::<f32>() * (bounds.max.x - bounds.min.x);
    let y = bounds.min.y + rng.random::<f32>() * (bounds.max.y - bounds.min.y);
    let (s, h) = (args.size, args.height);
    if args.anywhere {
        let z = bounds.min.z + rng.random::<f32>() * (bounds.max.z - bounds.min.z);
        let c = Vec3::new(x, y, z);
        let half = 0.5 * Vec3::new(s, s, h);
        return Some(Aabb::new(c - half, c + half));
    }
    if !args.rooms {
        let top = Vec3::new(x, y, bounds.max.z + 10.0);
        let hit = tracer.closest_hit(&Ray::new(top, -Vec3::Z))?;
        let name = scene.objects()[hit.object as usize].name.to_lowercase();
        if !(name.contains("ground") || name.contains("terrain")) {
            return None;
        }
        let z = top.z - hit.t + 1.0;
        return Some(Aabb::new(
            Vec3::new(x, y, z),
            Vec3::new(x + s, y + s, z + h),
        ));
    }
    let z = bounds.min.z + rng.random::<f32>() * (bounds.max.z - bounds.min.z);
    let start = Vec3::new(x, y, z);
    let floor = tracer.closest_hit(&Ray::new(start, -Vec3::Z))?;
    let [a, b, c] = scene.triangles()[floor.triangle as usize];
    let normal = (b - a).cross(c - a).normalize_or_zero();
    if normal.z.abs() < 0.9 {
        return None;
    }
    let z = start.z - floor.t + 0.3;
    let ceiling = tracer.closest_hit(&Ray::new(Vec3::new(x, y, z), Vec3::Z))?;
    if ceiling.t < h + 0.2 {
        return None;
    }
    let cell = Aabb::new(
        Vec3::new(x - 0.5 * s, y - 0.5 * s, z),
        Vec3::new(x + 0.5 * s, y + 0.5 * s, z + h),
    );
    (!holds_geometry(scene, tracer, &cell)).then_some(cell)
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("error: {e}\n{USAGE}");
            return ExitCode::FAILURE;
        }
    };
    let scene = match vis5d::scene::load(&args.model) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let tracer = Tracer::new(&scene);
    let rasteriser = if args.gpu {
        Rasteriser::best()
    } else {
        Rasteriser::cpu()
    };
    let oracle = match Oracle::new(&scene, args.params.clone(), rasteriser) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    // The shrinking's cube maps on the GPU too with --gpu.
    let shrink_rasteriser = if args.gpu {
        Rasteriser::best()
    } else {
        Rasteriser::cpu()
    };
    let shrink =
        match ShrinkOracle::with_rasteriser(&scene, ShrinkParams::default(), shrink_rasteriser) {
            Ok(o) => o,
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        };
    let sliced = if args.slices > 0 {
        match SlicedScene::new(&scene, args.slices) {
            Ok(s) => Some(s),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    } else {
        None
    };
    let mut slice_triangles_culled = 0.0;
    let triangles: usize = scene.objects().iter().map(|o| o.triangle_count()).sum();
    // Cells from one stream, rays from another: the same cells whatever
    // the ray counts.
    let mut cells_rng = Pcg64::seed_from_u64(args.seed);
    let mut rng = Pcg64::seed_from_u64(args.seed ^ 0x5eed_7a75);
    let (mut done, mut tries) = (0, 0);
    let (mut objects_culled, mut triangles_culled, mut truth, mut kept, mut seconds) =
        (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut ratios, mut proofs) = (0.0, 0.0);
    let (mut truth_aimed, mut ratios_aimed) = (0.0, 0.0);
    let mut stages = [0.0f64; 3];
    let kind = if args.anywhere {
        "random"
    } else if args.rooms {
        "room"
    } else {
        "street"
    };
    while done < args.cells {
        tries += 1;
        if tries > 10_000 * args.cells.max(1) {
            eprintln!("error: found no place for a {kind} cell");
            return ExitCode::FAILURE;
        }
        let Some(cell) = pick_cell(&scene, &tracer, &args, &mut cells_rng) else {
            continue;
        };
        let mut report = if args.method == "shrink" {
            // Only the shrinking's set and times, below.
            let mut r = oracle.cell(&Aabb::new(Vec3::NAN, Vec3::NAN), None);
            r.times = Default::default();
            r
        } else if let Some(sl) = &sliced {
            oracle.cell_slices(&cell, None, sl)
        } else {
            oracle.cell(&cell, None)
        };
        let mut slices = std::mem::take(&mut report.slices);
        if args.method != "extended" {
            let s = match &sliced {
                Some(sl) => shrink.cell_slices(&cell, sl),
                None => shrink.cell(&cell),
            };
            vis5d::slices::keep_the_larger(&mut slices, s.slices);
            if args.method == "shrink" {
                report.visible = s.visible;
            } else {
                report.visible.intersect_with(&s.visible);
            }
            report.times.select += s.times.shrink;
            report.times.rasterise += s.times.rasterise;
            report.times.test += s.times.test;
        }
        if args.split > 1 {
            let mut hidden = vis5d::bitset::ObjectSet::full(scene.objects().len());
            hidden.subtract(&report.visible);
            let k = args.split;
            let step = (cell.max - cell.min) / Vec3::new(k as f32, k as f32, 1.0);
            let mut union = vis5d::bitset::ObjectSet::new(scene.objects().len());
            for i in 0..k {
                for j in 0..k {
                    let lo = cell.min + step * Vec3::new(i as f32, j as f32, 0.0);
                    // The last sub-cell of a row ends on the cell's side.
                    let hi = Vec3::new(
                        if i + 1 == k {
                            cell.max.x
                        } else {
                            lo.x + step.x
                        },
                        if j + 1 == k {
                            cell.max.y
                        } else {
                            lo.y + step.y
                        },
                        cell.max.z,
                    );
                    let sub = oracle.cell(&Aabb::new(lo, hi), Some(&hidden));
                    union.union_with(&sub.visible);
                    report.times.select += sub.times.select;
                    report.times.rasterise += sub.times.rasterise;
                    report.times.test += sub.times.test;
                }
            }
            report.visible = union;
        }
        let visible_triangles: usize = report
            .visible
            .iter()
            .map(|o| scene.objects()[o].triangle_count())
            .sum();
        let rays: Vec<Ray> = (0..args.rays)
            .map(|_| Ray::new(uniform_point(&mut rng, &cell), uniform_direction(&mut rng)))
            .collect();
        let mut seen = vis5d::bitset::ObjectSet::new(scene.objects().len());
        for h in tracer.closest_hits(&rays).into_iter().flatten() {
            seen.insert(h.object as usize);
            let o = h.object as usize;
            if let (Some(sl), Some(Some(hidden))) = (&sliced, slices.get(o)) {
                let t = (h.triangle - scene.objects()[o].triangles.start) as usize;
                if sl.culled(o, t, hidden) {
                    eprintln!(
                        "error: a ray hits a triangle of {} that its slices {hidden:?} cull, from the cell {cell:?}",
                        scene.objects()[o].name
                    );
                    return ExitCode::FAILURE;
                }
            }
        }
        // Triangles drawn at slice granularity: a kept object's, less
        // what its slices cull.
        let slice_culled: usize = report
            .visible
            .iter()
            .filter_map(|o| slices.get(o).and_then(Option::as_ref))
            .map(|h| h.culled())
            .sum();
        if !seen.is_subset(&report.visible) {
            eprintln!("error: the oracle hid an object a ray hits, from the cell {cell:?}");
            return ExitCode::FAILURE;
        }
        // Aimed segments at the objects kept and not yet seen.
        let mut aimed = seen.clone();
        if args.aimed > 0 {
            let targets: Vec<usize> = report
                .visible
                .iter()
                .filter(|&o| !seen.contains(o))
                .collect();
            let mut segments = Vec::with_capacity(targets.len() * args.aimed);
            for &o in &targets {
                for _ in 0..args.aimed {
                    let p = uniform_point(&mut rng, &cell);
                    let q = scene.sample_surface(o, &mut rng);
                    if p != q {
                        segments.push(Ray::segment(p, q).with_tmax(1.0 + SEGMENT_SLACK));
                    }
                }
            }
            for h in tracer.closest_hits(&segments).into_iter().flatten() {
                aimed.insert(h.object as usize);
            }
            if !aimed.is_subset(&report.visible) {
                eprintln!(
                    "error: the oracle hid an object an aimed segment hits, from the cell {cell:?}"
                );
                return ExitCode::FAILURE;
            }
        }
        let n = scene.objects().len() as f64;
        let oc = 1.0 - report.visible.count() as f64 / n;
        let tc = 1.0 - visible_triangles as f64 / triangles as f64;
        let ratio = report.visible.count() as f64 / seen.count().max(1) as f64;
        // Of the objects no ray hit, the share the oracle proved hidden.
        let missed = scene.objects().len() - seen.count();
        let proved = (scene.objects().len() - report.visible.count()) as f64 / missed.max(1) as f64;
        let (lo, hi) = (cell.min, cell.max);
        println!(
            "cell ({:.1}, {:.1}, {:.1})-({:.1}, {:.1}, {:.1}): {} objects kept ({:.1}% culled, {:.1}% of triangles), >= {} seen by rays, {ratio:.2}x, {:.0}% of the rest proved hidden, {:.1} ms{}",
            lo.x,
            lo.y,
            lo.z,
            hi.x,
            hi.y,
            hi.z,
            report.visible.count(),
            100.0 * oc,
            100.0 * tc,
            seen.count(),
            100.0 * proved,
            1e3 * report.times.total().as_secs_f64(),
            if args.aimed > 0 {
                format!("; >= {} seen with aimed segments", aimed.count())
            } else {
                String::new()
            }
        );
        if args.list {
            for o in seen.iter() {
                let object = &scene.objects()[o];
                let (a, b) = (object.bounds.min, object.bounds.max);
                println!(
                    "  seen: {} ({:.2}, {:.2}, {:.2})-({:.2}, {:.2}, {:.2})",
                    object.name, a.x, a.y, a.z, b.x, b.y, b.z
                );
            }
            for o in report.visible.iter().filter(|&o| !seen.contains(o)) {
                let object = &scene.objects()[o];
                let (a, b) = (object.bounds.min, object.bounds.max);
                let how = if aimed.contains(o) {
                    "seen only by aimed segments"
                } else {
                    "not seen"
                };
                println!(
                    "  kept, {how}: {} ({:.2}, {:.2}, {:.2})-({:.2}, {:.2}, {:.2})",
                    object.name, a.x, a.y, a.z, b.x, b.y, b.z
                );
            }
        }
        slice_triangles_culled +=
            1.0 - (visible_triangles - slice_culled) as f64 / triangles as f64;
        objects_culled += oc;
        triangles_culled += tc;
        truth += seen.count() as f64;
        truth_aimed += aimed.count() as f64;
        ratios_aimed += report.visible.count() as f64 / aimed.count().max(1) as f64;
        kept += report.visible.count() as f64;
        seconds += report.times.total().as_secs_f64();
        stages[0] += report.times.select.as_secs_f64();
        stages[1] += report.times.rasterise.as_secs_f64();
        stages[2] += report.times.test.as_secs_f64();
        ratios += ratio;
        proofs += proved;
        done += 1;
    }
    let c = args.cells.max(1) as f64;
    println!(
        "mean over {} {kind} cells of {} x {} x {} m: {:.1}% of objects and {:.1}% of triangles culled; {:.1} objects kept, >= {:.1} seen, {:.2}x, {:.0}% of the rest proved hidden; {:.1} ms per cell (select {:.1}, rasterise {:.1}, test {:.1}){}",
        args.cells,
        args.size,
        args.size,
        args.height,
        100.0 * objects_culled / c,
        100.0 * triangles_culled / c,
        kept / c,
        truth / c,
        ratios / c,
        100.0 * proofs / c,
        1e3 * seconds / c,
        1e3 * stages[0] / c,
        1e3 * stages[1] / c,
        1e3 * stages[2] / c,
        if args.aimed > 0 {
            format!(
                "; with aimed segments >= {:.1} seen, {:.2}x",
                truth_aimed / c,
                ratios_aimed / c
            )
        } else {
            String::new()
        }
    );
    if sliced.is_some() {
        let (o, s) = (triangles_culled / c, slice_triangles_culled / c);
        println!(
            "slices ({} an axis): {:.1}% of triangles culled (objects: {:.1}%): {:.1}% fewer triangles drawn than at object granularity",
            args.slices,
            100.0 * s,
            100.0 * o,
            100.0 * (1.0 - (1.0 - s) / (1.0 - o).max(f64::MIN_POSITIVE))
        );
    }
    ExitCode::SUCCESS
}
