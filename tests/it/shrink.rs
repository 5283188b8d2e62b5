//! Occluder shrinking (papers/004) is never wrong: no object that a ray
//! from the cell hits first is declared hidden, on every committed scene,
//! on the property test's cells and on small cells where shrinking proves
//! much; and the same check fails when the solids are shrunk by too
//! little (a mutation it must catch).

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::geom::Aabb;
use vis5d::oracle::Rasteriser;
use vis5d::random::{uniform_direction, uniform_point};
use vis5d::scene::{self, Scene};
use vis5d::shrink::{ShrinkOracle, ShrinkParams};
use vis5d::trace::{Ray, Tracer};

use crate::committed;

/// The objects hit first by `rays` random rays from random points of
/// `cell` that the oracle calls hidden; and how many it hid.
fn violations(
    oracle: &ShrinkOracle,
    tracer: &Tracer,
    cell: &Aabb,
    rays: usize,
    rng: &mut Pcg64,
) -> (Vec<(usize, Ray)>, usize) {
    let report = oracle.cell(cell);
    let batch: Vec<Ray> = (0..rays)
        .map(|_| Ray::new(uniform_point(rng, cell), uniform_direction(rng)))
        .collect();
    let mut out: Vec<(usize, Ray)> = Vec::new();
    for (ray, hit) in batch.iter().zip(tracer.closest_hits(&batch)) {
        if let Some(h) = hit
            && !report.visible.contains(h.object as usize)
            && !out.iter().any(|(o, _)| *o == h.object as usize)
        {
            out.push((h.object as usize, *ray));
        }
    }
    let hidden = report.visible.capacity() - report.visible.count();
    (out, hidden)
}

/// The oracle property test's cells, and small cells (0.2% to 1% of the
/// scene's size) at random points, where shrinking by their half
/// diagonal leaves solids to hide behind.
fn cells(scene: &Scene, rng: &mut Pcg64) -> Vec<(String, Aabb)> {
    let mut out = crate::oracle::cells(scene, rng);
    let b = scene.bounds();
    let size = b.size();
    for k in 0..6 {
        let c = b.min + size * Vec3::new(rng.random(), rng.random(), rng.random());
        let half = Vec3::splat(size.max_element() * rng.random_range(0.001..0.005));
        out.push((format!("small {k}"), Aabb::new(c - half, c + half)));
    }
    out
}

/// Checks every cell of `name` with `rays` rays; returns the objects
/// hidden over all cells and the violations.
fn run(name: &str, params: ShrinkParams, rays: usize) -> (usize, Vec<String>) {
    run_with(name, params, rays, Rasteriser::cpu())
}

/// [`run`] with the cube maps drawn by `rasteriser`.
fn run_with(
    name: &str,
    params: ShrinkParams,
    rays: usize,
    rasteriser: Rasteriser,
) -> (usize, Vec<String>) {
    let scene = scene::load(committed(name)).expect("committed scene loads");
    let tracer = Tracer::new(&scene);
    let gpu = rasteriser.is_gpu();
    let oracle =
        ShrinkOracle::with_rasteriser(&scene, params, rasteriser).expect("valid parameters");
    assert_eq!(oracle.backend().starts_with("GPU"), gpu);
    let mut rng = Pcg64::seed_from_u64(0x5412);
    let (mut hidden, mut bad) = (0, Vec::new());
    for (label, cell) in cells(&scene, &mut rng) {
        let (found, h) = violations(&oracle, &tracer, &cell, rays, &mut rng);
        hidden += h;
        if let (failed @ 1.., first) = oracle.rasteriser().gpu_failures() {
            bad.push(format!("{failed} cube maps failed on the GPU: {first:?}"));
        }
        for (o, r) in found {
            bad.push(format!(
                "{name}, cell {label} {cell:?}: {} hidden but hit by {r:?}",
                scene.objects()[o].name
            ));
        }
    }
    (hidden, bad)
}

fn never_wrong(name: &str) -> usize {
    let (hidden, bad) = run(name, ShrinkParams::default(), 100_000);
    assert!(bad.is_empty(), "{bad:#?}");
    eprintln!("{name}: {hidden} objects hidden over the cells");
    hidden
}

#[test]
fn shrinking_is_never_wrong_on_apartment() {
    never_wrong("apartment.obj");
}

#[test]
fn shrinking_is_never_wrong_on_office() {
    never_wrong("office.obj");
}

#[test]
fn shrinking_is_never_wrong_on_city_and_hides_much_there() {
    // The city's blocks are closed boxes: small cells among them hide most
    // of the town.
    assert!(never_wrong("city.obj") > 300);
}

#[test]
fn shrinking_with_gpu_cube_maps_is_never_wrong_on_city_and_office() {
    for name in ["city.obj", "office.obj"] {
        let rasteriser = Rasteriser::best();
        if let Some(why) = rasteriser.cpu_reason() {
            eprintln!("skipped: {why}");
            return;
        }
        let (hidden, bad) = run_with(name, ShrinkParams::default(), 100_000, rasteriser);
        assert!(bad.is_empty(), "{bad:#?}");
        eprintln!("{name} (GPU cube maps): {hidden} objects hidden over the cells");
    }
}

#[test]
fn shrinking_is_never_wrong_on_forest() {
    never_wrong("forest.obj");
}

#[test]
fn shrinking_is_never_wrong_on_machine() {
    never_wrong("machine.obj");
}

#[test]
fn shrinking_by_too_little_is_caught_by_the_rays() {
    // Shrunk by a twentieth of the cell's half diagonal, the answer is
    // visibility from (near) the centre: rays from the rest of the cell see
    // past the corners of the buildings.
    let params = ShrinkParams {
        erosion_scale: 0.05,
        ..ShrinkParams::default()
    };
    let (hidden, bad) = run("city.obj", params, 100_000);
    assert!(hidden > 0);
    assert!(!bad.is_empty(), "the mutation went unnoticed");
}

#[test]
fn bad_settings_are_refused_by_name() {
    let scene = scene::load(committed("machine.obj")).unwrap();
    for (params, name) in [
        (
            ShrinkParams {
                resolution: 100,
                ..ShrinkParams::default()
            },
            "resolution",
        ),
        (
            ShrinkParams {
                occludee_depth: 0,
                ..ShrinkParams::default()
            },
            "occludee_depth",
        ),
        (
            ShrinkParams {
                erosion_scale: f64::NAN,
                ..ShrinkParams::default()
            },
            "erosion_scale",
        ),
    ] {
        let e = ShrinkOracle::new(&scene, params).err().expect("refused");
        assert!(e.to_string().contains(name), "{e}");
    }
    // A cell that is not a box proves nothing.
    let oracle = ShrinkOracle::new(&scene, ShrinkParams::default()).unwrap();
    let r = oracle.cell(&Aabb::new(Vec3::splat(1.0), Vec3::splat(f32::NAN)));
    assert_eq!(r.visible.count(), scene.objects().len());
}

#[test]
fn oracle_command_runs_the_shrinking_and_refuses_bad_input() {
    use crate::{text, vis5d};
    let cell = "272.8,111,1,273.8,112,2";
    let out = vis5d(&[
        "oracle",
        "scenes/city.obj",
        "--cell",
        cell,
        "--method",
        "shrink",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["method"], "shrink");
    let backend = j["backend"].as_str().unwrap();
    assert!(
        backend == "CPU" || backend.starts_with("GPU: "),
        "{backend}"
    );
    // `--cpu`: the reference.
    let cpu = vis5d(&[
        "oracle",
        "scenes/city.obj",
        "--cell",
        cell,
        "--method",
        "shrink",
        "--cpu",
        "--json",
    ]);
    assert!(cpu.status.success(), "{}", text(&cpu.stderr));
    let c: serde_json::Value = serde_json::from_slice(&cpu.stdout).unwrap();
    assert_eq!(c["backend"], "CPU");
    let visible = j["potentially_visible"].as_array().unwrap().len();
    assert_eq!(visible + j["hidden"].as_u64().unwrap() as usize, 211);
    assert!(j["hidden"].as_u64().unwrap() > 50, "{j}");
    // Half the cell's diagonal, rounded up to the next of 8 steps.
    let e = j["erosion"].as_f64().unwrap();
    assert!((0.866..0.866 * 1.1).contains(&e), "{e}");
    let f = &j["faces"];
    assert_eq!(
        f["input"].as_u64(),
        [
            f["degenerate"].as_u64(),
            f["swept"].as_u64(),
            f["unsafe"].as_u64(),
            f["kept"].as_u64()
        ]
        .iter()
        .map(|x| x.unwrap())
        .sum::<u64>()
        .into()
    );
    // The same cell, rays from it: everything they hit is kept.
    let scene = scene::load(committed("city.obj")).unwrap();
    let names: Vec<&str> = j["potentially_visible"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(9);
    let b = Aabb::new(Vec3::new(272.8, 111.0, 1.0), Vec3::new(273.8, 112.0, 2.0));
    let rays: Vec<Ray> = (0..20_000)
        .map(|_| Ray::new(uniform_point(&mut rng, &b), uniform_direction(&mut rng)))
        .collect();
    for h in tracer.closest_hits(&rays).into_iter().flatten() {
        let name = scene.objects()[h.object as usize].name.as_str();
        assert!(names.contains(&name), "{name} hit but not kept");
    }
    // Text output.
    let out = vis5d(&[
        "oracle",
        "scenes/city.obj",
        "--cell",
        cell,
        "--method",
        "shrink",
    ]);
    let t = text(&out.stdout);
    assert!(
        t.contains("shrunk by") && t.contains("potentially visible"),
        "{t}"
    );
    // Slices, with either method.
    for method in ["extended", "shrink"] {
        let out = vis5d(&[
            "oracle",
            "scenes/city.obj",
            "--cell",
            "272.8,111,1,278.8,117,3",
            "--method",
            method,
            "--slices",
            "16",
            "--json",
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let rows = j["slices"].as_array().unwrap();
        for r in rows {
            assert!(r["culled"].as_u64() <= r["triangles"].as_u64(), "{r}");
            assert!(r["culled"].as_u64().unwrap() > 0, "{r}");
            // The city's objects are of few triangles: one piece each,
            // whose index has something hidden.
            let indices = r["indices"].as_array().unwrap();
            assert_eq!(indices.len(), 1, "{r}");
            assert_ne!(indices[0], serde_json::json!([0, 0, 0]), "{r}");
            let name = r["object"].as_str().unwrap();
            assert!(
                j["potentially_visible"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|n| n == name),
                "{r}: slices only of kept objects"
            );
        }
        if method == "extended" {
            assert!(!rows.is_empty(), "{j}");
        }
    }
    let out = vis5d(&[
        "oracle",
        "scenes/city.obj",
        "--cell",
        cell,
        "--slices",
        "256",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("--slices: invalid slice count 256"),
        "{}",
        text(&out.stderr)
    );
    for (args, message) in [
        (
            vec![
                "oracle",
                "scenes/city.obj",
                "--cell",
                cell,
                "--method",
                "guess",
            ],
            "invalid value 'guess'",
        ),
        (
            vec![
                "oracle",
                "scenes/city.obj",
                "--cell",
                cell,
                "--method",
                "shrink",
                "--resolution",
                "100",
            ],
            "power of two",
        ),
        (
            vec![
                "oracle",
                "scenes/city.obj",
                "--cell",
                "1,1,1,0,0,0",
                "--method",
                "shrink",
            ],
            "x0 < x1",
        ),
    ] {
        let out = vis5d(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(
            text(&out.stderr).contains(message),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
}

#[test]
fn buildings_stay_on_their_floor_and_hide_the_street_behind_from_low_cells() {
    use crate::oracle::{boxed, scene_of};
    // A ground slab, a wide building, a small one behind it and a post in
    // front. The cell's half diagonal (1.73) is more than its centre's
    // height (1.5): shrunk up from the ground, the wide building would
    // float over the eye and hide nothing.
    let scene = scene_of(vec![
        boxed(Vec3::new(-50.0, -50.0, -0.5), Vec3::new(50.0, 50.0, 0.0)),
        boxed(Vec3::new(10.0, -15.0, 0.0), Vec3::new(20.0, 15.0, 12.0)),
        boxed(Vec3::new(25.0, -2.0, 0.0), Vec3::new(28.0, 2.0, 4.0)),
        boxed(Vec3::new(5.0, 6.0, 0.0), Vec3::new(5.5, 6.5, 3.0)),
    ]);
    let oracle = ShrinkOracle::new(&scene, ShrinkParams::default()).unwrap();
    let cell = Aabb::new(Vec3::new(-1.0, -1.0, 0.5), Vec3::new(1.0, 1.0, 2.5));
    let report = oracle.cell(&cell);
    assert!(!report.visible.contains(2), "the small building is hidden");
    assert!(report.visible.contains(1) && report.visible.contains(3));
    // Rays agree: none from the cell reaches it.
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(4);
    for _ in 0..5 {
        let (found, _) = violations(&oracle, &tracer, &cell, 100_000, &mut rng);
        assert!(found.is_empty(), "{found:?}");
    }
    // From 60 m up it shows over the roof.
    let high = Aabb::new(Vec3::new(-1.0, -1.0, 60.0), Vec3::new(1.0, 1.0, 62.0));
    assert!(oracle.cell(&high).visible.contains(2));
}

/// Slices (papers/004 sec. 3) culled by either oracle are never hit by a
/// ray from the cell, on the city's street cells and small cells.
#[test]
fn culled_slices_are_never_hit_by_rays() {
    use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
    use vis5d::slices::SlicedScene;
    for name in ["city.obj", "office.obj"] {
        let scene = scene::load(committed(name)).unwrap();
        let tracer = Tracer::new(&scene);
        let sliced = SlicedScene::new(&scene, 16).unwrap();
        let shrink = ShrinkOracle::new(&scene, ShrinkParams::default()).unwrap();
        let extended = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
        let mut rng = Pcg64::seed_from_u64(0x511ce);
        let (mut culled, mut cells_with_slices) = (0usize, 0);
        for (label, cell) in cells(&scene, &mut rng) {
            let a = shrink.cell_slices(&cell, &sliced).slices;
            let b = extended.cell_slices(&cell, None, &sliced).slices;
            let rays: Vec<Ray> = (0..50_000)
                .map(|_| Ray::new(uniform_point(&mut rng, &cell), uniform_direction(&mut rng)))
                .collect();
            let mut any = false;
            for slices in [&a, &b] {
                for (o, s) in slices.iter().enumerate() {
                    if let Some(h) = s {
                        assert_eq!(h.culled(), sliced.culled_count(o, h));
                        culled += h.culled();
                        any = true;
                    }
                }
            }
            cells_with_slices += usize::from(any);
            for h in tracer.closest_hits(&rays).into_iter().flatten() {
                let o = h.object as usize;
                let t = (h.triangle - scene.objects()[o].triangles.start) as usize;
                for slices in [&a, &b] {
                    if let Some(Some(h)) = slices.get(o) {
                        assert!(
                            !sliced.culled(o, t, h),
                            "{name}, cell {label} {cell:?}: a ray hits triangle {t} of {} in its culled slices {h:?}",
                            scene.objects()[o].name
                        );
                    }
                }
            }
        }
        eprintln!("{name}: {culled} triangles culled by slices in {cells_with_slices} cells");
        assert!(culled > 0, "{name}: no slice culled anything");
    }
}

/// A hilly terrain of many triangles (cut into pieces) with blocks on it:
/// from street cells, the pieces behind the blocks are culled by either
/// oracle's slices, and no ray from the cell hits a culled triangle.
#[test]
fn terrain_pieces_culled_are_never_hit_by_rays() {
    use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
    use vis5d::slices::SlicedScene;
    let height = terrain_height;
    let scene = terrain_town();
    let sliced = SlicedScene::new(&scene, 16).unwrap();
    assert!(sliced.pieces(0).len() > 4, "{}", sliced.pieces(0).len());
    let tracer = Tracer::new(&scene);
    let shrink = ShrinkOracle::new(&scene, ShrinkParams::default()).unwrap();
    let extended = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let mut rng = Pcg64::seed_from_u64(0x7e77a1);
    let mut culled = [0usize; 2];
    for k in 0..6 {
        // A street point: on a street between the blocks, 1-3 m up.
        let along = 1.0 + 24.0 * rng.random_range(0..5) as f32 + rng.random_range(0.0..2.0);
        let across = rng.random_range(6.0..110.0);
        let (x, y) = if k % 2 == 0 {
            (along, across)
        } else {
            (across, along)
        };
        let z = height(x, y) + rng.random_range(1.0..3.0);
        let size = [0.5, 2.0, 4.0][k % 3];
        let cell = Aabb::new(Vec3::new(x, y, z), Vec3::new(x + size, y + size, z + 1.0));
        let answers = [
            extended.cell_slices(&cell, None, &sliced).slices,
            shrink.cell_slices(&cell, &sliced).slices,
        ];
        for (m, slices) in answers.iter().enumerate() {
            if let Some(Some(h)) = slices.first() {
                assert_eq!(h.culled(), sliced.culled_count(0, h));
                culled[m] += h.culled();
            }
        }
        let rays: Vec<Ray> = (0..100_000)
            .map(|_| Ray::new(uniform_point(&mut rng, &cell), uniform_direction(&mut rng)))
            .collect();
        for h in tracer.closest_hits(&rays).into_iter().flatten() {
            let o = h.object as usize;
            let t = (h.triangle - scene.objects()[o].triangles.start) as usize;
            for (m, slices) in answers.iter().enumerate() {
                if let Some(Some(hidden)) = slices.get(o) {
                    assert!(
                        !sliced.culled(o, t, hidden),
                        "method {m}, cell {cell:?}: a ray hits triangle {t} of object {o} in its culled slices {hidden:?}"
                    );
                }
            }
        }
    }
    eprintln!(
        "terrain triangles culled: extended {}, shrink {}",
        culled[0], culled[1]
    );
    // The terrain (8,192 triangles, under every cell) is mostly behind
    // the blocks from the streets.
    assert!(culled[0] > 6 * 2000, "{culled:?}");
}

/// The ground's height in [`terrain_town`].
pub fn terrain_height(x: f32, y: f32) -> f32 {
    2.0 * (x * 0.05).sin() * (y * 0.04).cos()
}

/// A hilly terrain of 64 x 64 squares over 128 x 128 m (8,192 triangles,
/// object 0, cut into 8 pieces) with 5 x 5 blocks on it: 14 m square, 12
/// m tall, sunk 3 m into the ground, streets of 10 m between them.
pub fn terrain_town() -> Scene {
    use crate::oracle::{boxed, scene_of};
    let mut ground = Vec::new();
    for i in 0..64 {
        for j in 0..64 {
            let p = |i: i32, j: i32| {
                let (x, y) = (i as f32 * 2.0, j as f32 * 2.0);
                Vec3::new(x, y, terrain_height(x, y))
            };
            ground.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
            ground.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
        }
    }
    let mut objects = vec![ground];
    for bi in 0..5 {
        for bj in 0..5 {
            let lo = Vec3::new(6.0 + 24.0 * bi as f32, 6.0 + 24.0 * bj as f32, -3.0);
            objects.push(boxed(lo, lo + Vec3::new(14.0, 14.0, 15.0)));
        }
    }
    scene_of(objects)
}
