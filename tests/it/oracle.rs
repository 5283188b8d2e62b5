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
