//! The extended-projection oracle (papers/001): time per view cell as the
//! Depth Maps grow (64, 128, 256, 512 pixels on a side), on the CPU
//! reference and on the GPU where an adapter exists (Mesa's lavapipe on a
//! machine without one), on 8 street cells of the committed city (4 x 4 x
//! 1 m) and 8 room cells of the office (2 x 2 x 1 m). Throughput is cells per second. Before each
//! scene the bench prints the objects each rasteriser hides. At 256 the
//! GPU is also timed map by map (`gpu-map-by-map`: a submission and a
//! readback per map) against the default batch (all of a cell's maps in
//! one submission).
//!
//! The `bake/` group times the conservative bake (`vis5d build
//! --conservative`, `conservative::bake`) of the committed office and city
//! at depth 6 (127 oracle cells) on the CPU, and prints the mean leaf set.
//!
//! Run: `cargo bench --bench oracle` (results in notes/oracle.md).

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use vis5d::geom::Aabb;
use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
use vis5d::random::uniform_point;
use vis5d::scene::Scene;
use vis5d::trace::{Ray, Tracer};

/// `n` cells of `size` x `size` x 1 m standing 1 m above the floor, where
/// a ray cast down from a random point of the scene lands first on an
/// object named like "ground" or "floor" (street cells of the city, room
/// cells of the office), seeded.
fn cells(scene: &Scene, n: usize, size: f32) -> Vec<Aabb> {
    let tracer = Tracer::new(scene);
    let b = scene.bounds();
    let mut rng = Pcg64::seed_from_u64(17);
    let mut out = Vec::new();
    for _ in 0..1000 * n {
        if out.len() == n {
            break;
        }
        let p = uniform_point(&mut rng, &b);
        let Some(hit) = tracer.closest_hit(&Ray::new(p, -Vec3::Z)) else {
            continue;
        };
        let name = scene.objects()[hit.object as usize].name.to_lowercase();
        if name.contains("ground") || name.contains("floor") {
            let z = p.z - hit.t + 1.0;
            out.push(Aabb::new(
                Vec3::new(p.x, p.y, z),
                Vec3::new(p.x + size, p.y + size, z + 1.0),
            ));
        }
    }
    assert_eq!(out.len(), n, "no floor to stand on");
    out
}

fn bench_scene(c: &mut Criterion, name: &str, cell_size: f32) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene =
        vis5d::scene::load(root.join("scenes").join(format!("{name}.obj"))).expect("committed");
    let cells = cells(&scene, 8, cell_size);
    let mut g = c.benchmark_group(format!("oracle/{name}"));
    g.throughput(Throughput::Elements(cells.len() as u64));
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(5));
    for gpu in [false, true] {
        for resolution in [64, 128, 256, 512] {
            let rasteriser = if gpu {
                let r = Rasteriser::best();
                if !r.is_gpu() {
                    eprintln!("{name}: no GPU ({:?}); GPU rows skipped", r.cpu_reason());
                    break;
                }
                r
            } else {
                Rasteriser::cpu()
            };
            let label = if gpu { "gpu" } else { "cpu" };
            let params = OracleParams {
                resolution,
                ..OracleParams::default()
            };
            let oracle = Oracle::new(&scene, params, rasteriser).expect("valid parameters");
            let hidden: usize = cells
                .iter()
                .map(|cell| scene.objects().len() - oracle.cell(cell, None).visible.count())
                .sum();
            eprintln!(
                "{name} {label} {resolution}: {:.1} of {} objects hidden per cell",
                hidden as f64 / cells.len() as f64,
                scene.objects().len()
            );
            g.bench_with_input(BenchmarkId::new(label, resolution), &cells, |b, cells| {
                b.iter(|| {
                    for cell in cells {
                        oracle.cell(cell, None);
                    }
                })
            });
            // The GPU without batching: one submission and readback per
            // map, as before issue 13's batching.
            #[cfg(feature = "gpu")]
            if gpu
                && resolution == 256
                && let Ok(single) = vis5d::oracle::GpuRasteriser::new()
            {
                g.bench_with_input(
                    BenchmarkId::new("gpu-map-by-map", resolution),
                    &cells,
                    |b, cells| {
                        b.iter(|| {
                            for cell in cells {
                                oracle.cell_with(cell, None, &mut |jobs| {
                                    jobs.iter()
                                        .map(|&(n, o)| single.rasterise(n, o).expect("rasterises"))
                                        .collect()
                                });
                            }
                        })
                    },
                );
            }
        }
    }
    g.finish();
}

fn oracle(c: &mut Criterion) {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // Mesa's Vulkan drivers complain on stderr when it is unset.
        // SAFETY: criterion has started no thread yet.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    bench_scene(c, "city", 4.0);
    bench_scene(c, "office", 2.0);
}

fn bake(c: &mut Criterion) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut g = c.benchmark_group("bake");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(10));
    for name in ["office", "city"] {
        let scene =
            vis5d::scene::load(root.join("scenes").join(format!("{name}.obj"))).expect("committed");
        // The bake's defaults: no sweep (`vis5d build --conservative`).
        let oracle_params = OracleParams {
            sweep_planes: 0,
            sweep_patches: 0,
            ..OracleParams::default()
        };
        let oracle =
            Oracle::new(&scene, oracle_params, Rasteriser::cpu()).expect("valid parameters");
        let params = vis5d::conservative::BakeParams {
            max_depth: 6,
            ..Default::default()
        };
        let (tree, _) = vis5d::conservative::bake(&oracle, &params, &|_| {}).expect("bakes");
        let leaves = tree.leaves();
        let mean = leaves
            .iter()
            .map(|l| tree.nodes()[l.node].set.count())
            .sum::<usize>() as f64
            / leaves.len() as f64;
        eprintln!(
            "bake {name}: {} leaves, {mean:.1} of {} objects a leaf",
            leaves.len(),
            scene.objects().len()
        );
        g.bench_function(name, |b| {
            b.iter(|| vis5d::conservative::bake(&oracle, &params, &|_| {}).expect("bakes"))
        });
    }
    g.finish();
}

criterion_group!(benches, oracle, bake);
criterion_main!(benches);
