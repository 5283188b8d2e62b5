//! The runtime side: view queries per second, and the time to decode a
//! `.v5d` file, on trees built with default parameters for the apartment,
//! the block of 18 apartments and the city. Results go to notes/query.md.
//!
//! Views: 1,000 per scene, eye uniform in the view box, direction uniform on
//! the sphere, 90 degree square field of view, seeded.
//!
//! Criterion times batches of the 1,000 views (a mean per view). Before
//! it, each scene's line also gives the median and 90th percentile of one
//! view's time: each view timed alone, the best of 100 passes, the
//! timer's own cost taken off ([`per_view`]).
//!
//! Run: `cargo bench --bench query`.

use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use vis5d::builder::{BuildParams, build, to_file};
use vis5d::codec::write_file;
use vis5d::query::{Pvs, View};
use vis5d::render::random_views;
use vis5d::scene::Scene;
use vis5d::scene::procedural::{SceneKind, generate};
use vis5d::trace::Tracer;

const VIEWS: usize = 1000;

fn file_for(scene: &Scene) -> Vec<u8> {
    let tracer = Tracer::new(scene);
    let params = BuildParams::default();
    let (tree, _) = build(scene, &tracer, &params, &|_| {}).expect("default parameters are valid");
    write_file(&to_file(scene, tree, &params, None))
}

fn views(pvs: &Pvs) -> Vec<View> {
    random_views(&pvs.root_cell().space(), VIEWS, 90.0, 5)
}

/// The median and 90th percentile, in microseconds, of one view's query
/// time: each view timed alone, the best of `passes` passes, less the
/// least time an empty timing took.
fn per_view(pvs: &Pvs, views: &[View], passes: usize) -> (f64, f64) {
    let mut set = pvs.new_set();
    let mut best = vec![f64::INFINITY; views.len()];
    let mut timer = f64::INFINITY;
    for _ in 0..passes {
        for (best, v) in best.iter_mut().zip(views) {
            let start = Instant::now();
            pvs.query_view(v, &mut set).unwrap();
            *best = best.min(start.elapsed().as_secs_f64());
            let start = Instant::now();
            timer = timer.min(start.elapsed().as_secs_f64());
        }
    }
    let mut us: Vec<f64> = best.iter().map(|b| (b - timer).max(0.0) * 1e6).collect();
    us.sort_by(f64::total_cmp);
    (us[us.len() / 2], us[us.len() * 9 / 10])
}

fn queries(c: &mut Criterion) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenes = [
        (
            "apartment",
            vis5d::scene::load(root.join("scenes/apartment.obj")).expect("committed"),
        ),
        ("apartment_x18", generate(SceneKind::Apartment, 1, 18)),
        (
            "city",
            vis5d::scene::load(root.join("scenes/city.obj")).expect("committed"),
        ),
    ];
    for (name, scene) in &scenes {
        let bytes = file_for(scene);
        let pvs = Pvs::from_bytes(&bytes).expect("a fresh file decodes");
        let views = views(&pvs);
        let mut set = pvs.new_set();
        let mean: f64 = views
            .iter()
            .map(|v| {
                pvs.query_view(v, &mut set).unwrap();
                set.count() as f64
            })
            .sum::<f64>()
            / VIEWS as f64;
        let (median, p90) = per_view(&pvs, &views, 100);
        eprintln!(
            "{name}: {} objects, {} nodes, {} bytes ({}), mean answer {mean:.1} objects, \
             one view {median:.2} us median, {p90:.2} us 90th percentile",
            pvs.object_count(),
            pvs.node_count(),
            bytes.len(),
            pvs.coding()
        );
        let mut g = c.benchmark_group("query");
        g.throughput(Throughput::Elements(VIEWS as u64));
        g.measurement_time(Duration::from_secs(5));
        g.bench_function(BenchmarkId::new("view", name), |b| {
            b.iter(|| {
                for v in &views {
                    pvs.query_view(v, &mut set).unwrap();
                }
            })
        });
        g.finish();
        let mut g = c.benchmark_group("decode");
        g.throughput(Throughput::Bytes(bytes.len() as u64));
        g.measurement_time(Duration::from_secs(5));
        g.bench_function(*name, |b| {
            b.iter(|| Pvs::from_bytes(&bytes).expect("decodes"))
        });
        g.finish();
    }
}

criterion_group!(benches, queries);
criterion_main!(benches);
