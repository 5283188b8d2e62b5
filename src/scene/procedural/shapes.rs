//! Closed low-polygon solids that the procedural scenes are made of. All
//! are triangle soups appended to a `Vec<Triangle>`; z is up.

use std::f32::consts::TAU;

use glam::Vec3;

use crate::scene::Triangle;

/// An axis-aligned box `[min, max]`: 12 triangles.
pub fn push_box(tris: &mut Vec<Triangle>, min: Vec3, max: Vec3) {
    let c = |i: usize| {
        Vec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    };
    // Each face as a quad of corner indices (bit 0 = x, 1 = y, 2 = z),
    // counter-clockwise seen from outside.
    const QUADS: [[usize; 4]; 6] = [
        [0, 2, 3, 1], // -z
        [4, 5, 7, 6], // +z
        [0, 1, 5, 4], // -y
        [2, 6, 7, 3], // +y
        [0, 4, 6, 2], // -x
        [1, 3, 7, 5], // +x
    ];
    for [a, b, cc, d] in QUADS {
        tris.push([c(a), c(b), c(cc)]);
        tris.push([c(a), c(cc), c(d)]);
    }
}

/// A box given by its centre and full size.
pub fn push_box_at(tris: &mut Vec<Triangle>, center: Vec3, size: Vec3) {
    push_box(tris, center - size * 0.5, center + size * 0.5);
}

/// Two unit vectors perpendicular to `axis` and to each other.
fn basis(axis: Vec3) -> (Vec3, Vec3) {
    let a = axis.normalize();
    let u = a.any_orthonormal_vector();
    (u, a.cross(u))
}

/// A closed cylinder from `base` along `axis` (its length is the height),
/// with `segments` sides: `4 * segments` triangles.
pub fn push_cylinder(tris: &mut Vec<Triangle>, base: Vec3, axis: Vec3, radius: f32, segments: u32) {
    let (u, v) = basis(axis);
    let top = base + axis;
    let ring = |k: u32| {
        let a = TAU * k as f32 / segments as f32;
        (u * a.cos() + v * a.sin()) * radius
    };
    for k in 0..segments {
        let (r0, r1) = (ring(k), ring(k + 1));
        tris.push([base + r0, base + r1, top + r1]);
        tris.push([base + r0, top + r1, top + r0]);
        tris.push([base, base + r1, base + r0]);
        tris.push([top, top + r0, top + r1]);
    }
}

/// A closed cone from a disc at `base` to the apex `base + axis`:
/// `2 * segments` triangles.
pub fn push_cone(tris: &mut Vec<Triangle>, base: Vec3, axis: Vec3, radius: f32, segments: u32) {
    let (u, v) = basis(axis);
    let apex = base + axis;
    for k in 0..segments {
        let a0 = TAU * k as f32 / segments as f32;
        let a1 = TAU * (k + 1) as f32 / segments as f32;
        let r0 = base + (u * a0.cos() + v * a0.sin()) * radius;
        let r1 = base + (u * a1.cos() + v * a1.sin()) * radius;
        tris.push([r0, r1, apex]);
        tris.push([base, r1, r0]);
    }
}

/// A UV sphere with `rings` latitude bands and `segments` longitudes,
/// scaled by `radii` per axis (an ellipsoid): `2 * segments * (rings - 1)`
/// triangles.
pub fn push_ellipsoid(
    tris: &mut Vec<Triangle>,
    center: Vec3,
    radii: Vec3,
    rings: u32,
    segments: u32,
) {
    let p = |i: u32, k: u32| {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        let ph = TAU * k as f32 / segments as f32;
        center + radii * Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos())
    };
    for i in 0..rings {
        for k in 0..segments {
            let (a, b, c, d) = (p(i, k), p(i + 1, k), p(i + 1, k + 1), p(i, k + 1));
            if i != 0 {
                tris.push([a, b, d]);
            }
            if i != rings - 1 {
                tris.push([b, c, d]);
            }
        }
    }
}

/// Appends `count` leaves to `tris`: triangles of two random sides of
/// length in `size`, at random directions from a corner drawn uniformly in
/// the ellipsoid of `centre` and semi-axes `half` (the crowns of the
/// forests; the draws are made in a fixed order, so a seed gives the same
/// leaves).
pub fn push_leaves<R: rand::Rng + ?Sized>(
    tris: &mut Vec<Triangle>,
    rng: &mut R,
    centre: Vec3,
    half: Vec3,
    count: usize,
    size: std::ops::Range<f32>,
) {
    use rand::RngExt;
    let target = tris.len() + count;
    while tris.len() < target {
        let q = Vec3::new(
            rng.random_range(-1.0..1.0f32),
            rng.random_range(-1.0..1.0f32),
            rng.random_range(-1.0..1.0f32),
        );
        if q.length_squared() > 1.0 {
            continue;
        }
        let c = centre + q * half;
        let (a, b) = (
            crate::random::uniform_direction(rng),
            crate::random::uniform_direction(rng),
        );
        let s = rng.random_range(size.clone());
        tris.push([c, c + a * s, c + b * s]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{is_degenerate, triangle_area};

    fn area(tris: &[Triangle]) -> f64 {
        tris.iter().map(triangle_area).sum()
    }

    #[test]
    fn shapes_have_the_right_counts_and_areas() {
        let mut t = Vec::new();
        push_box(&mut t, Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(t.len(), 12);
        assert!((area(&t) - 22.0).abs() < 1e-9);

        let mut t = Vec::new();
        push_cylinder(&mut t, Vec3::ZERO, Vec3::Z * 2.0, 1.0, 64);
        assert_eq!(t.len(), 256);
        let exact = 2.0 * std::f64::consts::PI * (1.0 + 2.0);
        assert!((area(&t) - exact).abs() / exact < 0.01);

        let mut t = Vec::new();
        push_cone(&mut t, Vec3::ZERO, Vec3::X, 1.0, 8);
        assert_eq!(t.len(), 16);

        let mut t = Vec::new();
        push_ellipsoid(&mut t, Vec3::ZERO, Vec3::ONE, 16, 32);
        assert_eq!(t.len(), 2 * 32 * 15);
        let exact = 4.0 * std::f64::consts::PI;
        assert!((area(&t) - exact).abs() / exact < 0.02);
        assert!(t.iter().all(|x| !is_degenerate(x)));
    }
}
