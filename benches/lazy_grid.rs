//! The lazy occlusion grid (papers/002): time per view as the image grows
//! (128, 256, 512 pixels on a side), lazy against busy cell updates, on
//! the committed apartment, city and office; 32-pixel cells. Throughput is
//! views per second. Before each scene the bench prints, per image size,
//! the objects drawn and the pixel-level queries of both modes (the
//! paper's Fig. 8 figure).
//!
//! Run: `cargo bench --bench lazy_grid` (results in notes/report.md).

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use vis5d::bitset::ObjectSet;
use vis5d::lazy_grid::{GridParams, LazyGrid};
use vis5d::render::{Camera, random_views};

const VIEWS: usize = 20;

fn bench_scene(c: &mut Criterion, name: &str) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene =
        vis5d::scene::load(root.join("scenes").join(format!("{name}.obj"))).expect("committed");
    let grid = LazyGrid::new(&scene);
    let views = random_views(&scene.bounds(), VIEWS, 90.0, 99);
    let mut out = ObjectSet::new(scene.objects().len());
    let mut g = c.benchmark_group(format!("lazy_grid/{name}"));
    g.throughput(Throughput::Elements(VIEWS as u64));
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(4));
    for size in [128, 256, 512] {
        let cameras: Vec<Camera> = views
            .iter()
            .map(|v| Camera::new(v, size, size).expect("random views have a frame"))
            .collect();
        for lazy in [true, false] {
            let params = GridParams {
                cell_pixels: 32,
                lazy,
            };
            let (mut drawn, mut queries) = (0, 0);
            for cam in &cameras {
                let s = grid.cull(cam, &params, &mut out);
                drawn += s.objects_drawn;
                queries += s.pixel_queries;
            }
            let mode = if lazy { "lazy" } else { "busy" };
            eprintln!(
                "{name} {size} {mode}: {:.1} objects drawn, {:.1} pixel queries per view",
                drawn as f64 / VIEWS as f64,
                queries as f64 / VIEWS as f64
            );
            g.bench_with_input(BenchmarkId::new(mode, size), &cameras, |b, cameras| {
                b.iter(|| {
                    for cam in cameras {
                        grid.cull(cam, &params, &mut out);
                    }
                })
            });
        }
    }
    g.finish();
}

fn lazy_grid(c: &mut Criterion) {
    for name in ["apartment", "city", "office"] {
        bench_scene(c, name);
    }
}

criterion_group!(benches, lazy_grid);
criterion_main!(benches);
