//! Ray samples of view cells (papers/003 sec. 5, DESIGN.md "Sampling").
//!
//! Two kinds:
//! - a *cell ray*: a uniform point of the 5D cell (origin uniform in the
//!   box, direction uniform in solid angle over the angular box), traced to
//!   infinity; its closest hit proves that object visible from the cell.
//!   The builder caches them to score splits.
//! - an *object sample* for object O: origin p uniform in the cell's box,
//!   target q uniform on O's surface, the segment p -> q (to `1 +`
//!   [`SEGMENT_SLACK`]). When its direction leaves the cell's angular box
//!   the pair is *rejected*: no evidence either way, never a miss. It is a
//!   hit when its closest hit is O; whatever it hits is proven visible.
//!
//! [`reachable`] is the geometric test that decides "invisible" without a
//! ray when no direction from the cell's box to O's bounding box lies in
//! the angular box.

use glam::Vec3;
use rand::{Rng, RngExt};

use crate::geom::Aabb;
use crate::geom::cell::{
    AngularBox, Cell, DIMS, angles_to_direction, direction_bounds, directions_meet,
};
use crate::random::uniform_point;
use crate::scene::Scene;
use crate::trace::Ray;

/// How far past the target an object sample reaches, relative to its
/// length: a hit on O at `t` slightly above 1 (rounding of the surface
/// point) still counts.
pub const SEGMENT_SLACK: f32 = 1e-4;

/// A uniform point of `cell`: (x, y, z, theta, phi).
pub fn cell_point<R: Rng + ?Sized>(cell: &Cell, rng: &mut R) -> [f32; DIMS] {
    cell.sample([
        rng.random(),
        rng.random(),
        rng.random(),
        rng.random(),
        rng.random(),
    ])
}

/// The infinite ray of a cell point.
pub fn cell_ray(p: &[f32; DIMS]) -> Ray {
    Ray::new(Vec3::new(p[0], p[1], p[2]), angles_to_direction(p[3], p[4]))
}

/// An object sample for `object` from `cell`, or `None` when its direction
/// falls outside the cell's angular box (rejected).
pub fn object_sample<R: Rng + ?Sized>(
    scene: &Scene,
    cell: &Cell,
    object: usize,
    rng: &mut R,
) -> Option<Ray> {
    object_sample_in(scene, cell, &cell.angular_box(), object, rng)
}

/// [`object_sample`] with the cell's angular box test computed once.
fn object_sample_in<R: Rng + ?Sized>(
    scene: &Scene,
    cell: &Cell,
    angles: &AngularBox,
    object: usize,
    rng: &mut R,
) -> Option<Ray> {
    let space = cell.space();
    let p = uniform_point(rng, &space);
    let q = scene.sample_surface(object, rng);
    let d = q - p;
    (d != Vec3::ZERO && angles.contains(d))
        .then(|| Ray::segment(p, q).with_tmax(1.0 + SEGMENT_SLACK))
}

/// An object sample drawn target first: q uniform on the object's surface,
/// a direction d uniform (in solid angle) over the cell's angular box, and
/// p uniform on the part of the line `q - t d` (t > 0) inside the cell's
/// box; `None` (rejected) when that line misses the box. Every ray of the
/// cell that reaches the surface can be drawn, so a miss is evidence as
/// good as an origin-first sample's; what differs is which pairs are
/// rejected: few when the angular box is small and the spatial box large,
/// where origin-first samples are mostly rejected.
pub fn object_sample_from_target<R: Rng + ?Sized>(
    scene: &Scene,
    cell: &Cell,
    object: usize,
    rng: &mut R,
) -> Option<Ray> {
    let q = scene.sample_surface(object, rng);
    let a = cell.sample([0.0, 0.0, 0.0, rng.random(), rng.random()]);
    let d = angles_to_direction(a[3], a[4]);
    // Where q - t d is inside the box, t >= 0 (slabs).
    let space = cell.space();
    let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
    for k in 0..3 {
        let (o, v) = (q[k], -d[k]);
        if v == 0.0 {
            if o < space.min[k] || o > space.max[k] {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((space.min[k] - o) / v, (space.max[k] - o) / v);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    if t1 <= t0 || t1.is_nan() {
        return None;
    }
    let t = t0 + rng.random::<f32>() * (t1 - t0);
    let p = (q - d * t).clamp(space.min, space.max);
    (p != q).then(|| Ray::segment(p, q).with_tmax(1.0 + SEGMENT_SLACK))
}

/// Draws object samples for one (cell, object), choosing between
/// origin-first ([`object_sample`]) and target-first
/// ([`object_sample_from_target`]) draws by their acceptance so far: each
/// is tried at least 8 times, then the better one (by Laplace estimate) is
/// used, the other still one draw in 16.
#[derive(Clone, Copy, Debug)]
pub struct AdaptiveSampler {
    angles: AngularBox,
    tries: [u32; 2],
    accepted: [u32; 2],
}

impl AdaptiveSampler {
    /// A sampler for objects seen from `cell`.
    pub fn new(cell: &Cell) -> Self {
        Self {
            angles: cell.angular_box(),
            tries: [0; 2],
            accepted: [0; 2],
        }
    }

    /// Draws made so far.
    pub fn tries(&self) -> u32 {
        self.tries[0] + self.tries[1]
    }

    /// Draws accepted so far.
    pub fn accepted(&self) -> u32 {
        self.accepted[0] + self.accepted[1]
    }

    /// Whether both kinds of draw are nearly always rejected: after at
    /// least 128 draws, under 1 in 32 accepted. Deciding such an object
    /// would take thousands of draws per ray; the builder keeps it instead.
    pub fn hopeless(&self) -> bool {
        let t = self.tries();
        t >= 64 && self.accepted() * 16 < t
    }

    /// One draw: a ray, or `None` when it was rejected.
    pub fn draw<R: Rng + ?Sized>(
        &mut self,
        scene: &Scene,
        cell: &Cell,
        object: usize,
        rng: &mut R,
    ) -> Option<Ray> {
        let total = self.tries[0] + self.tries[1];
        let rate = |k: usize| (self.accepted[k] as f64 + 1.0) / (self.tries[k] as f64 + 2.0);
        let k = if total < 16 {
            (total % 2) as usize
        } else {
            let better = if rate(1) > rate(0) { 1 } else { 0 };
            if total.is_multiple_of(16) {
                1 - better
            } else {
                better
            }
        };
        let r = if k == 0 {
            object_sample_in(scene, cell, &self.angles, object, rng)
        } else {
            object_sample_from_target(scene, cell, object, rng)
        };
        self.tries[k] += 1;
        self.accepted[k] += r.is_some() as u32;
        r
    }
}

/// Whether some direction from the cell's box to `bounds` lies in the
/// cell's angular box (conservative: false only when none can).
pub fn reachable(cell: &Cell, bounds: &Aabb) -> bool {
    directions_meet(cell, direction_bounds(&cell.space(), bounds))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::cell::{PHI, THETA, direction_to_angles};
    use crate::scene::{SceneBuilder, SceneFormat};
    use rand::SeedableRng;
    use std::f32::consts::PI;
    use std::path::Path;

    fn plate_above() -> Scene {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("plate");
        let z = 5.0;
        b.push_triangle([
            Vec3::new(-1.0, -1.0, z),
            Vec3::new(1.0, -1.0, z),
            Vec3::new(1.0, 1.0, z),
        ])
        .unwrap();
        b.push_triangle([
            Vec3::new(-1.0, -1.0, z),
            Vec3::new(1.0, 1.0, z),
            Vec3::new(-1.0, 1.0, z),
        ])
        .unwrap();
        b.finish(Path::new("plate")).unwrap()
    }

    #[test]
    fn object_samples_start_in_the_cell_and_end_on_the_object() {
        let s = plate_above();
        let cell = Cell::all_directions(Aabb::new(Vec3::splat(-0.5), Vec3::splat(0.5)));
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        for _ in 0..1000 {
            let r = object_sample(&s, &cell, 0, &mut rng).expect("all directions accepted");
            assert!(cell.space().contains(r.origin));
            assert!((r.at(1.0).z - 5.0).abs() < 1e-5);
        }
    }

    #[test]
    fn rejected_outside_the_angular_box_and_unreachable_by_geometry() {
        let s = plate_above();
        let mut down = Cell::all_directions(Aabb::new(Vec3::splat(-0.5), Vec3::splat(0.5)));
        down.lo[PHI] = PI / 2.0;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(2);
        assert!((0..1000).all(|_| object_sample(&s, &down, 0, &mut rng).is_none()));
        assert!(!reachable(&down, &s.objects()[0].bounds));
        let mut up = down;
        up.lo[PHI] = 0.0;
        up.hi[PHI] = 0.4;
        assert!(reachable(&up, &s.objects()[0].bounds));
        let mut side = up;
        side.lo[THETA] = 0.0;
        side.hi[THETA] = 0.1;
        assert!(reachable(&side, &s.objects()[0].bounds));
    }

    #[test]
    fn target_first_samples_are_rays_of_the_cell_to_the_object() {
        let s = plate_above();
        let mut cell = Cell::all_directions(Aabb::new(Vec3::splat(-3.0), Vec3::splat(3.0)));
        cell.lo[PHI] = 0.2;
        cell.hi[PHI] = 0.5;
        cell.lo[THETA] = 1.0;
        cell.hi[THETA] = 2.0;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        let mut accepted = 0;
        for _ in 0..2000 {
            if let Some(r) = object_sample_from_target(&s, &cell, 0, &mut rng) {
                accepted += 1;
                assert!(cell.space().contains(r.origin), "{r:?}");
                assert!((r.at(1.0).z - 5.0).abs() < 1e-4);
                let (t, p) = direction_to_angles(r.dir);
                assert!(
                    cell.contains_angles(t, p) || (t - 1.0).abs() < 1e-4 || (p - 0.2).abs() < 1e-3,
                    "{t} {p}"
                );
            }
        }
        // Origin first, almost every pair would be rejected here.
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        let origin_first = (0..2000)
            .filter(|_| object_sample(&s, &cell, 0, &mut rng).is_some())
            .count();
        assert!(accepted > 4 * origin_first, "{accepted} vs {origin_first}");
    }

    #[test]
    fn cell_rays_are_in_the_cell() {
        let mut cell = Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::ONE));
        cell.lo[THETA] = 1.0;
        cell.hi[THETA] = 1.5;
        cell.lo[PHI] = 0.5;
        cell.hi[PHI] = 0.7;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for _ in 0..1000 {
            let p = cell_point(&cell, &mut rng);
            assert!(cell.contains(p));
            let r = cell_ray(&p);
            let (t, ph) = direction_to_angles(r.dir);
            assert!((t - p[3]).abs() < 1e-5 && (ph - p[4]).abs() < 1e-3);
        }
    }
}
