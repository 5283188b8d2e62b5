//! 5D view cells: boxes over (x, y, z, theta, phi), the space of viewing
//! rays of papers/003 sec. 3, with the parametrisation and measure of
//! DESIGN.md ("Facts the papers do not state plainly").
//!
//! - A direction d maps to `theta = atan2(d.y, d.x)` in [-pi, pi] and
//!   `phi = acos(d.z / |d|)` in [0, pi] (z is up: phi is the angle from +z).
//! - The measure of a cell is its 3D volume times its solid angle
//!   `(theta1 - theta0) * (cos phi0 - cos phi1)`, so a phi split at the
//!   midpoint is not balanced.
//! - Cells are half-open, `[lo, hi)` in every dimension, except that the
//!   root's upper bounds are closed (a split gives `[lo, v)` and `[v, hi)`),
//!   so every ray of the root lies in exactly one leaf.
//!
//! Split values lie on a q-bit grid of the node's range (papers/003 sec. 6,
//! DESIGN.md "Coding"): `lo + (hi - lo) * (k / 2^q)` for `0 < k < 2^q`,
//! evaluated in f32 by [`grid_value`] in exactly this order, so that a
//! decoder that replays the splits gets the very same cells.

use std::f32::consts::PI;

use glam::Vec3;

use super::{Aabb, trig};

/// The number of dimensions of view space.
pub const DIMS: usize = 5;

/// The index of theta among the dimensions (x, y, z come first).
pub const THETA: usize = 3;

/// The index of phi among the dimensions.
pub const PHI: usize = 4;

/// The names of the dimensions, for messages and reports.
pub const DIM_NAMES: [&str; DIMS] = ["x", "y", "z", "theta", "phi"];

/// The (theta, phi) of a direction (need not be unit length; must not be
/// zero).
pub fn direction_to_angles(d: Vec3) -> (f32, f32) {
    // atan2, not acos(z / |d|): acos loses ~3.5e-4 rad next to the poles.
    let [theta, phi] = trig::atan2([d.y, trig::hypot(d.x, d.y)], [d.x, d.z]);
    (theta, phi)
}

/// The unit direction of (theta, phi).
#[inline(always)]
pub fn angles_to_direction(theta: f32, phi: f32) -> Vec3 {
    let ([st, sp], [ct, cp]) = trig::sin_cos([theta, phi]);
    Vec3::new(sp * ct, sp * st, cp)
}

/// The split value `k / 2^bits` of the way from `lo` to `hi`, in the one
/// f32 evaluation order that the builder and the decoder share.
pub fn grid_value(lo: f32, hi: f32, k: u32, bits: u32) -> f32 {
    lo + (hi - lo) * (k as f32 / (1u32 << bits) as f32)
}

/// A box in view space: positions in `space`, directions with theta in
/// `[lo[3], hi[3])` and phi in `[lo[4], hi[4])`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// Lower bounds of (x, y, z, theta, phi).
    pub lo: [f32; DIMS],
    /// Upper bounds of (x, y, z, theta, phi).
    pub hi: [f32; DIMS],
}

impl Cell {
    /// The cell of all rays starting in `space`: every direction.
    pub fn all_directions(space: Aabb) -> Self {
        Self {
            lo: [space.min.x, space.min.y, space.min.z, -PI, 0.0],
            hi: [space.max.x, space.max.y, space.max.z, PI, PI],
        }
    }

    /// The spatial box.
    pub fn space(&self) -> Aabb {
        Aabb::new(
            Vec3::new(self.lo[0], self.lo[1], self.lo[2]),
            Vec3::new(self.hi[0], self.hi[1], self.hi[2]),
        )
    }

    /// The extent in dimension `dim`.
    pub fn width(&self, dim: usize) -> f32 {
        self.hi[dim] - self.lo[dim]
    }

    /// The solid angle of the angular box, in steradians.
    pub fn solid_angle(&self) -> f64 {
        let (p0, p1) = (self.lo[PHI] as f64, self.hi[PHI] as f64);
        (self.hi[THETA] as f64 - self.lo[THETA] as f64) * (p0.cos() - p1.cos())
    }

    /// The measure: 3D volume times solid angle.
    pub fn measure(&self) -> f64 {
        let v: f64 = (0..3).map(|d| self.width(d) as f64).product();
        v * self.solid_angle()
    }

    /// The two halves of a split of dimension `dim` at `value`:
    /// `[lo, value)` and `[value, hi)`.
    pub fn split(&self, dim: usize, value: f32) -> (Cell, Cell) {
        let mut a = *self;
        let mut b = *self;
        a.hi[dim] = value;
        b.lo[dim] = value;
        (a, b)
    }

    /// Whether the ray point `p` (x, y, z, theta, phi) lies in the closed
    /// cell.
    pub fn contains(&self, p: [f32; DIMS]) -> bool {
        (0..DIMS).all(|d| p[d] >= self.lo[d] && p[d] <= self.hi[d])
    }

    /// The point of the cell at relative coordinates `u` (each in
    /// `[0, 1)`), uniform with respect to the measure: positions and theta
    /// linear, phi through `cos phi` linear. Uniform `u` gives a uniform
    /// ray of the cell.
    pub fn sample(&self, u: [f32; DIMS]) -> [f32; DIMS] {
        let mut p = [0.0; DIMS];
        for d in 0..PHI {
            p[d] = self.lo[d] + u[d] * self.width(d);
        }
        let (_, [c0, c1]) = trig::sin_cos([self.lo[PHI], self.hi[PHI]]);
        let c = c0 + u[PHI] * (c1 - c0);
        p[PHI] = trig::acos(c).clamp(self.lo[PHI], self.hi[PHI]);
        p
    }

    /// Whether the direction angles `(theta, phi)` lie in the angular box
    /// (closed).
    pub fn contains_angles(&self, theta: f32, phi: f32) -> bool {
        theta >= self.lo[THETA]
            && theta <= self.hi[THETA]
            && phi >= self.lo[PHI]
            && phi <= self.hi[PHI]
    }
}

/// A cell's angular box as a fast test on direction vectors: phi by
/// comparing `d.z / |d|` with precomputed cosines, theta by `atan2` only
/// when the box does not span all of it. Agrees with
/// [`Cell::contains_angles`] up to rounding at the boundary.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AngularBox {
    /// cos of the upper phi bound (the smaller cosine).
    cos_min: f32,
    /// cos of the lower phi bound.
    cos_max: f32,
    /// The theta range, `None` when it is all of [-pi, pi].
    theta: Option<(f32, f32)>,
}

impl AngularBox {
    /// Whether direction `d` (non-zero) lies in the box.
    #[inline(always)]
    pub fn contains(&self, d: Vec3) -> bool {
        let c = d.z / d.length();
        if c < self.cos_min || c > self.cos_max {
            return false;
        }
        match self.theta {
            None => true,
            Some((t0, t1)) => {
                let [t] = trig::atan2([d.y], [d.x]);
                t >= t0 && t <= t1
            }
        }
    }
}

impl Cell {
    /// The angular box as an [`AngularBox`] test.
    pub fn angular_box(&self) -> AngularBox {
        let full = self.lo[THETA] <= -PI && self.hi[THETA] >= PI;
        AngularBox {
            cos_min: if self.hi[PHI] >= PI {
                -1.0
            } else {
                trig::cos(self.hi[PHI])
            },
            cos_max: if self.lo[PHI] <= 0.0 {
                1.0
            } else {
                trig::cos(self.lo[PHI])
            },
            theta: (!full).then_some((self.lo[THETA], self.hi[THETA])),
        }
    }
}

/// A conservative box around the directions `q - p` for `p` in `from` and
/// `q` in `to`: `(theta_lo, theta_hi, phi_lo, phi_hi)`, or `None` when the
/// boxes overlap and every direction is possible. The theta interval may
/// wrap: `theta_lo > theta_hi` means `[theta_lo, pi] u [-pi, theta_hi]`.
///
/// The difference vectors fill the box `M = to - from`; theta is bounded
/// by the corners of M's xy rectangle (which subtends less than pi when it
/// misses the origin), and `cos phi = z / |v|` is monotone in z and in the
/// xy distance, which vary independently over M, so its extremes are
/// exact. Intervals are widened by 1e-4 rad against rounding; phi is
/// computed as `atan2(rho, z)`, accurate next to the poles.
#[inline(always)]
pub fn direction_bounds(from: &Aabb, to: &Aabb) -> Option<(f32, f32, f32, f32)> {
    const PAD: f32 = 1e-4;
    let lo = to.min - from.max;
    let hi = to.max - from.min;
    let contains_zero = |l: f32, h: f32| l <= 0.0 && h >= 0.0;
    if contains_zero(lo.x, hi.x) && contains_zero(lo.y, hi.y) && contains_zero(lo.z, hi.z) {
        return None;
    }
    // Distance range of the xy rectangle from the z axis.
    let nearest = |l: f32, h: f32| {
        if contains_zero(l, h) {
            0.0
        } else {
            l.abs().min(h.abs())
        }
    };
    let rho_min = trig::hypot(nearest(lo.x, hi.x), nearest(lo.y, hi.y));
    let rho_max = trig::hypot(lo.x.abs().max(hi.x.abs()), lo.y.abs().max(hi.y.abs()));
    // phi = atan2(rho, z) (exact next to the poles, unlike acos) at the
    // lowest and highest z, and theta at the xy rectangle's corners: one
    // call, which computes the six angles side by side.
    let rho_at_lo = if hi.z >= 0.0 { rho_min } else { rho_max };
    let rho_at_hi = if lo.z <= 0.0 { rho_min } else { rho_max };
    let [phi_min, phi_max, base, a1, a2, a3, _, _] = trig::atan2(
        [rho_at_lo, rho_at_hi, lo.y, lo.y, hi.y, hi.y, 0.0, 0.0],
        [hi.z, lo.z, lo.x, hi.x, lo.x, hi.x, 1.0, 1.0],
    );
    let phi_lo = (phi_min - PAD).max(0.0);
    let phi_hi = (phi_max + PAD).min(PI);
    if contains_zero(lo.x, hi.x) && contains_zero(lo.y, hi.y) {
        return Some((-PI, PI, phi_lo, phi_hi));
    }
    // The rectangle misses the z axis: its corners bound theta, and the
    // arc they span is under pi. Find the arc by rotating so that the
    // first corner is at angle 0.
    let (mut dmin, mut dmax) = (0.0f32, 0.0f32);
    for a in [a1, a2, a3] {
        let mut d = a - base;
        if d > PI {
            d -= 2.0 * PI;
        } else if d < -PI {
            d += 2.0 * PI;
        }
        dmin = dmin.min(d);
        dmax = dmax.max(d);
    }
    // The arc is under pi, but two corners nearly opposite each other
    // (a rectangle thin across the axis's side and long along it) can
    // round to exactly pi apart, or past it, and the arc would be taken
    // the wrong way round: then every theta.
    if dmax - dmin >= PI - PAD {
        return Some((-PI, PI, phi_lo, phi_hi));
    }
    let wrap = |t: f32| {
        if t > PI {
            t - 2.0 * PI
        } else if t < -PI {
            t + 2.0 * PI
        } else {
            t
        }
    };
    Some((
        wrap(base + dmin - PAD),
        wrap(base + dmax + PAD),
        phi_lo,
        phi_hi,
    ))
}

/// Whether some direction of `bounds` (from [`direction_bounds`]) lies in
/// the cell's angular box.
pub fn directions_meet(cell: &Cell, bounds: Option<(f32, f32, f32, f32)>) -> bool {
    let Some((t0, t1, p0, p1)) = bounds else {
        return true;
    };
    if p1 < cell.lo[PHI] || p0 > cell.hi[PHI] {
        return false;
    }
    let (c0, c1) = (cell.lo[THETA], cell.hi[THETA]);
    if t0 <= t1 {
        !(t1 < c0 || t0 > c1)
    } else {
        // [t0, pi] u [-pi, t1]
        c1 >= t0 || c0 <= t1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_round_trip() {
        for d in [
            Vec3::X,
            Vec3::Y,
            -Vec3::X,
            Vec3::new(1.0, -2.0, 0.5),
            Vec3::Z,
            -Vec3::Z,
        ] {
            let (t, p) = direction_to_angles(d);
            assert!(
                (angles_to_direction(t, p) - d.normalize()).length() < 1e-6,
                "{d}"
            );
            assert!((-PI..=PI).contains(&t) && (0.0..=PI).contains(&p));
        }
        assert_eq!(direction_to_angles(Vec3::Z).1, 0.0);
        assert_eq!(direction_to_angles(-Vec3::Z).1, PI);
    }

    #[test]
    fn measure_is_volume_times_solid_angle() {
        let c = Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)));
        let four_pi = 4.0 * std::f64::consts::PI;
        assert!((c.solid_angle() - four_pi).abs() < 1e-5);
        assert!((c.measure() - 6.0 * four_pi).abs() < 1e-4);
        // A phi split at the midpoint is balanced (hemispheres); at pi/4
        // it is not.
        let (a, b) = c.split(PHI, PI / 2.0);
        assert!((a.measure() - b.measure()).abs() < 1e-4);
        let (a, b) = c.split(PHI, PI / 4.0);
        assert!(a.measure() < 0.2 * b.measure());
    }

    #[test]
    fn sampling_is_uniform_in_solid_angle() {
        let c = Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::ONE));
        // cos phi uniform: the upper hemisphere gets half the samples.
        let n = 10_000;
        let mut up = 0;
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            let p = c.sample([0.5, 0.5, 0.5, 0.5, u]);
            assert!(c.contains(p));
            up += (p[PHI] < PI / 2.0) as usize;
        }
        assert_eq!(up, n / 2);
    }

    #[test]
    fn angular_box_agrees_with_angles() {
        let mut c = Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::ONE));
        c.lo[THETA] = -1.0;
        c.hi[THETA] = 2.0;
        c.lo[PHI] = 0.3;
        c.hi[PHI] = 2.5;
        let b = c.angular_box();
        let full = Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::ONE)).angular_box();
        for i in 0..2000 {
            let t = -PI + (i as f32 * 0.618_034).fract() * 2.0 * PI;
            let p = (i as f32 * 0.414_213_6).fract() * PI;
            let d = angles_to_direction(t, p);
            let (t2, p2) = direction_to_angles(d);
            let near = (t2 - c.lo[THETA]).abs().min((t2 - c.hi[THETA]).abs()) < 1e-4
                || (p2 - c.lo[PHI]).abs().min((p2 - c.hi[PHI]).abs()) < 1e-4;
            if !near {
                assert_eq!(b.contains(d * 3.0), c.contains_angles(t2, p2), "{t} {p}");
            }
            assert!(full.contains(d));
        }
    }

    #[test]
    fn grid_values_are_inside_and_ordered() {
        let (lo, hi) = (-PI, PI);
        let mut last = lo;
        for k in 1..1024 {
            let v = grid_value(lo, hi, k, 10);
            assert!(v > last && v < hi);
            last = v;
        }
        assert_eq!(grid_value(0.0, 8.0, 512, 10), 4.0);
    }

    /// Brute force: directions between random points of the boxes all lie
    /// inside the bounds.
    #[test]
    fn direction_bounds_contain_every_direction() {
        let mut seed = 7u32;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        for _ in 0..1000 {
            let mut b = || {
                let c = Vec3::new(rnd(), rnd(), rnd()) * 10.0 - 5.0;
                let s = Vec3::new(rnd(), rnd(), rnd()) * 3.0;
                Aabb::new(c, c + s)
            };
            let (from, to) = (b(), b());
            let bounds = direction_bounds(&from, &to);
            // Random points, and every pair of corners (where the extreme
            // directions are).
            let corner = |b: &Aabb, k: usize| {
                Vec3::new(
                    [b.min.x, b.max.x][k & 1],
                    [b.min.y, b.max.y][(k >> 1) & 1],
                    [b.min.z, b.max.z][k >> 2],
                )
            };
            for k in 0..264 {
                let (p, q) = if k < 64 {
                    (corner(&from, k % 8), corner(&to, k / 8))
                } else {
                    (
                        from.lerp(Vec3::new(rnd(), rnd(), rnd())),
                        to.lerp(Vec3::new(rnd(), rnd(), rnd())),
                    )
                };
                // The angles in f64 (libm's), not by the f32 polynomials
                // that the bounds use.
                let v = (q - p).as_dvec3();
                let t = v.y.atan2(v.x) as f32;
                let ph = v.x.hypot(v.y).atan2(v.z) as f32;
                let mut cell = Cell::all_directions(from);
                cell.lo[THETA] = t;
                cell.hi[THETA] = t;
                cell.lo[PHI] = ph;
                cell.hi[PHI] = ph;
                assert!(
                    directions_meet(&cell, bounds),
                    "{from:?} {to:?} {t} {ph} {bounds:?}"
                );
            }
        }
    }

    #[test]
    fn direction_bounds_of_a_rectangle_thin_beside_the_axis() {
        // x = -1e-8, y from -1 to 1: the corners' theta round to exactly
        // -pi/2 and pi/2, pi apart, and the arc was taken on the wrong
        // side (theta in [-pi/2, pi/2], where every direction here has x <
        // 0; found by a review's fuzz). Every orientation.
        let from = Aabb::new(Vec3::ZERO, Vec3::ZERO);
        for (lo, hi, d) in [
            (
                Vec3::new(-1e-8, -1.0, 0.0),
                Vec3::new(-1e-8, 1.0, 0.0),
                -Vec3::X,
            ),
            (
                Vec3::new(1e-8, -1.0, 0.0),
                Vec3::new(1e-8, 1.0, 0.0),
                Vec3::X,
            ),
            (
                Vec3::new(-1.0, -1e-8, 0.0),
                Vec3::new(1.0, -1e-8, 0.0),
                -Vec3::Y,
            ),
            (
                Vec3::new(-1.0, 1e-8, 0.0),
                Vec3::new(1.0, 1e-8, 0.0),
                Vec3::Y,
            ),
        ] {
            let bounds = direction_bounds(&from, &Aabb::new(lo, hi));
            for v in [d, lo, hi] {
                let (t, ph) = direction_to_angles(v);
                let mut cell = Cell::all_directions(from);
                (cell.lo[THETA], cell.hi[THETA]) = (t, t);
                (cell.lo[PHI], cell.hi[PHI]) = (ph, ph);
                assert!(directions_meet(&cell, bounds), "{lo} {hi} {v}: {bounds:?}");
            }
        }
    }

    #[test]
    fn direction_bounds_near_the_poles() {
        // A box just off the +z axis: phi about 3.4e-4 must be inside
        // (acos(z / |v|) lost it in f32).
        let from = Aabb::new(Vec3::ZERO, Vec3::ZERO);
        let to = Aabb::new(
            Vec3::new(1.2e-4, 1.2e-4, 1.0),
            Vec3::new(2.4e-4, 2.4e-4, 2.0),
        );
        let (_, _, p0, p1) = direction_bounds(&from, &to).unwrap();
        let corner = direction_to_angles(Vec3::new(2.4e-4, 2.4e-4, 1.0)).1;
        assert!(
            corner > 3e-4 && p0 <= corner && corner <= p1,
            "{p0} {p1} {corner}"
        );
        let to = Aabb::new(
            Vec3::new(1.2e-4, 1.2e-4, -2.0),
            Vec3::new(2.4e-4, 2.4e-4, -1.0),
        );
        let (_, _, p0, p1) = direction_bounds(&from, &to).unwrap();
        let corner = direction_to_angles(Vec3::new(2.4e-4, 2.4e-4, -1.0)).1;
        assert!(p0 <= corner && corner <= p1, "{p0} {p1} {corner}");
    }

    #[test]
    fn direction_bounds_exclude() {
        // A box straight above: only small phi.
        let from = Aabb::new(Vec3::splat(-0.1), Vec3::splat(0.1));
        let to = Aabb::new(Vec3::new(-0.1, -0.1, 10.0), Vec3::new(0.1, 0.1, 11.0));
        let b = direction_bounds(&from, &to);
        let mut down = Cell::all_directions(from);
        down.lo[PHI] = PI / 2.0;
        assert!(!directions_meet(&down, b));
        let mut up = Cell::all_directions(from);
        up.hi[PHI] = 0.1;
        assert!(directions_meet(&up, b));
        // A box along -x (theta = pi): the interval wraps.
        let to = Aabb::new(Vec3::new(-11.0, -0.5, -0.5), Vec3::new(-10.0, 0.5, 0.5));
        let b = direction_bounds(&from, &to).unwrap();
        assert!(b.0 > b.1, "{b:?}");
        let mut east = Cell::all_directions(from);
        east.lo[THETA] = -0.5;
        east.hi[THETA] = 0.5;
        assert!(!directions_meet(&east, Some(b)));
        let mut west = Cell::all_directions(from);
        west.lo[THETA] = 3.0;
        assert!(directions_meet(&west, Some(b)));
    }
}
