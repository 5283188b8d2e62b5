//! The extended-projection oracle is never wrong: no object that a ray
//! from the cell hits first is declared hidden (issue 5, "Never wrong").

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::geom::Aabb;
use vis5d::oracle::{Oracle, OracleParams};
use vis5d::scene::{self, Scene};
use vis5d::trace::{Ray, Tracer};

use crate::committed;

/// Uniform direction on the sphere.
fn direction(rng: &mut Pcg64) -> Vec3 {
    let z: f32 = rng.random_range(-1.0..1.0);
    let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * a.cos(), r * a.sin(), z)
}

/// Casts `rays` random rays from random points of `cell` and returns the
/// objects hit first that the oracle calls hidden, with a witness ray.
fn violations(
    oracle: &Oracle,
    tracer: &Tracer,
    cell: &Aabb,
    rays: usize,
    rng: &mut Pcg64,
) -> Vec<(usize, Ray)> {
    let report = oracle.cell(cell, None);
    let batch: Vec<Ray> = (0..rays)
        .map(|_| {
            let t = Vec3::new(rng.random(), rng.random(), rng.random());
            Ray::new(cell.min + (cell.max - cell.min) * t, direction(rng))
        })
        .collect();
    let hits = tracer.closest_hits(&batch);
    let mut out = Vec::new();
    for (ray, hit) in batch.iter().zip(&hits) {
        if let Some(h) = hit
            && !report.visible.contains(h.object as usize)
            && !out.iter().any(|(o, _)| *o == h.object as usize)
        {
            out.push((h.object as usize, *ray));
        }
    }
    out
}

/// The cells of the property test for one scene: random boxes of many
/// sizes inside the scene, tiny ones, huge ones, ones outside the scene,
/// and ones centred on object surfaces (touching or crossing geometry).
fn cells(scene: &Scene, rng: &mut Pcg64) -> Vec<(String, Aabb)> {
    let b = scene.bounds();
    let size = b.size();
    let at = |rng: &mut Pcg64| b.min + size * Vec3::new(rng.random(), rng.random(), rng.random());
    let mut out = Vec::new();
    for k in 0..4 {
        let c = at(rng);
        let half = size * rng.random_range(0.005..0.08);
        out.push((format!("random {k}"), Aabb::new(c - half, c + half)));
    }
    let c = at(rng);
    out.push(("tiny".into(), Aabb::new(c, c + Vec3::splat(1e-3))));
    out.push(("point".into(), Aabb::new(c, c)));
    out.push(("huge".into(), Aabb::new(b.min - size, b.max + size)));
    out.push((
        "outside".into(),
        Aabb::new(b.max + size * 0.2, b.max + size * 0.3),
    ));
    let object = rng.random_range(0..scene.objects().len());
    let p = scene.sample_surface(object, rng);
    out.push((
        "on a surface".into(),
        Aabb::new(p - size * 0.01, p + size * 0.01),
    ));
    let p = scene.sample_surface(rng.random_range(0..scene.objects().len()), rng);
    out.push(("touching a surface".into(), Aabb::new(p, p + size * 0.02)));
    out
}

fn check_scene(name: &str, rays: usize) {
    let scene = scene::load(committed(name)).expect("committed scene loads");
    let tracer = Tracer::new(&scene);
    let oracle = Oracle::new(&scene, OracleParams::default()).expect("default parameters");
    let mut rng = Pcg64::seed_from_u64(0x0ac1e);
    let mut culled = Vec::new();
    for (label, cell) in cells(&scene, &mut rng) {
        let found = violations(&oracle, &tracer, &cell, rays, &mut rng);
        let report = oracle.cell(&cell, None);
        culled.push((
            label.clone(),
            scene.objects().len() - report.visible.count(),
        ));
        assert!(
            found.is_empty(),
            "{name}, cell {label} {cell:?}: the oracle hid objects that rays hit: {:?}",
            found
                .iter()
                .map(|(o, r)| format!("{} by {r:?}", scene.objects()[*o].name))
                .collect::<Vec<_>>()
        );
    }
    eprintln!("{name}: objects culled per cell: {culled:?}");
}

#[test]
fn never_wrong_on_apartment() {
    check_scene("apartment.obj", 100_000);
}

#[test]
fn never_wrong_on_office() {
    check_scene("office.obj", 100_000);
}

#[test]
fn never_wrong_on_city() {
    check_scene("city.obj", 100_000);
}

#[test]
fn never_wrong_on_forest() {
    check_scene("forest.obj", 100_000);
}

#[test]
fn never_wrong_on_machine() {
    check_scene("machine.obj", 100_000);
}

/// The GPU rasteriser, or `None` (skip) without an adapter, unless
/// `VIS5D_REQUIRE_GPU` is set (CI sets it: there the GPU path must run).
fn gpu() -> Option<vis5d::oracle::oracle_gpu::GpuRasteriser> {
    match vis5d::oracle::oracle_gpu::GpuRasteriser::new() {
        Ok(g) => Some(g),
        Err(e) => {
            assert!(
                std::env::var_os("VIS5D_REQUIRE_GPU").is_none(),
                "VIS5D_REQUIRE_GPU is set but there is no GPU adapter: {e}"
            );
            eprintln!("skipping the GPU oracle test: {e}");
            None
        }
    }
}

/// On the GPU the oracle is never wrong either, and hides a subset of what
/// the CPU hides (the GPU fills a subset of the pixels, with margins
/// against the hardware's rounding), nearly all of it.
#[test]
fn the_gpu_oracle_is_never_wrong_and_close_to_the_cpu() {
    let Some(gpu) = gpu() else { return };
    for name in ["city.obj", "office.obj"] {
        let scene = scene::load(committed(name)).expect("committed scene loads");
        let tracer = Tracer::new(&scene);
        let oracle = Oracle::new(&scene, OracleParams::default()).expect("default parameters");
        let mut rng = Pcg64::seed_from_u64(0x69f0);
        let (mut cpu_hidden, mut gpu_hidden) = (0, 0);
        for (label, cell) in cells(&scene, &mut rng) {
            let cpu = oracle.cell(&cell, None);
            let on_gpu = oracle.cell_with(&cell, None, &mut |n, occ| {
                gpu.rasterise(n, occ).expect("the GPU rasterises")
            });
            assert!(
                cpu.visible.is_subset(&on_gpu.visible),
                "{name}, {label}: the GPU hid what the CPU keeps"
            );
            cpu_hidden += scene.objects().len() - cpu.visible.count();
            gpu_hidden += scene.objects().len() - on_gpu.visible.count();
            let rays: Vec<Ray> = (0..100_000)
                .map(|_| {
                    let t = Vec3::new(rng.random(), rng.random(), rng.random());
                    Ray::new(cell.min + (cell.max - cell.min) * t, direction(&mut rng))
                })
                .collect();
            for (ray, hit) in rays.iter().zip(tracer.closest_hits(&rays)) {
                if let Some(h) = hit {
                    assert!(
                        on_gpu.visible.contains(h.object as usize),
                        "{name}, {label}: the GPU oracle hid {} which {ray:?} hits",
                        scene.objects()[h.object as usize].name
                    );
                }
            }
        }
        eprintln!("{name}: hidden objects over the cells: CPU {cpu_hidden}, GPU {gpu_hidden}");
        assert!(
            gpu_hidden as f64 >= 0.9 * cpu_hidden as f64,
            "{name}: CPU {cpu_hidden}, GPU {gpu_hidden}"
        );
    }
}

fn vis5d(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_vis5d"))
        .args(args)
        .current_dir(crate::root())
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn oracle_command_reports_and_refuses_bad_input() {
    let out = vis5d(&[
        "oracle",
        "scenes/apartment.obj",
        "--cell",
        "2,2,1,2.5,2.5,1.5",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let visible = j["potentially_visible"].as_array().unwrap().len();
    assert_eq!(visible + j["hidden"].as_u64().unwrap() as usize, 174);
    assert!(j["hidden"].as_u64().unwrap() > 10, "{j}");
    assert!(!j["planes"].as_array().unwrap().is_empty());
    let out = vis5d(&[
        "oracle",
        "scenes/apartment.obj",
        "--cell",
        "2,2,1,2.5,2.5,1.5",
    ]);
    assert!(
        text(&out.stdout).contains("potentially visible"),
        "{}",
        text(&out.stdout)
    );
    for (args, message) in [
        (
            vec!["oracle", "scenes/apartment.obj", "--cell", "1,2,3"],
            "expected 6 numbers",
        ),
        (
            vec!["oracle", "scenes/apartment.obj", "--cell", "2,2,2,1,1,1"],
            "x0 < x1",
        ),
        (
            vec![
                "oracle",
                "scenes/apartment.obj",
                "--cell",
                "0,0,0,1,1,1",
                "--resolution",
                "100",
            ],
            "power of two",
        ),
        (
            vec!["oracle", "nope.obj", "--cell", "0,0,0,1,1,1"],
            "nope.obj",
        ),
    ] {
        let out = vis5d(&args);
        assert!(!out.status.success(), "{args:?}");
        assert!(
            text(&out.stderr).contains(message),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
}

#[test]
fn check_finds_no_violations_and_catches_a_lying_oracle() {
    let dir = tempfile::tempdir().unwrap();
    let v5d = dir.path().join("machine.v5d");
    let out = vis5d(&[
        "build",
        "scenes/machine.obj",
        "--max-depth",
        "6",
        "-o",
        v5d.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = vis5d(&[
        "check",
        "scenes/machine.obj",
        v5d.to_str().unwrap(),
        "--sample",
        "12",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["violations"], 0, "{j}");
    assert_eq!(j["leaves_checked"], 12);
    assert_eq!(j["leaves"].as_array().unwrap().len(), 12);
    for l in j["leaves"].as_array().unwrap() {
        // The oracle's set holds the ground truth's (no violation).
        assert!(l["oracle"].as_u64() >= l["truth"].as_u64(), "{l}");
    }
    // Another scene's tree is refused.
    let out = vis5d(&["check", "scenes/apartment.obj", v5d.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("another scene"),
        "{}",
        text(&out.stderr)
    );

    // An oracle that hides everything is caught, with witnesses.
    let scene = scene::load(committed("machine.obj")).unwrap();
    let bytes = std::fs::read(&v5d).unwrap();
    let file = vis5d::codec::read_file(&bytes, vis5d::codec::ReadLimits::default()).unwrap();
    let tracer = Tracer::new(&scene);
    let oracle = Oracle::new(&scene, OracleParams::default()).unwrap();
    let params = vis5d::oracle::oracle_check::CheckParams {
        sample: Some(5),
        burst: 200,
        truth_rays: 512,
        seed: 3,
    };
    let objects = scene.objects().len();
    let mut lying =
        |_: &Aabb, _: Option<&vis5d::bitset::ObjectSet>| vis5d::bitset::ObjectSet::new(objects);
    let report = vis5d::oracle::oracle_check::check(
        &oracle,
        &tracer,
        &file.tree,
        &params,
        &mut lying,
        &|_, _, _| {},
    );
    assert_eq!(report.leaves.len(), 5);
    let violations: Vec<_> = report.violations().collect();
    assert!(!violations.is_empty());
    for (leaf, v) in violations {
        // Each witness is a real ray of the leaf that hits the object first.
        let hit = tracer.closest_hit(&v.ray).expect("a witness hits");
        assert_eq!(hit.object, v.object);
        let o = v.ray.origin;
        assert!((0..3).all(|k| o[k] >= leaf.cell.lo[k] && o[k] <= leaf.cell.hi[k]));
    }
}
