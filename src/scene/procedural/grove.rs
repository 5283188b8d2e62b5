//! `grove`: a dense forest whose crowns are opaque. 16 x 16 trees on a
//! jittered 2.5 m grid over a 40 x 40 m plot, less those on a winding
//! trail through it. A crown is a shell of overlapping leaves: flat
//! triangles tangent to an ellipsoid, no two sharing an edge, but each
//! reaching past where its neighbours' planes cut it, so that the shell
//! holds the surface of a convex polyhedron and every line through the
//! crown's inside meets a leaf. From the trail, the trees a few rows in
//! are hidden behind the nearer crowns, and only many leaves together hide
//! them: the forest of papers/001 sec. 5, where the occlusion sweep must
//! fuse small occluders. Its truth is far nearer what rays find than the
//! `thicket`'s, whose crowns of random triangles are never closed (there,
//! segments aimed at each tree find ever more of them seen); here only
//! the gaps between crowns, narrowest at their tops and bottoms, let
//! aimed segments see more.

use std::f32::consts::TAU;

use glam::{Quat, Vec3};
use rand::RngExt;
use rand_pcg::Pcg64;

use super::Model;
use super::shapes::{push_box, push_cylinder};

const SIDE: usize = 16;
const STEP: f32 = 2.5;
/// Leaves (flat clusters of foliage) a crown.
const LEAVES: usize = 400;
/// A leaf's circumradius on the unit sphere: an equilateral triangle, its
/// inradius half that. The faces of the polyhedron that 400 points spread
/// on the sphere cut reach at most 0.137 from their point, under the
/// inradius 0.16 by a margin for the millimetre rounding
/// (`the_crowns_are_closed`). One triangle a leaf, not a quad: two
/// triangles of a quad rounded to the millimetre are no longer coplanar,
/// and the seam between them is then a crack that their projections from
/// a view cell leave open (each is projected alone).
const CIRCUMRADIUS: f32 = 0.32;
/// Half the trail's width at the ground: no trunk stands nearer its
/// middle line than this.
const TRAIL: f32 = 2.3;

/// The trail's middle line: `y` at `x`, a wave across the plot.
fn trail_y(x: f32) -> f32 {
    20.0 + 6.0 * (x / 7.0).sin()
}

/// Points spread evenly on the unit sphere (the Fibonacci lattice).
fn sphere_points(n: usize) -> Vec<Vec3> {
    let golden = TAU * (1.0 - 1.0 / 1.618_034);
    (0..n)
        .map(|k| {
            let z = 1.0 - (2 * k + 1) as f32 / n as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let a = golden * k as f32;
            Vec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

/// The leaf at unit point `p`, turned by `angle` about it, on the unit
/// sphere: an equilateral triangle in the plane tangent at `p`, centred
/// there, counter-clockwise seen from outside.
fn leaf(p: Vec3, angle: f32) -> [Vec3; 3] {
    let u = p.any_orthonormal_vector();
    let v = p.cross(u);
    let corner = |k: f32| {
        let (s, c) = (angle + k * TAU / 3.0).sin_cos();
        p + (u * c + v * s) * CIRCUMRADIUS
    };
    [corner(0.0), corner(1.0), corner(2.0)]
}

pub(super) fn generate(rng: &mut Pcg64) -> Model {
    let mut m = Model::default();
    let size = SIDE as f32 * STEP;
    push_box(
        m.object("ground"),
        Vec3::new(0.0, 0.0, -0.3),
        Vec3::new(size, size, 0.0),
    );
    let lattice = sphere_points(LEAVES);
    for j in 0..SIDE {
        for i in 0..SIDE {
            // Every draw is made for every grid spot, trail or not, so
            // that the trees keep their shapes whatever the trail.
            let p = Vec3::new(
                (i as f32 + 0.5) * STEP + rng.random_range(-0.5..0.5f32),
                (j as f32 + 0.5) * STEP + rng.random_range(-0.5..0.5f32),
                0.0,
            );
            let height = rng.random_range(4.0..7.0f32);
            let trunk = rng.random_range(0.12..0.2f32);
            let radius = rng.random_range(1.1..1.5f32);
            let bottom = rng.random_range(0.3..0.8f32);
            let turn = Quat::from_euler(
                glam::EulerRot::ZXZ,
                rng.random_range(0.0..TAU),
                rng.random_range(0.0..TAU),
                rng.random_range(0.0..TAU),
            );
            let angles: Vec<f32> = (0..LEAVES).map(|_| rng.random_range(0.0..TAU)).collect();
            if (p.y - trail_y(p.x)).abs() < TRAIL {
                continue;
            }
            push_cylinder(
                m.object(format!("tree_{i}_{j}/trunk")),
                p,
                Vec3::Z * height,
                trunk,
                8,
            );
            let top = height + 0.5;
            let centre = p + Vec3::Z * (0.5 * (bottom + top));
            let half = Vec3::new(radius, radius, 0.5 * (top - bottom));
            let crown = m.object(format!("tree_{i}_{j}/crown"));
            for (q, &angle) in lattice.iter().zip(&angles) {
                crown.push(leaf(turn * *q, angle).map(|v| centre + v * half));
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// Every leaf holds its face of the polyhedron that the leaves' planes
    /// bound (the face of `p` is where a line from the centre meets `p`'s
    /// plane first: the directions nearest `p`), with room to spare: so
    /// the shell, whatever the turns, holds a closed convex surface.
    #[test]
    fn the_crowns_are_closed() {
        let mut rng = Pcg64::seed_from_u64(3);
        let points = sphere_points(LEAVES);
        let mut widest = 0.0f32;
        for _ in 0..200_000 {
            let d = crate::random::uniform_direction(&mut rng);
            let p = *points
                .iter()
                .max_by(|a, b| a.dot(d).total_cmp(&b.dot(d)))
                .unwrap();
            let x = d / p.dot(d);
            widest = widest.max((x - p).length());
        }
        // The leaf's inradius, less a margin, bounds every face point's
        // distance from its point in any turn.
        assert!(widest < 0.137, "a face reaches {widest} from its point");
        assert!(0.5 * CIRCUMRADIUS > widest + 0.02);
        let [a, b, c] = leaf(Vec3::Z, 1.0);
        assert!(((b - a).length() - 3f32.sqrt() * CIRCUMRADIUS).abs() < 1e-5);
        assert!(((c - b).length() - 3f32.sqrt() * CIRCUMRADIUS).abs() < 1e-5);
        assert!(a.z == 1.0 && b.z == 1.0 && c.z == 1.0);
        assert!(
            (b - a).cross(c - a).z > 0.0,
            "counter-clockwise from outside"
        );
    }
}
