//! Build time of the 5D tree with default parameters, on the paper's
//! scenes (papers/003 sec. 8): the apartment (`scenes/apartment.obj`), the
//! block of 18 apartments (`vis5d scene apartment --replicate 18`) and the
//! machine (`scenes/machine.obj`). Throughput is rays cast per second;
//! before each scene the bench prints the rays, the tree's shape and the
//! share of time spent tracing. Results go to notes/build.md.
//!
//! Run: `cargo bench --bench build`.

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use vis5d::builder::{BuildParams, build, summarize};
use vis5d::scene::Scene;
use vis5d::scene::procedural::{SceneKind, generate};
use vis5d::trace::Tracer;

fn bench_scene(c: &mut Criterion, name: &str, scene: &Scene) {
    let tracer = Tracer::new(scene);
    let params = BuildParams::default();
    let (tree, stats) =
        build(scene, &tracer, &params, &|_| {}).expect("default parameters are valid");
    let s = summarize(&tree, scene);
    let threads = rayon::current_num_threads();
    eprintln!(
        "{name}: {} objects, {} triangles: {} leaves, depth {}, {} rays ({} cell, {} object), \
         {:.2} s, {:.2} Mrays/s, tracing {:.0}% of {threads} threads",
        scene.objects().len(),
        scene.triangles().len(),
        s.leaves,
        s.depth,
        stats.rays(),
        stats.cell_rays,
        stats.object_rays,
        stats.seconds,
        stats.rays() as f64 / stats.seconds / 1e6,
        100.0 * stats.trace_seconds / (stats.seconds * threads as f64),
    );
    let mut g = c.benchmark_group("build");
    g.throughput(Throughput::Elements(stats.rays()));
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(10));
    g.bench_function(name, |b| {
        b.iter(|| build(scene, &tracer, &params, &|_| {}).expect("valid"))
    });
    g.finish();
}

fn builds(c: &mut Criterion) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let apartment = vis5d::scene::load(root.join("scenes/apartment.obj")).expect("committed scene");
    bench_scene(c, "apartment", &apartment);
    let machine = vis5d::scene::load(root.join("scenes/machine.obj")).expect("committed scene");
    bench_scene(c, "machine", &machine);
    let block = generate(SceneKind::Apartment, 1, 18);
    bench_scene(c, "apartment_x18", &block);
}

criterion_group!(benches, builds);
criterion_main!(benches);
