//! Rays per second of [`vis5d::trace::Tracer`] against obvhs called
//! directly (the pattern of obvhs's own examples: `CwBvh` from
//! `build_cwbvh_from_tris` with `medium_build`, `Ray::new_inf`, the
//! `primitive_indices` lookup in the closure), on the same rays and scenes,
//! on 1 thread and on all threads.
//!
//! Scenes: `scenes/city.obj` and the largest real scene,
//! `../shared/scenes/forest_morse_land1_trees/land1_trees.obj` (skipped
//! when absent). Rays: origins uniform in the scene's box, directions
//! uniform on the sphere, seeded. Results go to notes/trace.md.
//!
//! Run: `cargo bench --bench trace`.

use std::path::Path;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::RayHit;
use obvhs::triangle::Triangle as BvhTriangle;
use rayon::prelude::*;
use vis5d::scene::Scene;
use vis5d::trace::{Ray, Tracer};

const RAYS: usize = 20_000;

fn random_rays(scene: &Scene, n: usize) -> Vec<Ray> {
    vis5d::raylog::random_rays(&scene.bounds(), n, 2024)
}

/// obvhs as its examples use it.
struct Raw {
    bvh: CwBvh,
    tris: Vec<BvhTriangle>,
}

impl Raw {
    fn new(scene: &Scene) -> Self {
        let tris: Vec<BvhTriangle> = scene
            .triangles()
            .iter()
            .map(|t| BvhTriangle {
                v0: t[0].into(),
                v1: t[1].into(),
                v2: t[2].into(),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        Self { bvh, tris }
    }

    fn trace(&self, ray: &Ray) -> Option<(u32, f32)> {
        let r = obvhs::ray::Ray::new_inf(ray.origin.into(), ray.dir.into());
        let mut hit = RayHit::none();
        self.bvh
            .ray_traverse(r, &mut hit, |r, id| {
                self.tris[self.bvh.primitive_indices[id] as usize].intersect(r)
            })
            .then(|| (self.bvh.primitive_indices[hit.primitive_id as usize], hit.t))
    }
}

fn bench_scene(c: &mut Criterion, name: &str, path: &Path) {
    if !path.exists() {
        eprintln!("skipping {name}: {} is not here", path.display());
        return;
    }
    let scene = vis5d::scene::load(path).expect("the bench scene loads");
    let tracer = Tracer::new(&scene);
    let raw = Raw::new(&scene);
    let rays = random_rays(&scene, RAYS);
    let hits = rays
        .iter()
        .filter(|r| tracer.closest_hit(r).is_some())
        .count();
    eprintln!(
        "{name}: {} triangles, {} objects, {hits} of {RAYS} rays hit",
        scene.triangles().len(),
        scene.objects().len()
    );

    let mut g = c.benchmark_group(format!("trace/{name}"));
    g.throughput(Throughput::Elements(RAYS as u64));
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(4));
    let all = rayon::current_num_threads();
    for threads in [1, all] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        let mut out = vec![None; rays.len()];
        g.bench_function(BenchmarkId::new("vis5d", format!("{threads}t")), |b| {
            b.iter(|| pool.install(|| tracer.closest_hits_into(&rays, &mut out)))
        });
        let mut out = vec![None; rays.len()];
        g.bench_function(BenchmarkId::new("obvhs", format!("{threads}t")), |b| {
            b.iter(|| {
                pool.install(|| {
                    out.par_chunks_mut(256)
                        .zip(rays.par_chunks(256))
                        .for_each(|(o, r)| {
                            for (o, r) in o.iter_mut().zip(r) {
                                *o = raw.trace(r);
                            }
                        })
                })
            })
        });
    }
    g.finish();
}

fn trace(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    bench_scene(c, "city", &root.join("scenes/city.obj"));
    bench_scene(
        c,
        "land1_trees",
        &root.join("../shared/scenes/forest_morse_land1_trees/land1_trees.obj"),
    );
}

criterion_group!(benches, trace);
criterion_main!(benches);
