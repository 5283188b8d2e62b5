//! The GPU cube map against the CPU reference: per pixel, never covered
//! where the CPU is not, never a smaller `D`, and nearly all of the CPU's
//! coverage. Skipped (with a note) where no GPU adapter opens.

use std::sync::OnceLock;
use std::time::Instant;

use glam::{DQuat, DVec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use super::ShrinkOracle;
use super::shrink_cube::CubeMap;
use super::shrink_gpu::ShrinkGpu;
use super::shrink_mesh::tests::box_triangles;
use super::shrink_mesh::{Shrunk, Solid};
use super::{ShrinkParams, shrink_gpu};
use crate::oracle::GpuRasteriser;

fn gpu() -> Option<&'static (GpuRasteriser, ShrinkGpu)> {
    static GPU: OnceLock<Option<(GpuRasteriser, ShrinkGpu)>> = OnceLock::new();
    GPU.get_or_init(|| match GpuRasteriser::new() {
        Ok(g) => {
            let p = ShrinkGpu::new(&g).expect("pipelines build");
            Some((g, p))
        }
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    })
    .as_ref()
}

/// Covered pixels (CPU, GPU) of one map, after checking every pixel.
fn compare(
    gpu: &(GpuRasteriser, ShrinkGpu),
    eye: DVec3,
    n: usize,
    solids: &[&Shrunk],
) -> (usize, usize) {
    let mut cpu = CubeMap::new(eye, n);
    for s in solids {
        cpu.draw(s);
    }
    let map = gpu.1.build(&gpu.0, eye, n, solids).expect("the GPU map");
    let (_, cd, cdf, cf) = cpu.maps();
    let (m, gd, gdf, gf) = map.maps();
    assert_eq!(m, n);
    for p in 0..6 * n * n {
        if gdf[p].is_finite() {
            assert!(
                cdf[p].is_finite() && gdf[p] >= cdf[p],
                "pixel {p} of n = {n}, eye {eye:?}: GPU {} CPU {}",
                gdf[p],
                cdf[p]
            );
            if gdf[p] == cdf[p] {
                assert!(gf[p] >= cf[p], "pixel {p}: floor {} < {}", gf[p], cf[p]);
            }
        }
        if gd[p].is_finite() {
            assert!(
                cd[p].is_finite() && gd[p] >= cd[p],
                "pixel {p} of n = {n}: GPU {} CPU {}",
                gd[p],
                cd[p]
            );
        }
    }
    (cpu.covered(), map.covered())
}

/// Solids of a random scene of `kind` (0: boxes, 1: rotated boxes, 2:
/// prisms on a floor and a ground slab).
fn random_solids(rng: &mut Pcg64, kind: usize) -> Vec<Solid> {
    let mut out = Vec::new();
    let count = rng.random_range(3..25);
    let v = |rng: &mut Pcg64, a: f64, b: f64| {
        DVec3::new(
            rng.random_range(a..b),
            rng.random_range(a..b),
            rng.random_range(a..b),
        )
    };
    for _ in 0..count {
        match kind {
            0 => {
                let a = v(rng, -10.0, 10.0);
                let s = Solid::new(&box_triangles(a, a + v(rng, 0.5, 4.0)), None);
                out.extend(s);
            }
            1 => {
                let half = v(rng, 0.25, 2.0);
                let axis = v(rng, -1.0, 1.0).normalize_or(DVec3::Z);
                let q = DQuat::from_axis_angle(axis, rng.random_range(0.0..6.3));
                let c = v(rng, -10.0, 10.0);
                let tris: Vec<[DVec3; 3]> = box_triangles(-half, half)
                    .iter()
                    .map(|t| t.map(|p| q * p + c))
                    .collect();
                out.extend(Solid::new(&tris, None));
            }
            _ => {
                let k = rng.random_range(3..9);
                let (cx, cy) = (rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0));
                let r = rng.random_range(0.5..3.0);
                let h = rng.random_range(0.5..6.0);
                let phase: f64 = rng.random_range(0.0..6.3);
                let ring: Vec<(f64, f64)> = (0..k)
                    .map(|i| {
                        let a = phase + i as f64 * std::f64::consts::TAU / k as f64;
                        (cx + r * a.cos(), cy + r * a.sin())
                    })
                    .collect();
                let mut tris = Vec::new();
                for i in 0..k {
                    let (p, q) = (ring[i], ring[(i + 1) % k]);
                    let (p0, q0) = (DVec3::new(p.0, p.1, 0.0), DVec3::new(q.0, q.1, 0.0));
                    let (p1, q1) = (DVec3::new(p.0, p.1, h), DVec3::new(q.0, q.1, h));
                    tris.push([p0, q0, q1]);
                    tris.push([p0, q1, p1]);
                    if i > 0 && i + 1 < k {
                        let o = DVec3::new(ring[0].0, ring[0].1, h);
                        tris.push([o, p1, q1]);
                    }
                }
                out.extend(Solid::new(&tris, Some(0.0)));
            }
        }
    }
    if kind == 2 {
        let g = Solid::new(
            &box_triangles(DVec3::new(-15.0, -15.0, -1.0), DVec3::new(15.0, 15.0, 0.0)),
            None,
        );
        out.extend(g);
    }
    let twins: Vec<Solid> = out.iter().filter_map(Solid::on_its_floor).collect();
    out.extend(twins);
    out
}

/// The solids the oracle would draw from `eye`.
fn drawable(solids: &[Shrunk], eye: DVec3) -> Vec<&Shrunk> {
    solids
        .iter()
        .filter(|s| {
            let apart = (0..3).any(|k| s.solid_max[k] < eye[k] || s.solid_min[k] > eye[k]);
            apart && s.floor.is_none_or(|f| eye.z > f) && !s.triangles.is_empty()
        })
        .collect()
}

fn report(what: &str, cpu: usize, gpu: usize) {
    let ratio = gpu as f64 / cpu.max(1) as f64;
    eprintln!("{what}: GPU covers {gpu} of the CPU's {cpu} pixels ({ratio:.4})");
    assert!(ratio >= 0.95, "{what}: coverage ratio {ratio}");
}

#[test]
fn gpu_cube_maps_of_random_scenes_are_within_the_cpus() {
    let Some(gpu) = gpu() else { return };
    let mut rng = Pcg64::seed_from_u64(0x6b5);
    let (mut cpu_total, mut gpu_total) = (0, 0);
    for round in 0..36 {
        let kind = round % 3;
        let solids = random_solids(&mut rng, kind);
        let e = rng.random_range(0.02..0.3);
        let shrunk: Vec<Shrunk> = solids.iter().map(|s| s.shrink(e, 1e-9).0).collect();
        for _ in 0..2 {
            let mut eye = DVec3::new(
                rng.random_range(-12.0..12.0),
                rng.random_range(-12.0..12.0),
                rng.random_range(-12.0..12.0),
            );
            if kind == 2 {
                eye.z = rng.random_range(0.1..8.0);
            }
            // Often in the plane of some shrunk faces (seen edge-on), or
            // a hair off it.
            if rng.random_bool(0.5) {
                let s = &shrunk[rng.random_range(0..shrunk.len())];
                if let Some(v) = s.vertices.first() {
                    let k = rng.random_range(0..3);
                    eye[k] = v[k] + [0.0, 1e-9, -1e-6][rng.random_range(0..3)];
                }
            }
            let n = 1 << rng.random_range(4..=8);
            let drawn = drawable(&shrunk, eye);
            let (c, g) = compare(gpu, eye, n, &drawn);
            cpu_total += c;
            gpu_total += g;
        }
    }
    report("random scenes", cpu_total, gpu_total);
}

#[test]
fn gpu_cube_maps_of_the_city_are_within_the_cpus() {
    let Some(gpu) = gpu() else { return };
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/city.obj");
    let scene = crate::scene::load(path).expect("the committed city loads");
    let oracle = ShrinkOracle::new(&scene, ShrinkParams::default()).expect("valid");
    let b = scene.bounds();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let diag = (hi - lo).length();
    let mut rng = Pcg64::seed_from_u64(0xc17);
    let (mut cpu_total, mut gpu_total) = (0, 0);
    for round in 0..8 {
        let t = DVec3::new(
            rng.random_range(0.0..1.0),
            rng.random_range(0.0..1.0),
            rng.random_range(0.0..0.3),
        );
        let eye = lo + (hi - lo) * t;
        let e = diag * rng.random_range(0.0005..0.005);
        let (set, _, _) = oracle.shrunk(e, 1e-6 * diag);
        let drawn = drawable(&set.solids, eye);
        let n = if round == 0 {
            256
        } else {
            1 << rng.random_range(4..=8)
        };
        let (c, g) = compare(gpu, eye, n, &drawn);
        cpu_total += c;
        gpu_total += g;
        if round == 0 {
            // Timing at the oracle's resolution (after a warm-up above).
            let (mut cpu_time, mut gpu_time) = (f64::INFINITY, f64::INFINITY);
            for _ in 0..3 {
                let start = Instant::now();
                let mut cpu = CubeMap::new(eye, n);
                for s in &drawn {
                    cpu.draw(s);
                }
                cpu_time = cpu_time.min(start.elapsed().as_secs_f64());
                let start = Instant::now();
                let _ = gpu.1.build(&gpu.0, eye, n, &drawn).expect("the GPU map");
                gpu_time = gpu_time.min(start.elapsed().as_secs_f64());
            }
            eprintln!(
                "city, {} solids at n = {n}, best of 3: CPU {:.1} ms, GPU {:.1} ms ({})",
                drawn.len(),
                1e3 * cpu_time,
                1e3 * gpu_time,
                gpu.0.adapter_name()
            );
        }
    }
    report("city", cpu_total, gpu_total);
}

#[test]
fn margins_and_rounding_up() {
    assert!(shrink_gpu::margin(256) > 1e-3);
    for x in [0.1, 1.0 / 3.0, 12_345.678_9, 1e-30] {
        let f = shrink_gpu::up32(x).unwrap();
        assert!(f64::from(f) >= x && f64::from(f.next_down()) < x);
    }
    assert_eq!(shrink_gpu::up32(1e300), None);
}
