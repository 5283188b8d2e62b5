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
//!   The same segments can be drawn target first
//!   ([`object_sample_from_target`]) or target first and aimed at the
//!   directions that reach the box ([`object_sample_aimed`]), which are
//!   rejected far less in small cells; [`AdaptiveSampler`] picks per
//!   (cell, object).
//!
//! [`reachable`] is the geometric test that decides "invisible" without a
//! ray when no direction from the cell's box to O's bounding box lies in
//! the angular box.

use glam::Vec3;
use rand::{Rng, RngExt};

use crate::geom::cell::{
    AngularBox, Cell, DIMS, PHI, THETA, angles_to_direction, direction_bounds, directions_meet,
};
use crate::geom::{Aabb, trig};
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
#[inline(always)]
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
    ray_into_target(&cell.space(), q, d, rng)
}

/// An object sample drawn target first and aimed: q uniform on the
/// object's surface, a direction d uniform (in solid angle) over the part
/// of the cell's angular box that can reach q from the cell's box (the
/// angular box cut to [`direction_bounds`] from the box to q), and p
/// uniform on the part of the line `q - t d` inside the box; `None`
/// (rejected) when no direction of the angular box reaches q or the line
/// misses the box. Its rays are the target-first draws' (every ray of the
/// cell that reaches the surface can be drawn), but it is rarely
/// rejected where both other kinds nearly always are: objects that only
/// the edge of a narrow angular box reaches.
#[inline(always)]
pub fn object_sample_aimed<R: Rng + ?Sized>(
    scene: &Scene,
    cell: &Cell,
    object: usize,
    rng: &mut R,
) -> Option<Ray> {
    let q = scene.sample_surface(object, rng);
    let space = cell.space();
    let (mut t0, mut t1) = (cell.lo[THETA], cell.hi[THETA]);
    let (mut p0, mut p1) = (cell.lo[PHI], cell.hi[PHI]);
    if let Some((b0, b1, c0, c1)) = direction_bounds(&space, &Aabb::new(q, q)) {
        p0 = p0.max(c0);
        p1 = p1.min(c1);
        if b0 <= b1 {
            t0 = t0.max(b0);
            t1 = t1.min(b1);
        } else {
            // The reaching directions wrap: [b0, pi] u [-pi, b1]; keep the
            // part of the cell's range in each, one drawn by its length.
            let hi_part = (t0.max(b0), t1);
            let lo_part = (t0, t1.min(b1));
            let len = |r: (f32, f32)| (r.1 - r.0).max(0.0);
            let (lh, ll) = (len(hi_part), len(lo_part));
            if lh + ll <= 0.0 {
                return None;
            }
            (t0, t1) = if rng.random::<f32>() * (lh + ll) < lh {
                hi_part
            } else {
                lo_part
            };
        }
        if t0 > t1 || p0 > p1 {
            return None;
        }
    }
    let theta = t0 + rng.random::<f32>() * (t1 - t0);
    let (_, [k0, k1]) = trig::sin_cos([p0, p1]);
    let phi = trig::acos(k0 + rng.random::<f32>() * (k1 - k0));
    let d = angles_to_direction(theta, phi.clamp(p0, p1));
    ray_into_target(&space, q, d, rng)
}

/// The segment from a point p uniform on the part of the line `q - t d`
/// (t > 0) inside `space` to q, or `None` when the line misses the box.
#[inline(always)]
fn ray_into_target<R: Rng + ?Sized>(space: &Aabb, q: Vec3, d: Vec3, rng: &mut R) -> Option<Ray> {
    // Where q - t d is inside the box, t >= 0 (slabs).
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
/// origin-first ([`object_sample`]) and aimed target-first
/// ([`object_sample_aimed`]) draws by their acceptance so far: each
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
    /// least 64 draws, under 1 in 16 accepted. Deciding such an object
    /// would take thousands of draws per ray; the builder keeps it instead.
    pub fn hopeless(&self) -> bool {
        let t = self.tries();
        t >= 64 && self.accepted() * 16 < t
    }

    /// One draw: a ray, or `None` when it was rejected.
    #[inline(always)]
    pub fn draw<R: Rng + ?Sized>(
        &mut self,
        scene: &Scene,
        cell: &Cell,
        object: usize,
        rng: &mut R,
    ) -> Option<Ray> {
        let total = self.tries[0] + self.tries[1];
        let k = if total < 16 {
            (total % 2) as usize
        } else {
            // Laplace estimates (accepted + 1) / (tries + 2) compared
            // exactly, by cross-multiplying (no divisions).
            let odds = |k: usize, l: usize| {
                (u64::from(self.accepted[k]) + 1) * (u64::from(self.tries[l]) + 2)
            };
            let better = if odds(1, 0) > odds(0, 1) { 1 } else { 0 };
            if total.is_multiple_of(16) {
                1 - better
            } else {
                better
            }
        };
        let r = if k == 0 {
            object_sample_in(scene, cell, &self.angles, object, rng)
        } else {
            object_sample_aimed(scene, cell, object, rng)
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

    /// A plate at x = 5 facing a thin slab of a cell (z within 5 cm of
    /// 0) whose angular box is a sliver of theta (0 to 0.02): few pairs of
    /// a point of the slab and a point of the plate have a direction in
    /// the sliver (origin first), and few directions of the sliver reach
    /// the slab from a point of the plate (target first), so both draws are
    /// nearly always rejected, and the builder used to keep such objects
    /// untested. Aimed draws cut the sliver to the directions that reach
    /// the slab and are rarely rejected; every ray drawn is a ray of the
    /// cell to the plate.
    #[test]
    fn aimed_samples_reach_what_both_other_draws_miss() {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("wall");
        let (p0, p1, p2, p3) = (
            Vec3::new(5.0, -1.0, -1.0),
            Vec3::new(5.0, 1.0, -1.0),
            Vec3::new(5.0, 1.0, 1.0),
            Vec3::new(5.0, -1.0, 1.0),
        );
        b.push_triangle([p0, p1, p2]).unwrap();
        b.push_triangle([p0, p2, p3]).unwrap();
        let s = b.finish(Path::new("wall")).unwrap();
        let mut cell = Cell::all_directions(Aabb::new(
            Vec3::new(-1.0, -1.0, -0.05),
            Vec3::new(1.0, 1.0, 0.05),
        ));
        cell.lo[THETA] = 0.0;
        cell.hi[THETA] = 0.02;
        let draws = 4000;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut aimed = 0;
        for _ in 0..draws {
            if let Some(r) = object_sample_aimed(&s, &cell, 0, &mut rng) {
                aimed += 1;
                assert!(cell.space().contains(r.origin), "{r:?}");
                assert!((r.at(1.0).x - 5.0).abs() < 1e-4);
                let (t, p) = direction_to_angles(r.dir);
                assert!((-1e-4..=0.02 + 1e-4).contains(&t), "{t} {p}");
            }
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let plain = (0..draws)
            .filter(|_| object_sample_from_target(&s, &cell, 0, &mut rng).is_some())
            .count();
        let origin_first = (0..draws)
            .filter(|_| object_sample(&s, &cell, 0, &mut rng).is_some())
            .count();
        assert!(plain * 16 < draws, "plain target-first accepted {plain}");
        assert!(
            origin_first * 16 < draws,
            "origin first accepted {origin_first}"
        );
        assert!(aimed * 4 > draws, "aimed accepted {aimed} of {draws}");
        // Through the sampler: no longer hopeless.
        let mut sampler = AdaptiveSampler::new(&cell);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(6);
        for _ in 0..256 {
            sampler.draw(&s, &cell, 0, &mut rng);
        }
        assert!(!sampler.hopeless());
    }

    /// Aimed samples cover the rays that reach the target: from a cell
    /// whose box sees the plate over its whole angular box, the directions
    /// drawn fill the part of the box that reaches the plate.
    #[test]
    fn aimed_samples_fill_the_directions_that_reach() {
        let s = plate_above();
        let mut cell = Cell::all_directions(Aabb::new(Vec3::splat(-0.5), Vec3::splat(0.5)));
        cell.hi[PHI] = 0.6;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut bins = [0u32; 8];
        let mut accepted = 0;
        for _ in 0..8000 {
            if let Some(r) = object_sample_aimed(&s, &cell, 0, &mut rng) {
                accepted += 1;
                let (t, _) = direction_to_angles(r.dir);
                bins[(((t + PI) / (2.0 * PI) * 8.0) as usize).min(7)] += 1;
            }
        }
        assert!(accepted > 2000, "{accepted}");
        // The plate is square and centred: every octant of theta is drawn.
        assert!(bins.iter().all(|&b| b > accepted / 16), "{bins:?}");
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
