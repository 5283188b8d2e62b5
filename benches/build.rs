//! Build time of the 5D tree with default parameters as the scene grows:
//! the apartment of papers/003 sec. 8 replicated 1, 4 and 16 times
//! (`vis5d scene apartment --replicate K`: blocks of apartments, 3 per
//! floor), and the machine (`scenes/machine.obj`). Criterion's throughput
//! is objects per second; before each size the bench prints the rays cast,
//! rays per second, the tree's shape and the share of time spent tracing.
//! Results go to notes/build.md.
//!
//! Run: `cargo bench --bench build`.

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use vis5d::builder::{BuildParams, build, summarize};
use vis5d::scene::Scene;
use vis5d::scene::procedural::{SceneKind, generate};
use vis5d::trace::Tracer;

fn bench_scene(c: &mut Criterion, name: &str, size: u32, scene: &Scene) {
    let tracer = Tracer::new(scene);
    let params = BuildParams::default();
    let (tree, stats) =
        build(scene, &tracer, &params, &|_| {}).expect("default parameters are valid");
    let s = summarize(&tree, scene);
    let threads = rayon::current_num_threads();
    eprintln!(
        "{name} x{size}: {} objects, {} triangles: {} leaves, depth {}, {} rays ({} cell, {} object), \
         {:.2} s, {:.2} Mrays/s, {:.0} objects/s, tracing {:.0}% of {threads} threads",
        scene.objects().len(),
        scene.triangles().len(),
        s.leaves,
        s.depth,
        stats.rays(),
        stats.cell_rays,
        stats.object_rays,
        stats.seconds,
        stats.rays() as f64 / stats.seconds / 1e6,
        scene.objects().len() as f64 / stats.seconds,
        100.0 * stats.trace_seconds / (stats.seconds * threads as f64),
    );
    let mut g = c.benchmark_group(format!("build/{name}"));
    g.throughput(Throughput::Elements(scene.objects().len() as u64));
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(10));
    g.bench_with_input(BenchmarkId::from_parameter(size), scene, |b, scene| {
        b.iter(|| build(scene, &tracer, &params, &|_| {}).expect("valid"))
    });
    g.finish();
}

fn builds(c: &mut Criterion) {
    for k in [1, 4, 16] {
        bench_scene(c, "apartment", k, &generate(SceneKind::Apartment, 1, k));
    }
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = vis5d::scene::load(root.join("scenes/machine.obj")).expect("committed scene");
    bench_scene(c, "machine", 1, &machine);
}

criterion_group!(benches, builds);
criterion_main!(benches);
