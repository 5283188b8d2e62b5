//! Street-level culling of the oracle, the figure papers/001 reports for a
//! city (about 96% of the geometry culled from street cells).
//!
//! Picks `CELLS` random ground positions of a scene (a vertical ray from
//! above must land first on an object named like "ground" or "terrain"),
//! puts a view cell of `SIZE` x `SIZE` x 1 m there, 1 m above the ground,
//! runs the oracle on the CPU and prints, per cell and on average, the
//! share of objects and triangles proved hidden, a lower bound of the
//! visible set (objects hit by 200,000 random rays from the cell), and the
//! time.
//!
//! ```text
//! cargo run --release --example street_cells -- scenes/city.obj 20 4
//! ```

use std::process::ExitCode;

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::geom::Aabb;
use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
use vis5d::random::{uniform_direction, uniform_point};
use vis5d::trace::{Ray, Tracer};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 4 {
        eprintln!("usage: street_cells MODEL CELLS SIZE");
        return ExitCode::FAILURE;
    }
    let scene = match vis5d::scene::load(&args[1]) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let (Ok(cells), Ok(size)) = (args[2].parse::<usize>(), args[3].parse::<f32>()) else {
        eprintln!("error: CELLS must be a count and SIZE a length");
        return ExitCode::FAILURE;
    };
    let tracer = Tracer::new(&scene);
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::best())
        .expect("default parameters are valid");
    let bounds = scene.bounds();
    let triangles: usize = scene.objects().iter().map(|o| o.triangle_count()).sum();
    let mut rng = Pcg64::seed_from_u64(7);
    let (mut done, mut tries) = (0, 0);
    let (mut objects_culled, mut triangles_culled, mut truth, mut kept, mut seconds) =
        (0.0, 0.0, 0.0, 0.0, 0.0);
    while done < cells {
        tries += 1;
        if tries > 1000 * cells.max(1) {
            eprintln!(
                "error: found no ground to stand on (an object named like \"ground\" or \"terrain\")"
            );
            return ExitCode::FAILURE;
        }
        let x = bounds.min.x + rng.random::<f32>() * (bounds.max.x - bounds.min.x);
        let y = bounds.min.y + rng.random::<f32>() * (bounds.max.y - bounds.min.y);
        let top = Vec3::new(x, y, bounds.max.z + 10.0);
        let Some(hit) = tracer.closest_hit(&Ray::new(top, -Vec3::Z)) else {
            continue;
        };
        let name = scene.objects()[hit.object as usize].name.to_lowercase();
        if !(name.contains("ground") || name.contains("terrain")) {
            continue;
        }
        let z = top.z - hit.t + 1.0;
        let cell = Aabb::new(Vec3::new(x, y, z), Vec3::new(x + size, y + size, z + 1.0));
        let report = oracle.cell(&cell, None);
        let visible_triangles: usize = report
            .visible
            .iter()
            .map(|o| scene.objects()[o].triangle_count())
            .sum();
        let rays: Vec<Ray> = (0..200_000)
            .map(|_| Ray::new(uniform_point(&mut rng, &cell), uniform_direction(&mut rng)))
            .collect();
        let mut seen = vis5d::bitset::ObjectSet::new(scene.objects().len());
        for h in tracer.closest_hits(&rays).into_iter().flatten() {
            seen.insert(h.object as usize);
        }
        assert!(
            seen.is_subset(&report.visible),
            "the oracle hid an object a ray hits"
        );
        let n = scene.objects().len() as f64;
        let oc = 1.0 - report.visible.count() as f64 / n;
        let tc = 1.0 - visible_triangles as f64 / triangles as f64;
        println!(
            "cell at ({x:.1}, {y:.1}, {z:.1}): {} objects kept ({:.1}% culled, {:.1}% of triangles), >= {} seen by rays, {:.1} ms",
            report.visible.count(),
            100.0 * oc,
            100.0 * tc,
            seen.count(),
            1e3 * report.times.total().as_secs_f64()
        );
        objects_culled += oc;
        triangles_culled += tc;
        truth += seen.count() as f64;
        kept += report.visible.count() as f64;
        seconds += report.times.total().as_secs_f64();
        done += 1;
    }
    let c = cells.max(1) as f64;
    println!(
        "mean over {cells} street cells of {size} x {size} x 1 m: {:.1}% of objects and {:.1}% of triangles culled; {:.1} objects kept, >= {:.1} seen; {:.1} ms per cell",
        100.0 * objects_culled / c,
        100.0 * triangles_culled / c,
        kept / c,
        truth / c,
        1e3 * seconds / c
    );
    ExitCode::SUCCESS
}
