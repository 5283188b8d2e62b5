//! `city`: a 5 x 5 grid of blocks separated by 14 m streets; each block is
//! cut into 2 x 2 or 3 x 2 lots holding one building each (a box of
//! log-normal height between 6 and 120 m, some with a setback upper part
//! and rooftop plant), and street lamps line the streets. Street-level views
//! see the street they stand in and its crossings; tall buildings stick out
//! above the others.

use glam::Vec3;
use rand::RngExt;
use rand_pcg::Pcg64;

use super::Model;
use super::shapes::{push_box, push_cylinder};

const BLOCKS: usize = 5;
const BLOCK: f32 = 50.0;
const STREET: f32 = 14.0;

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// A standard normal sample (Box-Muller), from the one seeded stream.
fn normal(rng: &mut Pcg64) -> f32 {
    let u1 = rng.random_range(f32::EPSILON..1.0f32);
    let u2 = rng.random::<f32>();
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

pub(super) fn generate(rng: &mut Pcg64) -> Model {
    let mut m = Model::default();
    let size = BLOCKS as f32 * (BLOCK + STREET) + STREET;
    push_box(m.object("ground"), v(0.0, 0.0, -0.5), v(size, size, 0.0));
    for bi in 0..BLOCKS {
        for bj in 0..BLOCKS {
            let o = v(
                STREET + bi as f32 * (BLOCK + STREET),
                STREET + bj as f32 * (BLOCK + STREET),
                0.0,
            );
            let (nx, ny) = if rng.random_bool(0.5) { (3, 2) } else { (2, 3) };
            let (lx, ly) = (BLOCK / nx as f32, BLOCK / ny as f32);
            for i in 0..nx {
                for j in 0..ny {
                    let inset = rng.random_range(1.0..3.0f32);
                    let a = o + v(i as f32 * lx + inset, j as f32 * ly + inset, 0.0);
                    let b = o + v(
                        (i + 1) as f32 * lx - inset,
                        (j + 1) as f32 * ly - inset,
                        0.0,
                    );
                    let h = (20f32.ln() + 0.6 * normal(rng)).exp().clamp(6.0, 120.0);
                    let tris = m.object(format!("block_{bi}_{bj}/building_{i}_{j}"));
                    push_box(tris, a, b.with_z(h));
                    if h > 30.0 && rng.random_bool(0.6) {
                        let c = (a + b) * 0.5;
                        let half = (b - a) * 0.3;
                        let top = h + rng.random_range(0.15..0.4f32) * h;
                        push_box(tris, (c - half).with_z(h), (c + half).with_z(top));
                    } else if rng.random_bool(0.5) {
                        let c = a + (b - a) * rng.random_range(0.2..0.6f32);
                        push_box(tris, c.with_z(h), c + v(4.0, 3.0, h + 2.5));
                    }
                }
            }
        }
    }
    // Street lamps along the x-running streets, on both sides.
    let mut k = 0;
    for sj in 0..=BLOCKS {
        let y = sj as f32 * (BLOCK + STREET);
        for side in [1.5, STREET - 1.5] {
            for i in 0..BLOCKS {
                let x = STREET + i as f32 * (BLOCK + STREET) + BLOCK * 0.5;
                let tris = m.object(format!("lamp_{k}"));
                push_cylinder(tris, v(x, y + side, 0.0), Vec3::Z * 6.0, 0.12, 6);
                push_box(
                    tris,
                    v(x - 0.3, y + side - 0.3, 6.0),
                    v(x + 0.3, y + side + 0.3, 6.3),
                );
                k += 1;
            }
        }
    }
    m
}
