//! Tests of the GPU rasteriser: against an exact reference and against
//! the CPU rasteriser, on random and adversarial occluders.

use super::*;
use crate::geom::polygon::{convex_hull, rectangle};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use std::sync::OnceLock;
use std::time::Instant;

/// One rasteriser for all tests (opening a device takes a while); None
/// when there is no adapter, and the tests then skip.
fn gpu() -> Option<&'static GpuRasteriser> {
    static GPU: OnceLock<Option<GpuRasteriser>> = OnceLock::new();
    GPU.get_or_init(|| match GpuRasteriser::new() {
        Ok(g) => {
            eprintln!("oracle_gpu tests run on {g:?}");
            Some(g)
        }
        Err(e) => {
            // CI installs Mesa's CPU Vulkan driver and sets this, so
            // that the GPU path is really tested there.
            assert!(
                std::env::var_os("VIS5D_REQUIRE_GPU").is_none(),
                "VIS5D_REQUIRE_GPU is set but there is no GPU adapter: {e}"
            );
            eprintln!("oracle_gpu tests skipped: {e}");
            None
        }
    })
    .as_ref()
}

/// Exact reference: pixel (i, j) is covered by an occluder iff its four
/// corners are inside every view (closed convex polygons); the value is
/// the smallest Depth over covering occluders.
fn reference(n: usize, occluders: &[ProjectedOccluder]) -> Vec<f64> {
    let mut map = vec![f64::INFINITY; n * n];
    for o in occluders {
        if o.views.is_empty() || o.depth.is_nan() {
            continue;
        }
        let inside = |view: &[DVec2], p: DVec2| {
            let s = signed_area(view).signum();
            (0..view.len()).all(|e| {
                let (a, b) = (view[e], view[(e + 1) % view.len()]);
                s * (b - a).perp_dot(p - a) >= 0.0
            })
        };
        // Covered pixels lie within the first view's bounding box.
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for &p in &o.views[0] {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        let range = |a: f64, b: f64| {
            let a = a.floor().clamp(0.0, n as f64) as usize;
            let b = b.ceil().clamp(0.0, n as f64) as usize;
            a..b
        };
        for j in range(lo.y, hi.y) {
            for i in range(lo.x, hi.x) {
                let corners = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .map(|(dx, dy)| DVec2::new((i + dx) as f64, (j + dy) as f64));
                let covered = o.views.iter().all(|v| {
                    v.len() >= 3 && signed_area(v) != 0.0 && corners.iter().all(|&c| inside(v, c))
                });
                if covered {
                    map[j * n + i] = map[j * n + i].min(o.depth);
                }
            }
        }
    }
    map
}

/// Random occluders: hulls of random points, 8 views translated by
/// small random offsets, random Depths of both signs.
fn random_occluders(rng: &mut Pcg64, n: usize, count: usize) -> Vec<ProjectedOccluder> {
    let side = n as f64;
    (0..count)
        .map(|_| {
            let centre = DVec2::new(
                rng.random_range(-0.1 * side..1.1 * side),
                rng.random_range(-0.1 * side..1.1 * side),
            );
            let radius = rng.random_range(0.04 * side..0.25 * side);
            let mut points: Vec<DVec2> = (0..rng.random_range(3..12))
                .map(|_| {
                    centre
                        + DVec2::new(
                            rng.random_range(-radius..radius),
                            rng.random_range(-radius..radius),
                        )
                })
                .collect();
            let base = convex_hull(&mut points);
            let jitter = 0.1 * radius;
            let views = (0..8)
                .map(|_| {
                    let t = DVec2::new(
                        rng.random_range(-jitter..jitter),
                        rng.random_range(-jitter..jitter),
                    );
                    base.iter().map(|&p| p + t).collect()
                })
                .collect();
            ProjectedOccluder {
                views,
                depth: rng.random_range(-100.0..100.0),
            }
        })
        .collect()
}

/// Compares a GPU map with the reference: panics on any unsound pixel
/// (written where no occluder covers it, below the smallest covering
/// Depth, or not any occluder's rounded Depth); returns (GPU-written
/// pixels, reference pixels, pixels holding exactly the rounded
/// reference value).
fn check_sound(
    n: usize,
    occluders: &[ProjectedOccluder],
    gpu: &[f64],
    exact: &[f64],
) -> (usize, usize, usize) {
    assert_eq!(gpu.len(), n * n);
    let values: std::collections::HashSet<u64> = occluders
        .iter()
        .map(|o| f64::from(f32_at_least(o.depth)).to_bits())
        .collect();
    let (mut written, mut expected, mut tight) = (0, 0, 0);
    for (k, (&g, &r)) in gpu.iter().zip(exact).enumerate() {
        let (i, j) = (k % n, k / n);
        if r != f64::INFINITY {
            expected += 1;
        }
        if g == f64::INFINITY {
            continue;
        }
        written += 1;
        assert!(
            r != f64::INFINITY,
            "pixel ({i}, {j}) written with {g} but no occluder covers it"
        );
        assert!(g >= r, "pixel ({i}, {j}) holds {g} < true depth {r}");
        assert!(values.contains(&g.to_bits()), "pixel ({i}, {j}) holds {g}");
        if g == f64::from(f32_at_least(r)) {
            tight += 1;
        }
    }
    (written, expected, tight)
}

fn square(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
    rectangle(DVec2::new(x0, y0), DVec2::new(x1, y1))
}

#[test]
fn random_occluders_are_sound_and_useful() {
    let Some(gpu) = gpu() else { return };
    let mut rng = Pcg64::seed_from_u64(5);
    for (n, count, maps) in [(64, 30, 6), (256, 60, 3)] {
        let (mut written, mut expected, mut tight) = (0, 0, 0);
        for _ in 0..maps {
            let occluders = random_occluders(&mut rng, n, count);
            let map = gpu.rasterise(n, &occluders).unwrap();
            let (w, e, t) = check_sound(n, &occluders, &map, &reference(n, &occluders));
            written += w;
            expected += e;
            tight += t;
        }
        let ratio = written as f64 / expected as f64;
        eprintln!(
            "n = {n}: GPU wrote {written} of {expected} reference pixels ({ratio:.4}), \
             {tight} with the exact smallest value"
        );
        assert!(
            expected > 1000,
            "too few covered pixels to judge: {expected}"
        );
        assert!(
            ratio >= 0.95,
            "GPU wrote only {ratio:.4} of the reference pixels"
        );
    }
}

#[test]
fn axis_aligned_squares_on_pixel_edges_are_exact() {
    let Some(gpu) = gpu() else { return };
    let n = 32;
    let occluders = vec![
        ProjectedOccluder {
            views: vec![square(4.0, 6.0, 12.0, 9.0); 8],
            depth: 3.0,
        },
        // Views offset by whole pixels: the intersection is [21, 29] x [2, 30].
        ProjectedOccluder {
            views: (0..8)
                .map(|i| square(20.0 + f64::from(i % 2), 2.0, 29.0, 30.0))
                .collect(),
            depth: -7.5,
        },
        // A 1x1 pixel square, clockwise.
        ProjectedOccluder {
            views: vec![square(0.0, 31.0, 1.0, 32.0).into_iter().rev().collect(); 8],
            depth: 0.25,
        },
        // Fractional edges: pixels 2..=4 by 13..=14 only.
        ProjectedOccluder {
            views: vec![square(1.9, 12.5, 5.0, 15.2); 8],
            depth: 1.0,
        },
    ];
    let map = gpu.rasterise(n, &occluders).unwrap();
    let exact = reference(n, &occluders);
    let (written, expected, tight) = check_sound(n, &occluders, &map, &exact);
    assert_eq!(expected, 8 * 3 + 8 * 28 + 1 + 3 * 2);
    assert_eq!(written, expected, "axis-aligned squares must be exact");
    assert_eq!(tight, expected);
    assert_eq!(map[31 * n], 0.25);
    assert_eq!(map[13 * n + 2], 1.0);
    assert_eq!(map[12 * n + 2], f64::INFINITY);
}

#[test]
fn views_that_do_not_all_overlap_write_nothing() {
    let Some(gpu) = gpu() else { return };
    let n = 64;
    // Seven views share a large square; the eighth lies elsewhere.
    let mut views = vec![square(4.0, 4.0, 40.0, 40.0); 7];
    views.push(square(44.0, 44.0, 60.0, 60.0));
    // Two views that overlap by less than a pixel.
    let thin = vec![
        square(4.0, 44.0, 20.5, 60.0),
        square(19.7, 44.0, 36.0, 60.0),
    ];
    let occluders = [
        ProjectedOccluder { views, depth: 1.0 },
        ProjectedOccluder {
            views: thin,
            depth: 2.0,
        },
    ];
    let map = gpu.rasterise(n, &occluders).unwrap();
    assert!(map.iter().all(|&v| v == f64::INFINITY));
    // And the stencil was reset: a later occluder of the same map is
    // drawn normally.
    let mut more = occluders.to_vec();
    more.push(ProjectedOccluder {
        views: vec![square(8.0, 8.0, 16.0, 16.0); 8],
        depth: 4.0,
    });
    let map = gpu.rasterise(n, &more).unwrap();
    let (written, expected, tight) = check_sound(n, &more, &map, &reference(n, &more));
    assert_eq!((written, expected, tight), (64, 64, 64));
}

#[test]
fn overlapping_occluders_keep_the_smallest_depth() {
    let Some(gpu) = gpu() else { return };
    let n = 128;
    let a = square(10.0, 10.0, 80.0, 80.0);
    let tri = vec![
        DVec2::new(30.3, 20.1),
        DVec2::new(110.7, 50.2),
        DVec2::new(40.9, 120.4),
    ];
    let mut occluders = vec![
        ProjectedOccluder {
            views: vec![a.clone(); 8],
            depth: 5.0,
        },
        ProjectedOccluder {
            views: vec![tri.clone(); 8],
            depth: 2.0,
        },
        // Nearly equal depths (same depth key) in both orders: the
        // smaller must win whatever the depth buffer's precision.
        ProjectedOccluder {
            views: vec![square(50.0, 5.0, 70.0, 30.0); 8],
            depth: 1.000_000_1,
        },
        ProjectedOccluder {
            views: vec![square(60.0, 10.0, 75.0, 40.0); 8],
            depth: 1.000_000_3,
        },
        // A Depth between f32 values: stored rounded up.
        ProjectedOccluder {
            views: vec![square(0.0, 100.0, 20.0, 128.0); 8],
            depth: -0.1,
        },
        ProjectedOccluder {
            views: vec![square(0.0, 90.0, 10.0, 128.0); 8],
            depth: f64::NEG_INFINITY,
        },
    ];
    // Many layers over one spot, in random order.
    let mut rng = Pcg64::seed_from_u64(9);
    for _ in 0..40 {
        occluders.push(ProjectedOccluder {
            views: vec![square(90.0, 90.0, 120.0, 120.0); 8],
            depth: rng.random_range(3.0..9.0),
        });
    }
    let map = gpu.rasterise(n, &occluders).unwrap();
    let exact = reference(n, &occluders);
    let (written, expected, _) = check_sound(n, &occluders, &map, &exact);
    assert!(written as f64 >= 0.97 * expected as f64);
    // Away from the triangle's slanted edges every value is exact.
    for j in 85..128 {
        for i in 85..128 {
            let want = f64::from(f32_at_least(exact[j * n + i]));
            assert_eq!(map[j * n + i], want, "pixel ({i}, {j})");
        }
    }
    assert_eq!(map[50 * n + 50], 2.0);
    assert_eq!(map[15 * n + 20], 5.0);
    assert_eq!(map[20 * n + 65], f64::from(f32_at_least(1.000_000_1)));
    assert_eq!(map[110 * n + 5], f64::NEG_INFINITY);
    assert_eq!(map[105 * n + 15], f64::from(f32_at_least(-0.1)));
    assert!(map[105 * n + 15] > -0.1);
}

#[test]
fn degenerate_polygons_write_nothing() {
    let Some(gpu) = gpu() else { return };
    let n = 64;
    let tiny = vec![
        DVec2::new(10.2, 10.2),
        DVec2::new(10.9, 10.3),
        DVec2::new(10.5, 10.8),
    ];
    let sliver = vec![
        DVec2::new(5.0, 5.0),
        DVec2::new(60.0, 6.0),
        DVec2::new(5.0, 5.9),
    ];
    let flat = vec![
        DVec2::new(1.0, 1.0),
        DVec2::new(30.0, 30.0),
        DVec2::new(50.0, 50.0),
    ];
    let two = vec![DVec2::new(1.0, 1.0), DVec2::new(30.0, 30.0)];
    let nan = vec![
        DVec2::new(1.0, 1.0),
        DVec2::new(f64::NAN, 30.0),
        DVec2::new(1.0, 50.0),
    ];
    let mut occluders: Vec<ProjectedOccluder> = [tiny, sliver, flat, two, nan]
        .into_iter()
        .map(|v| ProjectedOccluder {
            views: vec![v; 8],
            depth: 1.0,
        })
        .collect();
    // A good view with one degenerate one, no views, a NaN depth,
    // an occluder wholly outside the map.
    let mut views = vec![square(2.0, 2.0, 40.0, 40.0); 7];
    views.push(vec![DVec2::new(3.0, 3.0); 4]);
    occluders.push(ProjectedOccluder { views, depth: 1.0 });
    occluders.push(ProjectedOccluder {
        views: Vec::new(),
        depth: 1.0,
    });
    occluders.push(ProjectedOccluder {
        views: vec![square(2.0, 2.0, 40.0, 40.0); 8],
        depth: f64::NAN,
    });
    occluders.push(ProjectedOccluder {
        views: vec![square(70.0, 2.0, 90.0, 40.0); 8],
        depth: 1.0,
    });
    let map = gpu.rasterise(n, &occluders).unwrap();
    assert!(map.iter().all(|&v| v == f64::INFINITY));
    // Nothing at all, and the smallest map.
    assert!(
        gpu.rasterise(n, &[])
            .unwrap()
            .iter()
            .all(|v| v.is_infinite())
    );
    let whole = [ProjectedOccluder {
        views: vec![square(-5.0, -5.0, 5.0, 5.0); 8],
        depth: 2.0,
    }];
    assert_eq!(gpu.rasterise(1, &whole).unwrap(), vec![2.0]);
}

#[test]
fn rasteriser_is_shared_across_threads() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<GpuRasteriser>();
    send_sync::<GpuError>();
    let Some(gpu) = gpu() else { return };
    let occluders = [ProjectedOccluder {
        views: vec![square(1.0, 1.0, 5.0, 5.0); 8],
        depth: 1.5,
    }];
    let maps: Vec<Vec<f64>> = std::thread::scope(|s| {
        let jobs: Vec<_> = (0..4)
            .map(|_| s.spawn(|| gpu.rasterise(8, &occluders).unwrap()))
            .collect();
        jobs.into_iter().map(|j| j.join().unwrap()).collect()
    });
    assert!(maps.iter().all(|m| m == &maps[0]));
    assert_eq!(maps[0].iter().filter(|&&v| v == 1.5).count(), 16);
}

#[test]
fn invalid_requests_are_errors() {
    let Some(gpu) = gpu() else { return };
    assert!(matches!(
        gpu.rasterise(48, &[]),
        Err(GpuError::InvalidInput(_))
    ));
    assert!(matches!(
        gpu.rasterise(8192, &[]),
        Err(GpuError::InvalidInput(_))
    ));
    assert!(matches!(
        gpu.rasterise(0, &[]),
        Err(GpuError::InvalidInput(_))
    ));
    let many = [ProjectedOccluder {
        views: vec![square(0.0, 0.0, 4.0, 4.0); 256],
        depth: 1.0,
    }];
    let e = gpu.rasterise(8, &many).unwrap_err();
    assert!(e.to_string().contains("256 views"), "{e}");
}

#[test]
fn erosion_matches_the_pixel_square_rule() {
    // CPU only: a pixel centre inside the eroded polygon has its square
    // inside the view, for random slanted triangles.
    let mut rng = Pcg64::seed_from_u64(3);
    for _ in 0..200 {
        let mut pts: Vec<DVec2> = (0..3)
            .map(|_| DVec2::new(rng.random_range(0.0..32.0), rng.random_range(0.0..32.0)))
            .collect();
        let view = convex_hull(&mut pts);
        let Some(eroded) = erode_view(&view, 32.0) else {
            continue;
        };
        let one = [ProjectedOccluder {
            views: vec![view.clone()],
            depth: 0.0,
        }];
        let exact = reference(32, &one);
        for j in 0..32 {
            for i in 0..32 {
                let c = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
                let inside = (0..eroded.len()).all(|e| {
                    let (a, b) = (eroded[e], eroded[(e + 1) % eroded.len()]);
                    (b - a).perp_dot(c - a) >= 0.0
                });
                if inside {
                    assert!(exact[j * 32 + i] == 0.0, "{view:?}: pixel ({i}, {j})");
                }
            }
        }
    }
}

#[test]
fn thousand_occluders_at_256() {
    let Some(gpu) = gpu() else { return };
    let n = 256;
    let mut rng = Pcg64::seed_from_u64(11);
    // Smaller occluders than the soundness test, as a scene's would be.
    let occluders: Vec<ProjectedOccluder> = random_occluders(&mut rng, n, 1000)
        .into_iter()
        .map(|mut o| {
            let c = o.views[0][0];
            for v in &mut o.views {
                for p in v.iter_mut() {
                    *p = c + (*p - c) * 0.4;
                }
            }
            o
        })
        .collect();
    let map = gpu.rasterise(n, &occluders).unwrap();
    // Many render passes (each loading the last one's buffers) give the
    // same map.
    assert_eq!(gpu.rasterise_in_passes(n, &occluders, 2000).unwrap(), map);
    let start = Instant::now();
    let runs = 3;
    for _ in 0..runs {
        assert_eq!(gpu.rasterise(n, &occluders).unwrap(), map);
    }
    let per_map = start.elapsed() / runs;
    let t = Instant::now();
    let prepared = prepare(n, &occluders);
    let batches = make_batches(n, &prepared);
    let chunks = build_vertices(n, &prepared, &batches, CHUNK_VERTICES);
    let cpu_side = t.elapsed();
    eprintln!(
        "1000 occluders at n = {n}: {per_map:?} per map on {} ({} drawn, {} batches, \
         {} vertices; erosion and batching {cpu_side:?})",
        gpu.adapter_name(),
        prepared.len(),
        batches.len(),
        chunks[0].vertices.len(),
    );
    let (written, expected, tight) = check_sound(n, &occluders, &map, &reference(n, &occluders));
    eprintln!("  wrote {written} of {expected} reference pixels, {tight} exact");
    assert!(written as f64 >= 0.9 * expected as f64);
}

/// Many maps of many small, thin and large occluders: a longer
/// soundness hunt (`cargo test --release -- --ignored oracle_gpu`).
#[test]
#[ignore = "slow: a soundness stress run"]
fn stress_soundness() {
    let Some(gpu) = gpu() else { return };
    let mut rng = Pcg64::seed_from_u64(77);
    let (mut written, mut expected) = (0, 0);
    for round in 0..300 {
        let n = [16, 64, 128, 1024][round % 4];
        let mut occluders = random_occluders(&mut rng, n, 40);
        // Shrink some to a few pixels, where margins matter most.
        for o in occluders.iter_mut().step_by(2) {
            let s = rng.random_range(0.02..0.3);
            let c = o.views[0][0];
            for v in &mut o.views {
                for p in v.iter_mut() {
                    *p = c + (*p - c) * s;
                }
            }
        }
        let map = gpu.rasterise(n, &occluders).unwrap();
        let (w, e, _) = check_sound(n, &occluders, &map, &reference(n, &occluders));
        written += w;
        expected += e;
    }
    eprintln!("stress: wrote {written} of {expected} reference pixels");
}

#[test]
fn large_maps_and_far_vertices() {
    let Some(gpu) = gpu() else { return };
    // A triangle reaching 1e7 pixels away, seen from two corners.
    let n = 1024;
    let far = vec![
        DVec2::new(-1e7, 500.25),
        DVec2::new(1e7, 520.75),
        DVec2::new(3.0e5, 2e7),
    ];
    let shifted = far.iter().map(|&p| p + DVec2::new(0.0, -3.5)).collect();
    let occluders = [ProjectedOccluder {
        views: vec![far, shifted],
        depth: 0.5,
    }];
    let map = gpu.rasterise(n, &occluders).unwrap();
    let (written, expected, tight) = check_sound(n, &occluders, &map, &reference(n, &occluders));
    assert!(expected > 500_000 && written as f64 >= 0.99 * expected as f64);
    assert_eq!(tight, written);
    // The largest map: its last row and column are reachable.
    let n = 4096;
    let corner = [ProjectedOccluder {
        views: vec![square(4090.0, 4093.0, 4096.0, 4096.0); 8],
        depth: 8.0,
    }];
    let map = gpu.rasterise(n, &corner).unwrap();
    let (written, expected, _) = check_sound(n, &corner, &map, &reference(n, &corner));
    assert_eq!((written, expected), (18, 18));
    assert_eq!(map[n * n - 1], 8.0);
}

#[test]
fn depth24_stencil8_gives_the_same_maps() {
    if gpu().is_none() {
        return;
    }
    let gpu24 = GpuRasteriser::open(false).unwrap();
    assert_eq!(gpu24.depth_format, wgpu::TextureFormat::Depth24PlusStencil8);
    let mut rng = Pcg64::seed_from_u64(21);
    let n = 128;
    let mut occluders = random_occluders(&mut rng, n, 40);
    // Depths closer than the 24-bit depth buffer resolves.
    for (k, o) in occluders.iter_mut().enumerate() {
        o.depth = 10.0 + 1e-6 * (k % 7) as f64;
    }
    let map = gpu24.rasterise(n, &occluders).unwrap();
    check_sound(n, &occluders, &map, &reference(n, &occluders));
    assert_eq!(map, gpu().unwrap().rasterise(n, &occluders).unwrap());
}

/// A device and queue the caller opened itself: the same maps as the
/// rasteriser that opened its own.
#[test]
fn a_device_the_caller_owns_gives_the_same_maps() {
    let Some(own) = gpu() else { return };
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::PRIMARY,
        flags: wgpu::InstanceFlags::empty(),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY))
        .into_iter()
        .find(|a| a.get_info().backend == own.info.backend)
        .expect("the adapter the rasteriser found");
    let (device, queue) =
        pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor::default()))
            .expect("a device with default features and limits");
    let theirs = GpuRasteriser::from_device(device, queue).expect("a rasteriser on it");
    assert_eq!(
        theirs.depth_format,
        wgpu::TextureFormat::Depth24PlusStencil8
    );
    let mut rng = Pcg64::seed_from_u64(22);
    let n = 256;
    let occluders = random_occluders(&mut rng, n, 60);
    let map = theirs.rasterise(n, &occluders).unwrap();
    check_sound(n, &occluders, &map, &reference(n, &occluders));
    assert_eq!(map, own.rasterise(n, &occluders).unwrap());
}

/// Several maps in one submission are the maps one at a time, empty jobs
/// included, in order.
#[test]
fn many_maps_in_one_submission_match_one_at_a_time() {
    let Some(gpu) = gpu() else { return };
    let mut rng = Pcg64::seed_from_u64(41);
    let sets: Vec<(usize, Vec<ProjectedOccluder>)> = [16usize, 64, 32, 64]
        .iter()
        .enumerate()
        .map(|(k, &n)| {
            let count = if k == 2 { 0 } else { 20 };
            (n, random_occluders(&mut rng, n, count))
        })
        .collect();
    let jobs: Vec<MapJob> = sets.iter().map(|(n, o)| (*n, o.as_slice())).collect();
    let many = gpu.rasterise_many(&jobs).unwrap();
    assert_eq!(many.len(), jobs.len());
    for ((n, occluders), map) in sets.iter().zip(&many) {
        assert_eq!(map, &gpu.rasterise(*n, occluders).unwrap());
    }
    assert!(many[2].iter().all(|d| d.is_infinite()));
    assert!(gpu.rasterise_many(&[]).unwrap().is_empty());
}
