//! The frustum cull of a view's answer, in the form a query runs it: the
//! side planes of a [`Frustum`] laid out one per lane of four, so that one
//! object's box is tested against all of them with a handful of
//! straight-line multiply-adds the compiler turns into vector code, and
//! the eye's plane beside them.
//!
//! A box with corners `lo`, `hi` reaches furthest along a normal `n` at
//! the corner that takes `hi` where `n` is positive and `lo` where it is
//! negative: `n+ . hi + n- . lo`, with `n+` and `n-` the normal's positive
//! and negative parts. The two parts are stored per lane, so no lane
//! selects a corner. The slack the [`Frustum`] allows a box (the angle
//! times its farthest point from the eye, plus f32 rounding) is bounded
//! for every box of the scene at once, from the scene's box, and folded
//! into one threshold per plane: the cull keeps every box that
//! [`Frustum::may_see`] keeps, and a few more that lie outside a plane by
//! less than the slack of the scene's farthest point.

use glam::{DVec3, Vec3};

use super::Frustum;
use crate::geom::Aabb;

/// Lanes: the frustum's four sides, or planes that keep everything (the
/// eye's plane is apart).
const LANES: usize = 4;

/// A [`Frustum`]'s planes as the cull tests them (see the module docs).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cull {
    /// Per axis, per lane: the normal's positive part (times `hi`).
    pos: [[f32; LANES]; 3],
    /// Per axis, per lane: the normal's negative part (times `lo`).
    neg: [[f32; LANES]; 3],
    /// Per lane: a box is kept when it reaches this far along the normal.
    keep: [f32; LANES],
    /// The eye's plane, tested on its own: its normal's positive and
    /// negative parts, and its threshold.
    eye: ([f32; 3], [f32; 3], f32),
}

impl Cull {
    /// The cull of `frustum` for boxes inside `scene` (finite, not empty).
    pub(crate) fn new(frustum: &Frustum, scene: &Aabb) -> Cull {
        let mut cull = Cull {
            pos: [[0.0; LANES]; 3],
            neg: [[0.0; LANES]; 3],
            keep: [f32::NEG_INFINITY; LANES],
            eye: ([0.0; 3], [0.0; 3], f32::NEG_INFINITY),
        };
        let (lo, hi) = (scene.min.as_dvec3(), scene.max.as_dvec3());
        // The largest |coordinate| of the scene's points, per axis.
        let reach = lo.abs().max(hi.abs());
        // The scene's farthest point from any plane's eye (the corners of
        // the box of eyes), and below the largest |n . p| of its points:
        // what the frustum's slack takes of any box in it, at most.
        let eyes = &frustum.eyes[..frustum.count];
        let (e0, e1) = eyes
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), e| {
                (a.min(e.as_dvec3()), b.max(e.as_dvec3()))
            });
        let far = (lo - e0)
            .abs()
            .max((hi - e0).abs())
            .max((lo - e1).abs())
            .max((hi - e1).abs())
            .length();
        for (k, &(n, d)) in frustum.planes[..frustum.count].iter().enumerate() {
            let along = n.abs().as_dvec3().dot(reach);
            let d = f64::from(d);
            // Padded by 1e-5 of itself: `Frustum::may_see` works its slack
            // out in f32, which may round up by a few ulps.
            let slack = (f64::from(Frustum::ANGLE_SLACK) * far + 1e-6 * (1.0 + d.abs() + along))
                * (1.0 + 1e-5);
            // Two f32 steps lower still: `may_see` subtracts its slack from
            // d in f32, which may round its threshold down by half a step.
            // Past 1.8e19 an f32 length overflows and `may_see` keeps
            // every box: so does the cull.
            let keep = if far < 1.8e19 {
                round_down(d - slack).next_down().next_down()
            } else {
                f32::NEG_INFINITY
            };
            let (pos, neg) = (n.max(Vec3::ZERO), n.min(Vec3::ZERO));
            if k == 0 {
                cull.eye = (pos.to_array(), neg.to_array(), keep);
                continue;
            }
            for axis in 0..3 {
                cull.pos[axis][k - 1] = pos[axis];
                cull.neg[axis][k - 1] = neg[axis];
            }
            cull.keep[k - 1] = keep;
        }
        cull
    }

    /// Whether the box `b` (`[lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]`) may be
    /// seen: it reaches every plane's threshold. A box of infinite or
    /// `f32::MAX` corners is always kept.
    #[inline]
    pub(crate) fn keeps(&self, b: &[f32; 6]) -> bool {
        let mut inside = [false; LANES];
        for (lane, inside) in inside.iter_mut().enumerate() {
            let along = self.pos[0][lane] * b[3]
                + self.neg[0][lane] * b[0]
                + self.pos[1][lane] * b[4]
                + self.neg[1][lane] * b[1]
                + self.pos[2][lane] * b[5]
                + self.neg[2][lane] * b[2];
            *inside = along >= self.keep[lane];
        }
        let (pos, neg, keep) = &self.eye;
        let along = pos[0] * b[3]
            + neg[0] * b[0]
            + pos[1] * b[4]
            + neg[1] * b[1]
            + pos[2] * b[5]
            + neg[2] * b[2];
        // `&`, not `&&`: no branch.
        (along >= *keep) & inside.iter().all(|&i| i)
    }
}

/// `x` as an f32 not above it.
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x { f.next_down() } else { f }
}

/// The box that covers the scene's boxes: `None` when there are none (a
/// file without bounds, or only empty objects).
pub(crate) fn scene_box<'a>(boxes: impl Iterator<Item = &'a Aabb>) -> Option<Aabb> {
    boxes
        .copied()
        .reduce(|a, b| Aabb::new(a.min.min(b.min), a.max.max(b.max)))
        .filter(|s| s.min.is_finite() && s.max.is_finite())
}

/// The corners of a box as [`Cull::keeps`] takes them.
pub(crate) fn corners(b: &Aabb) -> [f32; 6] {
    [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z]
}

/// What [`Cull::keeps`] takes for an object without bounds: kept always.
pub(crate) const UNBOUNDED: [f32; 6] = [
    -f32::MAX,
    -f32::MAX,
    -f32::MAX,
    f32::MAX,
    f32::MAX,
    f32::MAX,
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::query::View;
    use rand::{RngExt, SeedableRng};

    /// Every box the frustum keeps, the cull keeps; and it culls most of
    /// what the frustum culls (its slack is the scene's, not the box's).
    #[test]
    fn the_cull_keeps_what_the_frustum_keeps() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let mut point = |scale: f32| {
            Vec3::new(rng.random(), rng.random(), rng.random()) * (2.0 * scale) - Vec3::splat(scale)
        };
        let (mut culled_by_frustum, mut culled_by_both) = (0, 0);
        for scale in [1.0f32, 100.0, 5000.0] {
            let boxes: Vec<Aabb> = (0..200)
                .map(|_| {
                    let c = point(scale);
                    Aabb::new(c, c + point(0.05 * scale).abs())
                })
                .collect();
            let scene = scene_box(boxes.iter()).unwrap();
            for k in 0..100 {
                let eye = point(0.5 * scale);
                let fov = [10.0, 60.0, 90.0, 150.0, 171.0][k % 5];
                let mut view = View::square(eye, point(1.0), fov);
                view.up = [Vec3::Z, Vec3::Y, point(1.0), view.dir][k % 4];
                let eyes = Aabb::new(eye, eye + point(0.01 * scale).abs());
                let frustum = Frustum::new(&view, &eyes);
                let cull = Cull::new(&frustum, &scene);
                for b in &boxes {
                    let (f, c) = (frustum.may_see(b), cull.keeps(&corners(b)));
                    assert!(!f || c, "{b:?}: the frustum keeps it, the cull does not");
                    culled_by_frustum += usize::from(!f);
                    culled_by_both += usize::from(!f && !c);
                }
                assert!(cull.keeps(&UNBOUNDED));
            }
        }
        assert!(
            culled_by_both * 100 >= culled_by_frustum * 99 && culled_by_frustum > 10_000,
            "the cull culls {culled_by_both} of the frustum's {culled_by_frustum}"
        );
    }

    /// Boxes just outside a plane, by less than the slack, are kept; by
    /// much more, culled.
    #[test]
    fn a_box_on_the_plane_is_kept() {
        let view = View::square(Vec3::ZERO, Vec3::X, 90.0);
        let eyes = Aabb::new(Vec3::ZERO, Vec3::ZERO);
        let frustum = Frustum::new(&view, &eyes);
        let scene = Aabb::new(Vec3::splat(-10.0), Vec3::splat(10.0));
        let cull = Cull::new(&frustum, &scene);
        // Behind the eye, touching its plane.
        let touching = Aabb::new(Vec3::new(-1.0, -1.0, -1.0), Vec3::new(0.0, 1.0, 1.0));
        assert!(cull.keeps(&corners(&touching)));
        let behind = Aabb::new(Vec3::new(-2.0, -1.0, -1.0), Vec3::new(-0.01, 1.0, 1.0));
        assert!(!cull.keeps(&corners(&behind)));
        // Beside the side plane y = x, a hair outside.
        let beside = Aabb::new(Vec3::new(5.0, 6.0001, 0.0), Vec3::new(6.0, 7.0, 1.0));
        assert!(cull.keeps(&corners(&beside)));
        let far_beside = Aabb::new(Vec3::new(5.0, 6.5, 0.0), Vec3::new(6.0, 7.0, 1.0));
        assert!(!cull.keeps(&corners(&far_beside)));
    }
}
