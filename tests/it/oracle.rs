//! The extended-projection oracle is never wrong: no object that a ray
//! from the cell hits first is declared hidden (issue 5, "Never wrong").

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::geom::Aabb;
use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
use vis5d::random::{uniform_direction, uniform_point};
use vis5d::scene::{self, Scene};
use vis5d::trace::{Ray, Tracer};

use crate::committed;

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
        .map(|_| Ray::new(uniform_point(rng, cell), uniform_direction(rng)))
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
pub fn cells(scene: &Scene, rng: &mut Pcg64) -> Vec<(String, Aabb)> {
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
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu())
        .expect("default parameters");
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

/// The default parameters with the shafts off, so that the occlusion
/// sweep runs in every cell (with the shafts on it runs only where slices
/// are culled): the tests of the maps' paths cover its maps too.
pub fn with_sweep() -> OracleParams {
    OracleParams {
        shaft_budget: 0,
        ..OracleParams::default()
    }
}

/// The GPU rasteriser, or `None` (skip) without an adapter, unless
/// `VIS5D_REQUIRE_GPU` is set (CI sets it: there the GPU path must run).
pub fn gpu() -> Option<vis5d::oracle::GpuRasteriser> {
    match vis5d::oracle::GpuRasteriser::new() {
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
        let oracle =
            Oracle::new(&scene, with_sweep(), Rasteriser::cpu()).expect("valid parameters");
        let mut rng = Pcg64::seed_from_u64(0x69f0);
        let (mut cpu_hidden, mut gpu_hidden) = (0, 0);
        for (label, cell) in cells(&scene, &mut rng) {
            let cpu = oracle.cell(&cell, None);
            let on_gpu = oracle.cell_with(&cell, None, &mut |jobs| {
                gpu.rasterise_many(jobs).expect("the GPU rasterises")
            });
            assert!(
                cpu.visible.is_subset(&on_gpu.visible),
                "{name}, {label}: the GPU hid what the CPU keeps"
            );
            cpu_hidden += scene.objects().len() - cpu.visible.count();
            gpu_hidden += scene.objects().len() - on_gpu.visible.count();
            let rays: Vec<Ray> = (0..100_000)
                .map(|_| Ray::new(uniform_point(&mut rng, &cell), uniform_direction(&mut rng)))
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

use crate::{text, vis5d};

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
    // Negative coordinates need no `=`.
    let out = vis5d(&[
        "oracle",
        "scenes/city.obj",
        "--cell",
        "-5,-5,1,-1,-1,2",
        "--json",
        "--cpu",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
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
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: usage and runtime errors exit with 2"
        );
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
    assert_eq!(out.status.code(), Some(2));
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
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let params = vis5d::oracle::CheckParams {
        sample: Some(5),
        burst: 200,
        truth_rays: 512,
        seed: 3,
    };
    let objects = scene.objects().len();
    let mut lying =
        |_: &Aabb, _: Option<&vis5d::bitset::ObjectSet>| vis5d::bitset::ObjectSet::new(objects);
    let report = vis5d::oracle::check_tree(
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

pub fn scene_of(objects: Vec<Vec<[Vec3; 3]>>) -> Scene {
    let mut b = vis5d::scene::SceneBuilder::new(vis5d::scene::SceneFormat::Procedural);
    for (i, tris) in objects.into_iter().enumerate() {
        b.begin_object(format!("o{i}"));
        for t in tris {
            b.push_triangle(t).unwrap();
        }
    }
    b.finish(std::path::Path::new("review")).unwrap()
}

fn quad_x(x: f32, h: f32) -> Vec<[Vec3; 3]> {
    let p = |y: f32, z: f32| Vec3::new(x, y, z);
    vec![
        [p(-h, -h), p(h, -h), p(h, h)],
        [p(-h, -h), p(h, h), p(-h, h)],
    ]
}

pub fn boxed(min: Vec3, max: Vec3) -> Vec<[Vec3; 3]> {
    let mut t = Vec::new();
    vis5d::scene::procedural::shapes::push_box(&mut t, min, max);
    t
}

/// The counterexamples of a review (2026-11-26), each with its witness
/// ray: the object the tracer hits must not be hidden.
#[test]
fn review_counterexamples_stay_fixed() {
    let cases: Vec<(&str, Scene, Aabb, Ray)> = vec![
        (
            // An occludee one f32 step behind a wall: the tracer's t ties.
            "one ulp behind",
            scene_of(vec![
                quad_x(f32::from_bits(2.0f32.to_bits() + 1), 1.0),
                quad_x(2.0, 128.0),
            ]),
            Aabb::new(Vec3::new(-10.0, -0.5, -0.5), Vec3::new(-9.0, 0.5, 0.5)),
            Ray::new(
                Vec3::new(-9.0, -0.5, 0.024_241_09),
                Vec3::new(11.0, 0.050_789_833, -0.294_044_85),
            ),
        ),
        (
            // An occluder corner 1e-20 in front of the cell's face.
            "corner on the face",
            scene_of(vec![
                vec![[
                    Vec3::new(1e-20, -0.341_830_37, -0.492_479_1),
                    Vec3::new(2.012_819_8, 0.970_323_56, 3.510_507_6),
                    Vec3::new(1.074_579_8, -1.167_902, 7.779_474_3),
                ]],
                boxed(
                    Vec3::new(6.739_907_3, -8.886_976, -0.059_370_995),
                    Vec3::new(7.039_907_5, -8.586_976, 0.240_629_02),
                ),
            ]),
            Aabb::new(Vec3::new(-0.1, -0.1, -0.1), Vec3::new(0.0, 0.1, 0.1)),
            Ray::new(
                Vec3::new(-0.007_632_091_6, 0.1, -0.1),
                Vec3::new(6.965_734_5, -8.692_199, 0.040_629_007),
            ),
        ),
        (
            "sin(pi) from a point cell",
            scene_of(vec![
                vec![[
                    Vec3::new(1.224_646_9e-16, -0.820_254_1, 0.273_308_28),
                    Vec3::new(1.829_406_7, 3.626_968_4, -0.577_61),
                    Vec3::new(2.121_785_6, 2.694_637_3, -3.786_832_8),
                ]],
                boxed(
                    Vec3::new(7.536_247_7, -4.957_026, -9.415_441),
                    Vec3::new(7.836_248, -4.657_026, -9.115_441),
                ),
            ]),
            Aabb::new(Vec3::ZERO, Vec3::ZERO),
            Ray::new(Vec3::ZERO, Vec3::new(7.755_234_2, -4.946_707_7, -9.534_675)),
        ),
        (
            // A ray along a wall's diagonal (the tracer used to leak).
            "shared edge",
            scene_of(vec![
                quad_x(2.0, 128.0),
                boxed(Vec3::new(5.0, -0.3, -0.7), Vec3::new(6.0, 0.9, 0.4)),
            ]),
            Aabb::new(Vec3::new(-10.0, -0.5, -0.5), Vec3::new(-9.0, 0.5, 0.5)),
            Ray::new(Vec3::new(-9.5, -0.3, -0.3), Vec3::X),
        ),
        (
            // A cell's top one f32 step below a floor patch (review of the
            // sweep, stop 25): a ray from the top face slants up through
            // the floor, whose hit t rounds below 0, and reaches the box.
            "a patch one ulp above the face",
            scene_of(vec![
                vec![
                    [
                        Vec3::new(-50.0, -50.0, 1.0),
                        Vec3::new(50.0, -50.0, 1.0),
                        Vec3::new(50.0, 50.0, 1.0),
                    ],
                    [
                        Vec3::new(-50.0, -50.0, 1.0),
                        Vec3::new(50.0, 50.0, 1.0),
                        Vec3::new(-50.0, 50.0, 1.0),
                    ],
                ],
                boxed(Vec3::new(10.0, -1.0, 2.0), Vec3::new(12.0, 1.0, 4.0)),
            ]),
            Aabb::new(
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.999_999_94),
            ),
            Ray::new(
                Vec3::new(-0.768_083_33, 0.801_176_3, 0.999_999_94),
                Vec3::new(11.448_421, -1.627_095_9, 2.075_660_7),
            ),
        ),
    ];
    for (label, scene, cell, ray) in cases {
        let tracer = Tracer::new(&scene);
        let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
        let report = oracle.cell(&cell, None);
        let hit = tracer
            .closest_hit(&ray)
            .expect("the witness hits something");
        assert!(
            report.visible.contains(hit.object as usize),
            "{label}: hid o{} which {ray:?} hits",
            hit.object
        );
        // And random rays from the cell agree too.
        let mut rng = Pcg64::seed_from_u64(11);
        let found = violations(&oracle, &tracer, &cell, 20_000, &mut rng);
        assert!(found.is_empty(), "{label}: {found:?}");
    }
    // A cell that is not a box proves nothing hidden.
    let scene = scene_of(vec![
        quad_x(2.0, 128.0),
        boxed(Vec3::new(5.0, -0.3, -0.7), Vec3::new(6.0, 0.9, 0.4)),
    ]);
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    for cell in [
        Aabb::new(Vec3::new(f32::NAN, -0.5, -0.5), Vec3::new(-9.0, 0.5, 0.5)),
        Aabb::new(Vec3::new(-9.0, -0.5, -0.5), Vec3::new(-10.0, 0.5, 0.5)),
        Aabb::new(Vec3::splat(f32::NEG_INFINITY), Vec3::new(-9.0, 0.5, 0.5)),
    ] {
        assert_eq!(oracle.cell(&cell, None).visible.count(), 2, "{cell:?}");
    }
}

/// The occlusion sweep's patches (issue 13): a slab triangulated around a
/// hole, its seams running right between a cell above it and a box below.
/// The slab's convex pieces part at the seams, so the placed planes alone
/// cannot hide the box; drawn whole as a patch, the slab does. Rays from
/// the cell agree that the box is hidden, and an object under the hole
/// stays visible.
#[test]
fn a_slab_with_a_hole_hides_what_is_under_it_but_not_under_the_hole() {
    let v = |x: f32, y: f32| Vec3::new(x, y, 3.0);
    let outer = [v(0.0, 0.0), v(10.0, 0.0), v(10.0, 10.0), v(0.0, 10.0)];
    let inner = [v(5.0, 5.0), v(7.0, 5.0), v(7.0, 7.0), v(5.0, 7.0)];
    let mut slab = Vec::new();
    for k in 0..4 {
        let n = (k + 1) % 4;
        slab.push([outer[k], outer[n], inner[n]]);
        slab.push([outer[k], inner[n], inner[k]]);
    }
    let scene = scene_of(vec![
        slab,
        boxed(Vec3::new(1.0, 5.0, 0.0), Vec3::new(2.0, 6.0, 1.0)),
        boxed(Vec3::new(5.5, 5.5, 0.0), Vec3::new(6.5, 6.5, 1.0)),
    ]);
    let cell = Aabb::new(Vec3::new(2.0, 2.0, 3.5), Vec3::new(4.0, 4.0, 5.0));
    let off = OracleParams {
        sweep_planes: 0,
        sweep_patches: 0,
        ..OracleParams::default()
    };
    let without = Oracle::new(&scene, off, Rasteriser::cpu()).unwrap();
    let with = Oracle::new(&scene, with_sweep(), Rasteriser::cpu()).unwrap();
    assert!(without.cell(&cell, None).visible.contains(1));
    let report = with.cell(&cell, None);
    assert!(!report.visible.contains(1), "the box under the slab");
    assert!(report.visible.contains(2), "the box under the hole");
    assert!(report.sweep_planes > 0 && report.sweep_hidden >= 1);
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(25);
    assert!(violations(&with, &tracer, &cell, 100_000, &mut rng).is_empty());
    // Some ray aimed from the cell at the box under the hole reaches it.
    let rays: Vec<Ray> = (0..10_000)
        .map(|_| {
            let from = uniform_point(&mut rng, &cell);
            let to = scene.sample_surface(2, &mut rng);
            Ray::new(from, (to - from).normalize())
        })
        .collect();
    assert!(
        tracer
            .closest_hits(&rays)
            .iter()
            .flatten()
            .any(|h| h.object == 2)
    );
}

/// Occludees below object level (issue 13): one object made of two cubes,
/// each behind its own wall, its box spanning the gap between the walls.
/// Whole, it cannot be proved hidden; cluster by cluster it is, and rays
/// agree. A box in the gap stays visible.
#[test]
fn an_object_hidden_in_parts_is_proved_hidden_cluster_by_cluster() {
    let wall = |y0: f32, y1: f32| boxed(Vec3::new(2.0, y0, -3.0), Vec3::new(2.2, y1, 3.0));
    // Each cube's Projection on the walls stays 0.25 m (several pixels)
    // clear of the gap.
    let mut parts = boxed(Vec3::new(5.0, -2.5, -0.25), Vec3::new(5.5, -2.0, 0.25));
    parts.extend(boxed(Vec3::new(5.0, 2.0, -0.25), Vec3::new(5.5, 2.5, 0.25)));
    let scene = scene_of(vec![
        wall(-3.0, -0.5),
        wall(0.5, 3.0),
        parts,
        boxed(Vec3::new(5.0, -0.2, -0.2), Vec3::new(5.4, 0.2, 0.2)),
    ]);
    let cell = Aabb::new(Vec3::new(-1.0, -0.2, -0.2), Vec3::new(-0.5, 0.2, 0.2));
    let whole = OracleParams {
        occludee_depth: 1,
        ..OracleParams::default()
    };
    let without = Oracle::new(&scene, whole, Rasteriser::cpu()).unwrap();
    assert!(without.cell(&cell, None).visible.contains(2));
    let with = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let report = with.cell(&cell, None);
    assert!(!report.visible.contains(2), "the two cubes");
    assert!(report.visible.contains(3), "the box in the gap");
    assert!(report.cluster_hidden >= 1);
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(26);
    assert!(violations(&with, &tracer, &cell, 100_000, &mut rng).is_empty());
}

/// The review's counterexample on a committed scene (stop 25): a cell whose
/// top lies a denormal below the forest's ground, a tree seen through the
/// ground plane's rounding. The witness ray must hit a kept object.
#[test]
fn a_cell_a_hair_below_the_ground_keeps_what_rays_from_it_hit() {
    let scene = scene::load(committed("forest.obj")).expect("committed scene loads");
    let tracer = Tracer::new(&scene);
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let cell = Aabb::new(
        Vec3::new(34.845_783, 51.449_524, -0.260_757_27),
        Vec3::new(35.349_827, 51.953_568, -1e-45),
    );
    let ray = Ray::new(
        Vec3::new(35.349_827, 51.449_524, -1e-45),
        Vec3::new(-23.951_918, -18.347_977, 8.327_698),
    );
    let report = oracle.cell(&cell, None);
    if let Some(hit) = tracer.closest_hit(&ray) {
        assert!(
            report.visible.contains(hit.object as usize),
            "hid {} which {ray:?} hits",
            scene.objects()[hit.object as usize].name
        );
    }
    let mut rng = Pcg64::seed_from_u64(27);
    assert!(violations(&oracle, &tracer, &cell, 50_000, &mut rng).is_empty());
}

/// A cell reaching into a building (a closed convex box) by a whole slab:
/// the slab's viewpoints see only the building and what is inside it, so
/// the projections run from the rest of the cell, and the building,
/// touching that rest, still hides what is behind it. Checked with rays.
#[test]
fn a_cell_reaching_into_a_building_projects_from_the_part_outside() {
    let scene = scene_of(vec![
        // 0: the building, which the cell reaches into from x = 2 to 4.
        boxed(Vec3::new(2.0, -10.0, -1.0), Vec3::new(10.0, 5.5, 10.0)),
        // 1: a box inside the building: seen from the slab inside it.
        boxed(Vec3::new(6.0, 1.0, 1.0), Vec3::new(7.0, 2.0, 2.0)),
        // 2: behind the building.
        boxed(Vec3::new(12.0, 1.0, 0.5), Vec3::new(13.0, 2.0, 1.5)),
        // 3: a wall across the street at y = 6, and 4 behind it, hidden
        // from the cell's part outside the building only.
        boxed(Vec3::new(-1.0, 6.0, -1.0), Vec3::new(3.0, 6.2, 3.0)),
        boxed(Vec3::new(1.0, 8.0, 0.5), Vec3::new(1.8, 8.5, 1.5)),
        // 5: in the street, beside the cell.
        boxed(Vec3::new(-3.0, 1.0, 0.0), Vec3::new(-2.5, 2.0, 1.0)),
    ]);
    let cell = Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 4.0, 2.0));
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let report = oracle.cell(&cell, None);
    assert_eq!(report.inside_solids, 1);
    assert!(report.projected_from.max.x > 2.0 && report.projected_from.max.x < 2.01);
    let visible: Vec<usize> = report.visible.iter().collect();
    assert_eq!(visible, vec![0, 1, 3, 5], "{report:?}");
    // The same as from the part outside alone, where the wall hides 4
    // (from the cell's corners at x = 4, inside the building, a line
    // passes its end).
    let outside = Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.9, 4.0, 2.0));
    assert!(!oracle.cell(&outside, None).visible.contains(4));
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(28);
    let found = violations(&oracle, &tracer, &cell, 200_000, &mut rng);
    assert!(found.is_empty(), "{found:?}");
    // A cell wholly inside the building sees what is inside it only.
    let within = Aabb::new(Vec3::new(3.0, 0.0, 0.0), Vec3::new(5.0, 2.0, 2.0));
    let report = oracle.cell(&within, None);
    assert_eq!(report.visible.iter().collect::<Vec<_>>(), vec![0, 1]);
    assert!(violations(&oracle, &tracer, &within, 50_000, &mut rng).is_empty());
}

/// A review's counterexamples to the first version of the above (stop
/// 28): a cell poking into a solid's corner without a whole slab inside it
/// hid a box inside the solid (the solid, clipped at a plane, was taken to
/// hide it from viewpoints inside it); a cell inside a solid hid a
/// triangle one f32 step beyond the solid's face (a tie at the face).
#[test]
fn what_lies_in_or_on_a_solid_the_cell_reaches_is_kept() {
    let f = f32::from_bits;
    let scene = scene_of(vec![
        boxed(Vec3::splat(2.0), Vec3::splat(10.0)),
        boxed(Vec3::splat(6.0), Vec3::splat(7.0)),
    ]);
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let cell = Aabb::new(Vec3::ZERO, Vec3::new(4.0, 4.0, f(0x40066666)));
    let ray = Ray::new(
        Vec3::new(4.0, f(0x40195c43), f(0x40066666)),
        Vec3::new(f(0x3ee181c6), f(0x3f0ae83c), f(0x3f371ae4)),
    );
    let tracer = Tracer::new(&scene);
    assert_eq!(tracer.closest_hit(&ray).map(|h| h.object), Some(1));
    assert!(oracle.cell(&cell, None).visible.contains(1));
    let beyond = f(0x41200001);
    let scene = scene_of(vec![
        boxed(Vec3::new(2.0, -10.0, -1.0), Vec3::new(10.0, 5.5, 10.0)),
        vec![[
            Vec3::new(beyond, 0.0, 0.0),
            Vec3::new(beyond, 3.0, 0.0),
            Vec3::new(beyond, 0.0, 3.0),
        ]],
    ]);
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let cell = Aabb::new(Vec3::new(3.0, -1.0, 0.0), Vec3::new(5.0, 4.0, 2.0));
    let ray = Ray::new(
        Vec3::new(f(0x4071bd28), f(0x3edd6cb8), f(0x3e349638)),
        Vec3::new(f(0x3f7985a7), f(0x3e64b79d), f(0xbc12b800)),
    );
    let tracer = Tracer::new(&scene);
    if let Some(h) = tracer.closest_hit(&ray) {
        assert!(oracle.cell(&cell, None).visible.contains(h.object as usize));
    }
    assert!(oracle.cell(&cell, None).visible.contains(1));
    let mut rng = Pcg64::seed_from_u64(29);
    assert!(violations(&oracle, &tracer, &cell, 50_000, &mut rng).is_empty());
}

/// A review's counterexamples (stop 28): solids the oracle slices (a
/// floorless box, a closed L-shaped extrusion) were cut on planes from a
/// cell one f32 step short of their walls, and a ray from the cell's
/// corner started past the wall (the tracer's t rounds below 0) and saw
/// the box inside.
#[test]
fn a_cell_a_hair_from_a_sliced_solid_keeps_what_is_inside_it() {
    let f = f32::from_bits;
    let mut floorless = boxed(Vec3::new(20.0, 0.5, 0.0), Vec3::new(30.0, 10.5, 10.0));
    // push_box's two triangles on z = 0 go: the mesh is open at its floor.
    floorless.retain(|t| !t.iter().all(|p| p.z == 0.0));
    let scene = scene_of(vec![
        floorless,
        boxed(Vec3::new(24.0, 4.5, 1.0), Vec3::new(25.0, 5.5, 2.0)),
    ]);
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    assert_eq!(oracle.solid_count(), 2, "both are sliced");
    let cell = Aabb::new(
        Vec3::new(f(0x41b00000), f(0xbf000000), f(0x40400000)),
        Vec3::new(f(0x41d00000), f(0x3effffff), f(0x40e00000)),
    );
    let ray = Ray::new(
        Vec3::new(f(0x41d00000), f(0x3effffff), f(0x40e00000)),
        Vec3::new(f(0xbe4e1d65), f(0x3f26845d), f(0xbf3b7db0)),
    );
    let tracer = Tracer::new(&scene);
    let hit = tracer.closest_hit(&ray).expect("the witness hits");
    assert!(
        oracle
            .cell(&cell, None)
            .visible
            .contains(hit.object as usize)
    );
    let mut rng = Pcg64::seed_from_u64(30);
    assert!(violations(&oracle, &tracer, &cell, 100_000, &mut rng).is_empty());
}

/// Shafts (stop 29): from a room of the committed office, the furniture of
/// the rooms across the corridor is hidden by this room's walls, the
/// corridor walls and the partitions beyond them together; no projection
/// plane holds them all (the partitions stand at right angles to the
/// corridor walls), so the maps alone keep it. One occluder at a time,
/// over parts of the cell and of the object, proves most of it hidden;
/// rays from the cell hit none of it.
#[test]
fn shafts_hide_the_rooms_across_the_corridor() {
    let scene = scene::load(committed("office.obj")).expect("committed scene loads");
    let cell = Aabb::new(Vec3::new(20.8, 7.8, 0.3), Vec3::new(23.8, 10.8, 2.3));
    let maps_only = OracleParams {
        shaft_budget: 0,
        ..OracleParams::default()
    };
    let without = Oracle::new(&scene, maps_only, Rasteriser::cpu()).unwrap();
    let with = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let (before, after) = (without.cell(&cell, None), with.cell(&cell, None));
    assert_eq!(before.shaft_hidden, 0);
    assert!(
        after.shaft_hidden >= 20 && after.visible.count() + 20 <= before.visible.count(),
        "kept {} -> {}, {} by shafts",
        before.visible.count(),
        after.visible.count(),
        after.shaft_hidden
    );
    // What the maps proved stays proved.
    let mut more = after.visible.clone();
    more.subtract(&before.visible);
    assert_eq!(more.count(), 0);
    let desk = scene
        .objects()
        .iter()
        .position(|o| o.name == "south_0/desk_0")
        .expect("the office has its desks");
    assert!(before.visible.contains(desk) && !after.visible.contains(desk));
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(29);
    let found = violations(&with, &tracer, &cell, 200_000, &mut rng);
    assert!(found.is_empty(), "{found:?}");
    // Portals (stop 43): the room diagonally across the corridor could be
    // seen only through both doors, at a slant their positions do not
    // allow; its desk is hidden, and the cell keeps at most twice what
    // 10^5 rays from it see (issue 13's target; 59 kept before portals).
    let across = scene
        .objects()
        .iter()
        .position(|o| o.name == "south_4/desk_0")
        .expect("the office has its desks");
    assert!(!after.visible.contains(across));
    let rays: Vec<Ray> = (0..100_000)
        .map(|_| Ray::new(uniform_point(&mut rng, &cell), uniform_direction(&mut rng)))
        .collect();
    let mut seen = vis5d::bitset::ObjectSet::new(scene.objects().len());
    for h in tracer.closest_hits(&rays).into_iter().flatten() {
        seen.insert(h.object as usize);
    }
    assert!(
        after.visible.count() <= 2 * seen.count(),
        "kept {}, rays see {}",
        after.visible.count(),
        seen.count()
    );
}

/// A room upstairs in the duplex (a BIM export): its party wall's mesh is
/// closed but some triangles are wound the other way, so it is no convex
/// solid and its faces (around a recess) leave a gap in every plane's
/// umbra. Closed modulo two, it is sliced, and its cut hides the room
/// beyond it; rays agree.
#[test]
fn a_wall_wound_both_ways_is_sliced_and_hides_the_room_beyond() {
    let path = crate::shared_scenes().join("apartment_ifc_duplex/duplex_apartment.obj");
    let scene = scene::load(&path).expect("the shared duplex loads");
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    assert!(oracle.solid_count() >= 190, "{}", oracle.solid_count());
    let cell = Aabb::new(Vec3::new(0.9, -15.1, 3.4), Vec3::new(3.9, -12.1, 5.4));
    let report = oracle.cell(&cell, None);
    let index = |prefix: &str| {
        scene
            .objects()
            .iter()
            .position(|o| o.name.starts_with(prefix))
            .unwrap_or_else(|| panic!("the duplex has {prefix}"))
    };
    for beyond in [
        "IfcWallStandardCase_33_",
        "IfcFurnishingElement_66_",
        "IfcDoor_74_",
    ] {
        assert!(!report.visible.contains(index(beyond)), "{beyond} kept");
    }
    assert!(report.visible.contains(index("IfcWall_22_")));
    assert!(report.visible.count() <= 125, "{}", report.visible.count());
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(30);
    let found = violations(&oracle, &tracer, &cell, 200_000, &mut rng);
    assert!(found.is_empty(), "{found:?}");
}

/// A review's counterexamples to the first shafts (stop 29): a triangle
/// seen at a thousandth of a radian, a tiny object just behind it. The
/// crossings lay inside the triangle by a millimetre, but the tracer's
/// rounding moves a grazing ray's crossing along the plane by the rounding
/// over the sine of its angle: rays pass the edge and hit the object.
#[test]
fn grazing_rays_past_a_triangle_keep_what_is_behind_it() {
    let cases: [([Vec3; 3], Vec<[Vec3; 3]>, Vec3); 2] = [
        (
            [
                Vec3::new(2.1926947, -0.37290096, 0.3083964),
                Vec3::new(2.163077, -0.3364323, -4.691383),
                Vec3::new(-0.97020674, 3.5295715, -2.144513),
            ],
            boxed(
                Vec3::new(5.0987544, -3.951188, -2.2360275),
                Vec3::new(5.1007543, -3.9491882, -2.2340276),
            ),
            Vec3::new(-123.93261, 154.92769, -0.3118063),
        ),
        (
            [
                Vec3::new(-2.1684935, 1.1347047, -1.2246826),
                Vec3::new(-1.8650773, 0.30058095, -1.6853081),
                Vec3::new(-1.9406667, 1.2207307, -2.315872),
            ],
            vec![[
                Vec3::new(-2.0387533, 0.56700546, -1.1966841),
                Vec3::new(-2.0387523, 0.56700546, -1.1966841),
                Vec3::new(-2.0387533, 0.56700647, -1.1966836),
            ]],
            Vec3::new(2.3801174, 30.867102, -53.15487),
        ),
    ];
    for (triangle, object, eye) in cases {
        let scene = scene_of(vec![vec![triangle], object]);
        let cell = Aabb::new(eye, eye);
        let tracer = Tracer::new(&scene);
        let mut rng = Pcg64::seed_from_u64(29);
        // Rays from the point to the object's surface do hit it first.
        let seen = (0..10_000).any(|_| {
            let q = scene.sample_surface(1, &mut rng);
            tracer
                .closest_hit(&Ray::new(eye, q - eye))
                .is_some_and(|h| h.object == 1)
        });
        assert!(seen);
        let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
        assert!(oracle.cell(&cell, None).visible.contains(1));
    }
}

/// The same review's case for the Depth Maps (older than the shafts): a
/// triangle seen nearly edge-on from 200 m, a 2 mm box just past it. The
/// exact segments cross the triangle, the tracer's rays pass outside it
/// (the rounding over the sine of the grazing angle): the maps draw each
/// polygon inset by that.
#[test]
fn the_maps_keep_what_grazing_rays_see_past_a_triangle() {
    let triangle = [
        Vec3::new(1.3740398, 7.9293003, 10.031703),
        Vec3::new(1.38339, 7.1812134, -9.954299),
        Vec3::new(1.4285, -12.430685, 0.78680986),
    ];
    let object = boxed(
        Vec3::new(1.3705349, 8.028803, 0.019936096),
        Vec3::new(1.372535, 8.030804, 0.021936096),
    );
    let scene = scene_of(vec![vec![triangle], object]);
    let cell = Aabb::new(
        Vec3::new(3.8770337, -192.48901, 7.527639),
        Vec3::new(3.9770336, -192.389, 7.627639),
    );
    let tracer = Tracer::new(&scene);
    let witness = Ray::new(
        Vec3::new(3.9770336, -192.389, 7.627639),
        Vec3::new(-2.6044986, 200.41982, -7.6077027),
    );
    assert_eq!(tracer.closest_hit(&witness).map(|h| h.object), Some(1));
    for shafts in [0, 512] {
        let params = OracleParams {
            shaft_budget: shafts,
            ..OracleParams::default()
        };
        let oracle = Oracle::new(&scene, params, Rasteriser::cpu()).unwrap();
        assert!(oracle.cell(&cell, None).visible.contains(1));
    }
}

/// A closed prism: the convex polygon `base` (counter-clockwise in x, y)
/// extruded from `z0` to `z1`.
fn prism(base: &[(f32, f32)], z0: f32, z1: f32) -> Vec<[Vec3; 3]> {
    let p = |(x, y): (f32, f32), z: f32| Vec3::new(x, y, z);
    let mut t = Vec::new();
    for k in 1..base.len() - 1 {
        t.push([p(base[0], z0), p(base[k + 1], z0), p(base[k], z0)]);
        t.push([p(base[0], z1), p(base[k], z1), p(base[k + 1], z1)]);
    }
    for k in 0..base.len() {
        let (a, b) = (base[k], base[(k + 1) % base.len()]);
        t.push([p(a, z0), p(b, z0), p(b, z1)]);
        t.push([p(a, z0), p(b, z1), p(a, z1)]);
    }
    t
}

/// A room of separate solids, as BIM models give them: a floor and a
/// ceiling slab, four walls standing between them with mitred corners
/// (each pair shares a slanted face no grid plane follows), a door filling
/// a doorway of the east wall, and a table standing on the floor. Objects
/// `[outside, above, below]` are returned with the scene.
fn walled_room(door: bool) -> (Scene, [usize; 3]) {
    let t = 0.2;
    let (w, h) = (6.0, 3.0);
    let mut objects = vec![
        boxed(Vec3::new(-t, -t, -t), Vec3::new(w + t, w + t, 0.0)),
        boxed(Vec3::new(-t, -t, h), Vec3::new(w + t, w + t, h + t)),
        // South, west and north walls, mitred at their corners.
        prism(&[(-t, -t), (w + t, -t), (w, 0.0), (0.0, 0.0)], 0.0, h),
        prism(&[(-t, w + t), (-t, -t), (0.0, 0.0), (0.0, w)], 0.0, h),
        prism(&[(w + t, w + t), (-t, w + t), (0.0, w), (w, w)], 0.0, h),
        // The east wall in three parts around a doorway from y = 2 to 3,
        // 2 m high.
        prism(&[(w + t, -t), (w + t, 2.0), (w, 2.0), (w, 0.0)], 0.0, h),
        prism(&[(w, 3.0), (w + t, 3.0), (w + t, w + t), (w, w)], 0.0, h),
        boxed(Vec3::new(w, 2.0, 2.0), Vec3::new(w + t, 3.0, h)),
        boxed(Vec3::new(2.0, 2.0, 0.0), Vec3::new(3.0, 3.0, 0.8)),
    ];
    if door {
        objects.push(boxed(Vec3::new(w, 2.0, 0.0), Vec3::new(w + t, 3.0, 2.0)));
    }
    let first = objects.len();
    objects.push(boxed(Vec3::new(10.0, 2.0, 0.5), Vec3::new(11.0, 3.0, 1.5)));
    objects.push(boxed(Vec3::new(2.0, 2.0, 4.0), Vec3::new(3.0, 3.0, 5.0)));
    objects.push(boxed(Vec3::new(2.0, 2.0, -2.0), Vec3::new(3.0, 3.0, -1.0)));
    (scene_of(objects), [first, first + 1, first + 2])
}

/// Sealed rooms (stop 42): from inside the closed room nothing outside
/// is reached by a free path, whatever the maps prove; with the door
/// gone, everything is. Rays agree either way, from the room and from
/// cells reaching into its walls and its floor.
#[test]
fn a_room_of_separate_solids_is_sealed_by_its_door() {
    let room = Aabb::new(Vec3::new(0.5, 0.5, 0.5), Vec3::new(5.5, 5.5, 2.5));
    let (scene, outside) = walled_room(true);
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let report = oracle.cell(&room, None);
    for o in outside {
        assert!(!report.visible.contains(o), "object {o} kept");
    }
    assert_eq!(report.sealed_hidden, 3, "{report:?}");
    assert!(report.visible.contains(8), "the table is seen");
    // A flat polygon is no solid to seal with (it has no inside), and its
    // height does not stop the proofs below it.
    let (sealed, _) = walled_room(true);
    let mut objects: Vec<Vec<[Vec3; 3]>> = (0..sealed.objects().len())
        .map(|o| sealed.object_triangles(o).to_vec())
        .collect();
    objects.push(
        quad_x(30.0, 1.0)
            .into_iter()
            .map(|t| t.map(|v| Vec3::new(v.y + 30.0, v.z, 10.0)))
            .collect(),
    );
    let with_quad = scene_of(objects);
    let quad = Oracle::new(&with_quad, OracleParams::default(), Rasteriser::cpu()).unwrap();
    assert_eq!(quad.cell(&room, None).sealed_hidden, 4);
    let counts = oracle.sealed_counts();
    assert!(counts.voxels > 0 && counts.blocked > 0 && counts.components >= 2);
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(42);
    let cells = [
        room,
        // Into the east wall, the door and the floor.
        Aabb::new(Vec3::new(5.0, 1.5, 0.5), Vec3::new(6.1, 3.5, 1.5)),
        Aabb::new(Vec3::new(1.0, 1.0, -0.1), Vec3::new(2.0, 2.0, 0.5)),
        // A hair inside the mitred corner, and one outside the room.
        Aabb::new(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.01, 0.01, 1.01)),
        Aabb::new(Vec3::new(8.0, 1.0, 0.5), Vec3::new(9.0, 2.0, 1.5)),
    ];
    for cell in cells {
        let found = violations(&oracle, &tracer, &cell, 200_000, &mut rng);
        assert!(found.is_empty(), "{cell:?}: {found:?}");
    }
    // The command says what sealing did, and turns it off.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.obj");
    scene::write_obj_file(&scene, &[], &file).unwrap();
    let cell = "0.5,0.5,0.5,5.5,5.5,2.5";
    let run = |more: &[&str]| -> serde_json::Value {
        let mut args = vec!["oracle", file.to_str().unwrap(), "--cell", cell, "--json"];
        args.extend(more);
        let out = vis5d(&args);
        assert!(out.status.success(), "{}", text(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    assert_eq!(run(&[])["sealed_hidden"], 3);
    assert_eq!(run(&["--seal-voxels", "0"])["sealed_hidden"], 0);
    let out = vis5d(&["oracle", file.to_str().unwrap(), "--cell", cell]);
    assert!(
        text(&out.stdout).contains("sealed: 3 objects"),
        "{}",
        text(&out.stdout)
    );
    let out = vis5d(&[
        "oracle",
        file.to_str().unwrap(),
        "--cell",
        cell,
        "--seal-voxels",
        "-1",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    // Without the door, nothing is sealed off.
    let (open, outside) = walled_room(false);
    let oracle = Oracle::new(&open, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let report = oracle.cell(&room, None);
    assert_eq!(report.sealed_hidden, 0);
    assert!(report.visible.contains(outside[0]), "seen through the door");
    let tracer = Tracer::new(&open);
    let found = violations(&oracle, &tracer, &room, 200_000, &mut rng);
    assert!(found.is_empty(), "{found:?}");
}

/// The duplex's rooms upstairs (stop 42): its walls, slabs, doors and
/// windows are separate solids, mitred at the corners; sealed, a room
/// keeps close to what rays from it see (7.1x before).
#[test]
fn the_duplex_rooms_are_sealed() {
    let path = crate::shared_scenes().join("apartment_ifc_duplex/duplex_apartment.obj");
    let scene = scene::load(&path).expect("the shared duplex loads");
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(42);
    let cell = Aabb::new(Vec3::new(0.9, -15.1, 3.4), Vec3::new(3.9, -12.1, 5.4));
    let report = oracle.cell(&cell, None);
    let batch: Vec<Ray> = (0..100_000)
        .map(|_| Ray::new(uniform_point(&mut rng, &cell), uniform_direction(&mut rng)))
        .collect();
    let mut seen = vis5d::bitset::ObjectSet::new(scene.objects().len());
    for h in tracer.closest_hits(&batch).into_iter().flatten() {
        seen.insert(h.object as usize);
    }
    assert!(seen.is_subset(&report.visible));
    assert!(
        report.visible.count() <= 2 * seen.count(),
        "{} kept, {} seen",
        report.visible.count(),
        seen.count()
    );
    assert!(report.sealed_hidden >= 50, "{}", report.sealed_hidden);
    let found = violations(&oracle, &tracer, &cell, 200_000, &mut rng);
    assert!(found.is_empty(), "{found:?}");
}

/// A review's counterexamples to the first sealed rooms (stop 42), each
/// with its witness ray: the object it hits first must be kept, and
/// random rays from the cell find nothing hidden hit.
#[test]
fn review_counterexamples_to_sealing_stay_fixed() {
    let floorless = |min: Vec3, max: Vec3| {
        let mut t = boxed(min, max);
        t.retain(|t| !t.iter().all(|p| p.z == min.z));
        t
    };
    let f = f32::from_bits;
    let mut cases: Vec<(&str, Scene, Aabb, Ray)> = Vec::new();
    // From inside a solid open at the bottom, rays leave through its
    // floor, which the tracer does not see.
    cases.push((
        "a cell inside a raised shell open at the bottom",
        scene_of(vec![
            floorless(Vec3::new(0.0, 0.0, 1.0), Vec3::new(4.0, 4.0, 3.0)),
            boxed(Vec3::new(1.5, 1.5, -1.0), Vec3::new(2.5, 2.5, 0.0)),
            boxed(Vec3::new(-6.0, -6.0, -2.0), Vec3::new(10.0, 10.0, -1.0)),
        ]),
        Aabb::new(Vec3::new(1.0, 1.0, 2.0), Vec3::new(3.0, 3.0, 2.5)),
        Ray::new(Vec3::new(2.0, 2.0, 2.0), Vec3::new(0.0, 0.0, -1.0)),
    ));
    // The same in an attic: four walls without a ceiling under a gable
    // roof without a bottom face; the table below is seen through it.
    let (w, h, t) = (6.0f32, 3.0f32, 0.2f32);
    let p = Vec3::new;
    let (x0, x1, xm, y0, y1, z0, z1) = (-t, w + t, w / 2.0, -t, w + t, h, h + 2.0);
    cases.push((
        "an attic under a roof open at the bottom",
        scene_of(vec![
            boxed(p(-t, -t, -t), p(w + t, w + t, 0.0)),
            boxed(p(-t, -t, 0.0), p(w + t, 0.0, h)),
            boxed(p(-t, w, 0.0), p(w + t, w + t, h)),
            boxed(p(-t, 0.0, 0.0), p(0.0, w, h)),
            boxed(p(w, 0.0, 0.0), p(w + t, w, h)),
            vec![
                [p(x0, y0, z0), p(xm, y0, z1), p(x1, y0, z0)],
                [p(x0, y1, z0), p(x1, y1, z0), p(xm, y1, z1)],
                [p(x0, y0, z0), p(x0, y1, z0), p(xm, y1, z1)],
                [p(x0, y0, z0), p(xm, y1, z1), p(xm, y0, z1)],
                [p(x1, y0, z0), p(xm, y0, z1), p(xm, y1, z1)],
                [p(x1, y0, z0), p(xm, y1, z1), p(x1, y1, z0)],
            ],
            boxed(p(2.0, 2.0, 0.0), p(3.0, 3.0, 0.8)),
        ]),
        Aabb::new(p(2.0, 1.0, 3.3), p(4.0, 5.0, 3.8)),
        Ray::new(p(2.5, 2.5, 3.5), p(0.0, 0.0, -1.0)),
    ));
    // A wall split into two solids by a slanted slit 2^-30 wide: the two
    // faces are not in one plane, however close (a far box makes the
    // scene big, so a tolerance relative to it would have closed it).
    let (d, g) = (2f32.powi(-20), 2f32.powi(-30));
    cases.push((
        "a slit between two parts of a wall",
        scene_of(vec![
            boxed(p(-6.0, -6.0, -1.0), p(6.0, 6.2, 0.0)),
            boxed(p(-6.0, -6.0, 3.0), p(6.0, 6.2, 4.0)),
            boxed(p(-6.0, -6.0, 0.0), p(-5.0, 6.2, 3.0)),
            boxed(p(5.0, -6.0, 0.0), p(6.0, 6.2, 3.0)),
            boxed(p(-5.0, -6.0, 0.0), p(5.0, -5.0, 3.0)),
            boxed(p(-5.0, 5.2, 0.0), p(5.0, 6.2, 3.0)),
            prism(&[(-5.0, 0.0), (0.0, 0.0), (d, t), (-5.0, t)], 0.0, 3.0),
            prism(&[(g, 0.0), (5.0, 0.0), (5.0, t), (d + g, t)], 0.0, 3.0),
            boxed(p(-0.5, 2.0, 1.0), p(0.5, 3.0, 2.0)),
            boxed(p(900.0, 900.0, 0.0), p(901.0, 901.0, 1.0)),
        ]),
        Aabb::new(p(-1.0, -3.0, 1.0), p(1.0, -0.5, 2.0)),
        Ray::new(
            p(f(0xb6fffc00), f(0xbfcccccd), f(0x3fc00000)),
            p(f(0x35800000), f(0x3e4ccccd), 0.0),
        ),
    ));
    // A second review: under a small budget the grid's top planes went
    // first (ties among the planes never to drop were broken by height),
    // so what stood above the grid's top was reached by nothing.
    let mut raised: Vec<Vec<[Vec3; 3]>> = (0..12)
        .map(|i| {
            let (x, z) = (i as f32, 0.25 * i as f32);
            floorless(p(x, 0.0, z), p(x + 0.5, 0.5, z + 0.25))
        })
        .collect();
    raised.push(boxed(p(2.0, 3.0, 6.0), p(3.0, 4.0, 7.0)));
    cases.push((
        "floors and the grid's top dropped by a small budget",
        scene_of(raised),
        Aabb::new(p(0.0, 2.0, 4.0), p(1.0, 3.0, 4.5)),
        Ray::new(p(0.5, 2.5, 4.25), p(2.0, 1.0, 2.25)),
    ));
    let mut rng = Pcg64::seed_from_u64(42);
    for (k, (name, scene, cell, ray)) in cases.into_iter().enumerate() {
        let params = OracleParams {
            seal_voxels: if k == 3 { 1000 } else { 1 << 24 },
            ..OracleParams::default()
        };
        let oracle = Oracle::new(&scene, params, Rasteriser::cpu()).unwrap();
        let tracer = Tracer::new(&scene);
        let hit = tracer.closest_hit(&ray).expect("the witness hits");
        let report = oracle.cell(&cell, None);
        assert!(
            report.visible.contains(hit.object as usize),
            "{name}: object {} hidden",
            hit.object
        );
        let found = violations(&oracle, &tracer, &cell, 200_000, &mut rng);
        assert!(found.is_empty(), "{name}: {found:?}");
    }
}

/// Asserts that none of `hidden` is hit by `per_object` segments from
/// random points of `cell` to random points of its surface.
fn assert_unseen(
    scene: &Scene,
    tracer: &Tracer,
    cell: &Aabb,
    hidden: &[usize],
    per_object: usize,
    rng: &mut Pcg64,
) {
    for &o in hidden {
        let rays: Vec<Ray> = (0..per_object)
            .map(|_| Ray::segment(uniform_point(rng, cell), scene.sample_surface(o, rng)))
            .collect();
        let hits = tracer.closest_hits(&rays);
        assert!(
            hits.iter().flatten().all(|h| h.object as usize != o),
            "hidden object {o} ({}) seen",
            scene.objects()[o].name
        );
    }
}

/// The grove's crowns are convex shells (leaves overlapping past their
/// neighbours' planes): each hides as a solid, and its cross-sections
/// are cuts for the shafts, so from a half-metre cell on the trail a
/// fifth of the grove is proved hidden (without the shells, a few
/// objects; with them but no cuts, a tenth), and rays, random and aimed
/// at each hidden object, agree.
#[test]
fn the_groves_crowns_hide_as_convex_shells() {
    use vis5d::scene::procedural::{SceneKind, generate};
    let scene = generate(SceneKind::Grove, 1, 1);
    let (x, y) = (10.0f32, 20.0 + 6.0 * (10.0f32 / 7.0).sin());
    let cell = Aabb::new(Vec3::new(x, y, 1.0), Vec3::new(x + 0.5, y + 0.5, 1.5));
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    assert!(oracle.occluder_counts().shells > 200);
    let report = oracle.cell(&cell, None);
    let n = scene.objects().len();
    let hidden: Vec<usize> = (0..n).filter(|&i| !report.visible.contains(i)).collect();
    assert!(hidden.len() >= n / 5, "{} of {n} hidden", hidden.len());
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(45);
    assert!(violations(&oracle, &tracer, &cell, 100_000, &mut rng).is_empty());
    assert_unseen(&scene, &tracer, &cell, &hidden, 300, &mut rng);
}

/// The sweep reaching back (`sweep_reach`): in the grove, whose crowns are
/// closed shells of separate leaf triangles, a small cell on the trail
/// sees few trees, and the leaves fuse only through many thin sweep
/// steps. Each plane also taking the reprojections of the planes 2, 4, 8
/// and 16 back proves more hidden than the chain alone, and rays, random
/// and aimed at every hidden object, agree. The shafts are off: since
/// they test convex shells segment by segment and search deeper (stop
/// 48) they prove all that reaching back adds here (206 hidden either
/// way); without them 96 against 80. Here it hides a superset of what the chain hides, as on every
/// cell measured; that is not certain in general (a plane the chain
/// leaves empty, and skips, then holds reprojections, which shifts which
/// planes are 1, 2, 4, ... back and which two planes an object is tested
/// on).
#[test]
fn the_sweep_reaching_back_fuses_the_groves_crowns() {
    use vis5d::scene::procedural::{SceneKind, generate};
    let scene = generate(SceneKind::Grove, 1, 1);
    // On the trail's middle line (y = 20 + 6 sin(x / 7)), 1 m up.
    let (x, y) = (24.0f32, 20.0 + 6.0 * (24.0f32 / 7.0).sin());
    let cell = Aabb::new(Vec3::new(x, y, 1.0), Vec3::new(x + 0.25, y + 0.25, 1.25));
    let oracle = |reach: usize| {
        let params = OracleParams {
            sweep_planes: 16,
            sweep_reach: reach,
            shaft_budget: 0,
            ..OracleParams::default()
        };
        Oracle::new(&scene, params, Rasteriser::cpu()).unwrap()
    };
    let (chain, reaching) = (oracle(1), oracle(5));
    let (a, b) = (chain.cell(&cell, None), reaching.cell(&cell, None));
    let n = scene.objects().len();
    let hidden =
        |v: &vis5d::bitset::ObjectSet| (0..n).filter(|&i| !v.contains(i)).collect::<Vec<_>>();
    let (ha, hb) = (hidden(&a.visible), hidden(&b.visible));
    assert!(
        ha.iter().all(|i| hb.contains(i)),
        "reaching back lost a proof"
    );
    assert!(
        hb.len() > ha.len() && hb.len() >= n / 5,
        "{} hidden reaching back, {} by the chain, of {n}",
        hb.len(),
        ha.len()
    );
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(44);
    assert!(violations(&reaching, &tracer, &cell, 100_000, &mut rng).is_empty());
    assert_unseen(&scene, &tracer, &cell, &hb, 200, &mut rng);
}

/// Settings out of their domain are refused by name, the sweep's reach
/// among them (1 to 8).
#[test]
fn bad_oracle_settings_are_refused_by_name() {
    let scene = scene_of(vec![boxed(Vec3::ZERO, Vec3::ONE)]);
    for (params, name) in [
        (
            OracleParams {
                sweep_reach: 0,
                ..OracleParams::default()
            },
            "sweep_reach",
        ),
        (
            OracleParams {
                sweep_reach: 9,
                ..OracleParams::default()
            },
            "sweep_reach",
        ),
        (
            OracleParams {
                occludee_depth: 0,
                ..OracleParams::default()
            },
            "occludee_depth",
        ),
        (
            OracleParams {
                resolution: 100,
                ..OracleParams::default()
            },
            "resolution",
        ),
    ] {
        let Err(e) = Oracle::new(&scene, params, Rasteriser::cpu()) else {
            panic!("{name} out of its domain was taken");
        };
        assert!(e.to_string().contains(name), "{e}");
    }
    for reach in 1..=8 {
        let params = OracleParams {
            sweep_reach: reach,
            ..OracleParams::default()
        };
        assert!(Oracle::new(&scene, params, Rasteriser::cpu()).is_ok());
    }
}

/// A ridge of ground, a grid of 2 m squares turned a little (so its rim is
/// ragged), with houses on either side of it.
fn ridge_scene() -> Scene {
    let ridge = |x: f32, y: f32| 6.0 * (-(y - 30.0).powi(2) / 20.0).exp() + 0.02 * x;
    let (s, c) = 0.05f32.sin_cos();
    let at = |i: usize, j: usize| {
        let (u, v) = (2.0 * i as f32 - 30.0, 2.0 * j as f32 - 30.0);
        let (x, y) = (30.0 + c * u - s * v, 30.0 + s * u + c * v);
        Vec3::new(x, y, ridge(x, y))
    };
    let mut ground = Vec::new();
    for j in 0..30 {
        for i in 0..30 {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            ground.push([a, b, c]);
            ground.push([a, c, d]);
        }
    }
    let mut objects = vec![ground];
    for y in [16.0f32, 44.0] {
        for k in 0..6 {
            let x = 6.0 + 9.0 * k as f32;
            objects.push(boxed(
                Vec3::new(x, y, 0.0),
                Vec3::new(x + 2.0, y + 2.0, 2.5),
            ));
        }
    }
    scene_of(objects)
}

/// Terrains as solids: from a cell on the near side of a ridge (a height
/// field of 1,800 triangles), the houses beyond it are proved hidden by
/// the ridge's cuts, and rays, random and aimed at each, agree; a cell
/// dipping into the ridge's flank does not use it, and rays agree there
/// too.
#[test]
fn a_ridge_of_ground_hides_the_houses_beyond_it() {
    let scene = ridge_scene();
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(46);
    // Ground about 0.3 m high there.
    let cell = Aabb::new(Vec3::new(27.0, 10.0, 1.0), Vec3::new(29.0, 12.0, 2.5));
    let report = oracle.cell(&cell, None);
    let beyond: Vec<usize> = (7..13).filter(|&o| !report.visible.contains(o)).collect();
    assert_eq!(beyond.len(), 6, "{beyond:?} of the houses beyond hidden");
    assert!(
        (1..7).all(|o| report.visible.contains(o)),
        "a house in front hidden"
    );
    assert!(report.planes.iter().any(|p| p.slices > 0));
    assert!(violations(&oracle, &tracer, &cell, 100_000, &mut rng).is_empty());
    assert_unseen(&scene, &tracer, &cell, &beyond, 300, &mut rng);
    // A cell on the flank, its uphill side in the ground.
    let flank = Aabb::new(Vec3::new(27.0, 24.0, 3.0), Vec3::new(29.0, 28.0, 4.0));
    let report = oracle.cell(&flank, None);
    let hidden: Vec<usize> = (0..scene.objects().len())
        .filter(|&o| !report.visible.contains(o))
        .collect();
    assert!(violations(&oracle, &tracer, &flank, 100_000, &mut rng).is_empty());
    assert_unseen(&scene, &tracer, &flank, &hidden, 300, &mut rng);
}

/// What a report proves (all but its times).
fn proved(r: &vis5d::oracle::CellReport) -> impl PartialEq + std::fmt::Debug {
    (
        r.visible.clone(),
        r.planes.clone(),
        (
            r.hidden_by_parent,
            r.touching,
            r.sweep_planes,
            r.sweep_hidden,
        ),
        (
            r.cluster_hidden,
            r.shaft_hidden,
            r.sealed_hidden,
            r.inside_solids,
        ),
        // Bits, so that a NaN cell's box equals itself.
        [r.projected_from.min, r.projected_from.max].map(|v| v.to_array().map(f32::to_bits)),
    )
}

/// `Oracle::cells` makes every cell's maps in one call of the rasteriser
/// (one GPU submission) and answers each cell as `Oracle::cell` does
/// alone: the property test's cells, a cell that is no box, and cells
/// given what their parents hid; on the CPU and, where there is one, the
/// GPU.
#[test]
fn a_batch_of_cells_answers_as_each_cell_alone() {
    let gpu = gpu();
    for name in ["city.obj", "office.obj"] {
        let scene = scene::load(committed(name)).expect("committed scene loads");
        let oracle =
            Oracle::new(&scene, with_sweep(), Rasteriser::cpu()).expect("valid parameters");
        let mut rng = Pcg64::seed_from_u64(0xba7c);
        let mut boxes: Vec<Aabb> = cells(&scene, &mut rng).into_iter().map(|c| c.1).collect();
        boxes.push(Aabb::new(Vec3::splat(f32::NAN), Vec3::ONE));
        // Children of the first two cells, with what their parents hid.
        let parents: Vec<vis5d::bitset::ObjectSet> = boxes[..2]
            .iter()
            .map(|b| {
                let mut hidden = vis5d::bitset::ObjectSet::full(scene.objects().len());
                hidden.subtract(&oracle.cell(b, None).visible);
                hidden
            })
            .collect();
        let mut batch: Vec<(Aabb, Option<&vis5d::bitset::ObjectSet>)> =
            boxes.iter().map(|&b| (b, None)).collect();
        for (b, hidden) in boxes[..2].iter().zip(&parents) {
            let child = Aabb::new(b.min, b.center());
            batch.push((child, Some(hidden)));
        }
        let alone: Vec<_> = batch.iter().map(|(b, h)| oracle.cell(b, *h)).collect();
        let mut calls = 0;
        let together = oracle.cells_with(&batch, &mut |jobs| {
            calls += 1;
            oracle.rasteriser().rasterise_many(jobs)
        });
        assert_eq!(calls, 1, "{name}: one call of the rasteriser");
        assert_eq!(together.len(), batch.len());
        for (k, (a, t)) in alone.iter().zip(&together).enumerate() {
            assert_eq!(proved(a), proved(t), "{name}, cell {k} on the CPU");
        }
        assert!(
            alone
                .iter()
                .any(|r| r.visible.count() < scene.objects().len()),
            "{name}: the cells prove something"
        );
        let Some(gpu) = &gpu else { continue };
        let mut calls = 0;
        let together = oracle.cells_with(&batch, &mut |jobs| {
            calls += 1;
            gpu.rasterise_many(jobs).expect("the GPU rasterises")
        });
        assert_eq!(calls, 1);
        for (k, ((b, h), t)) in batch.iter().zip(&together).enumerate() {
            let alone = oracle.cell_with(b, *h, &mut |jobs| {
                gpu.rasterise_many(jobs).expect("the GPU rasterises")
            });
            assert_eq!(proved(&alone), proved(t), "{name}, cell {k} on the GPU");
        }
    }
}
