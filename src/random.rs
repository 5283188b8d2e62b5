//! The random draws every stage shares: a direction uniform on the sphere
//! and a point uniform in a box, each written once.
//!
//! Every caller passes its own seeded generator (the project seeds every
//! stream, DESIGN.md "Dependencies"), so the same seed gives the same
//! draws. The order of the draws is part of the contract: procedural
//! scenes, random views and the tests' rays depend on it, so it must not
//! change (a change would change committed scenes and measured figures).

use glam::Vec3;
use rand::{Rng, RngExt};

use crate::geom::Aabb;

/// A unit vector uniform on the sphere (Archimedes: `z` uniform in
/// `[-1, 1)`, the azimuth uniform in `[0, 2 pi)`), from two draws in that
/// order.
pub fn uniform_direction<R: Rng + ?Sized>(rng: &mut R) -> Vec3 {
    let z: f32 = rng.random_range(-1.0..1.0);
    let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * a.cos(), r * a.sin(), z)
}

/// A point uniform in the box `b`, from three draws (x, y, z).
#[inline(always)]
pub fn uniform_point<R: Rng + ?Sized>(rng: &mut R, b: &Aabb) -> Vec3 {
    // Vec3::new evaluates its arguments left to right: x, y, z.
    b.lerp(Vec3::new(rng.random(), rng.random(), rng.random()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    #[test]
    fn directions_are_unit_and_spread_evenly() {
        let mut rng = Pcg64::seed_from_u64(5);
        let n = 20_000;
        let mut octants = [0u32; 8];
        let mut mean = Vec3::ZERO;
        for _ in 0..n {
            let d = uniform_direction(&mut rng);
            assert!((d.length() - 1.0).abs() < 1e-5, "{d}");
            mean += d;
            let k =
                (d.x > 0.0) as usize | ((d.y > 0.0) as usize) << 1 | ((d.z > 0.0) as usize) << 2;
            octants[k] += 1;
        }
        assert!((mean / n as f32).length() < 0.03, "{mean}");
        for c in octants {
            assert!(
                (c as f32 - n as f32 / 8.0).abs() < 0.1 * n as f32 / 8.0,
                "{octants:?}"
            );
        }
    }

    #[test]
    fn points_fall_in_the_box() {
        let mut rng = Pcg64::seed_from_u64(6);
        let b = Aabb::new(Vec3::new(-1.0, 2.0, 3.0), Vec3::new(0.0, 5.0, 3.5));
        for _ in 0..1000 {
            let p = uniform_point(&mut rng, &b);
            assert!(b.contains(p), "{p}");
        }
    }
}
