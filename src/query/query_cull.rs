//! The frustum cull of a view's answer, in the form a query runs it:
//! eight objects' boxes at a time ([`Boxes8`]) against each of a
//! [`Frustum`]'s planes, the eye's and the four sides, in AVX registers
//! where the CPU has them ([`Cull::keeps8_avx`]), a box at a time
//! elsewhere ([`Cull::keeps8`]), the same answers either way.
//!
//! A box with corners `lo`, `hi` reaches furthest along a normal `n` at
//! the corner that takes `hi` where `n` is positive and `lo` where it is
//! negative: `n+ . hi + n- . lo`, with `n+` and `n-` the normal's positive
//! and negative parts. The two parts are stored apart, so no lane
//! selects a corner. The slack the [`Frustum`] allows a box (the angle
//! times its farthest point from the eye, plus f32 rounding) is bounded
//! for every box of the scene at once, from the scene's box, and folded
//! into one threshold per plane: the cull keeps every box that
//! [`Frustum::may_see`] keeps, and a few more that lie outside a plane by
//! less than the slack of the scene's farthest point.

use glam::{DVec3, Vec3};

use super::Frustum;
use crate::geom::Aabb;

/// The most planes a [`Frustum`] has: the eye's and four sides.
const PLANES: usize = 5;

/// One plane of a [`Cull`]: a box is kept when it reaches `keep` along
/// the normal, whose positive and negative parts are apart.
#[derive(Clone, Copy, Debug)]
struct Plane {
    /// The normal's positive part (times a box's `hi`).
    pos: [f32; 3],
    /// The normal's negative part (times a box's `lo`).
    neg: [f32; 3],
    /// The threshold.
    keep: f32,
}

impl Plane {
    /// A plane that keeps every box.
    const ANY: Plane = Plane {
        pos: [0.0; 3],
        neg: [0.0; 3],
        keep: f32::NEG_INFINITY,
    };

    /// How far the box of corners `lo`, `hi` reaches along the normal:
    /// the same operations in the same order wherever it is used, so that
    /// one box and eight at a time give the same answer to the bit.
    #[inline(always)]
    fn along(&self, lo: [f32; 3], hi: [f32; 3]) -> f32 {
        self.pos[0] * hi[0]
            + self.neg[0] * lo[0]
            + self.pos[1] * hi[1]
            + self.neg[1] * lo[1]
            + self.pos[2] * hi[2]
            + self.neg[2] * lo[2]
    }
}

/// Eight objects' boxes, corner coordinate by corner coordinate
/// (`[lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]`, eight of each), as
/// [`Cull::keeps8`] tests them: the eight tests run as one in vector
/// registers.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct Boxes8 {
    c: [[f32; 8]; 6],
}

impl Boxes8 {
    /// Eight boxes that are always kept ([`UNBOUNDED`]).
    pub(crate) const UNBOUNDED: Boxes8 = Boxes8 {
        c: [
            [-f32::MAX; 8],
            [-f32::MAX; 8],
            [-f32::MAX; 8],
            [f32::MAX; 8],
            [f32::MAX; 8],
            [f32::MAX; 8],
        ],
    };

    /// Box `i` (0 to 7) as [`corners`] gives it.
    pub(crate) fn get(&self, i: usize) -> [f32; 6] {
        self.c.map(|c| c[i])
    }

    /// Sets box `i` (0 to 7) to the corners `b`.
    pub(crate) fn set(&mut self, i: usize, b: &[f32; 6]) {
        for (c, &v) in self.c.iter_mut().zip(b) {
            c[i] = v;
        }
    }
}

/// A [`Frustum`]'s planes as the cull tests them (see the module docs).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cull {
    /// The eye's plane, then the sides; [`Plane::ANY`] past the frustum's.
    planes: [Plane; PLANES],
}

impl Cull {
    /// The cull of `frustum` for boxes inside `scene` (finite, not empty).
    pub(crate) fn new(frustum: &Frustum, scene: &Aabb) -> Cull {
        let mut cull = Cull {
            planes: [Plane::ANY; PLANES],
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
            // Three f32 steps lower still: `may_see` subtracts its slack
            // from d in f32, which may round its threshold down by half a
            // step. Past 1.8e19 an f32 length overflows and `may_see`
            // keeps every box: so does the cull.
            let keep = if far < 1.8e19 {
                below(d - slack)
            } else {
                f32::NEG_INFINITY
            };
            let (pos, neg) = (n.max(Vec3::ZERO), n.min(Vec3::ZERO));
            cull.planes[k] = Plane {
                pos: pos.to_array(),
                neg: neg.to_array(),
                keep,
            };
        }
        cull
    }

    /// Whether the box `b` (`[lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]`) may be
    /// seen: it reaches every plane's threshold. A box of infinite or
    /// `f32::MAX` corners is always kept.
    #[inline]
    pub(crate) fn keeps(&self, b: &[f32; 6]) -> bool {
        let (lo, hi) = ([b[0], b[1], b[2]], [b[3], b[4], b[5]]);
        // `&`, not `&&`: no branch.
        self.planes
            .iter()
            .fold(true, |k, p| k & (p.along(lo, hi) >= p.keep))
    }

    /// [`Cull::keeps`] of each of the eight boxes, as bit i for box i.
    #[inline]
    pub(crate) fn keeps8(&self, b: &Boxes8) -> u8 {
        (0..8).fold(0, |m, i| m | (u8::from(self.keeps(&b.get(i))) << i))
    }

    /// [`Cull::keeps8`] in AVX registers, eight lanes: [`Plane::along`]'s
    /// multiplies and adds in its order (never fused), so each lane's sum
    /// is the one [`Cull::keeps`] makes, and its `>=` (false on NaN).
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    pub(crate) fn keeps8_avx(&self, b: &Boxes8) -> u8 {
        use std::arch::x86_64::*;
        // SAFETY: each load reads the eight f32 of one row of `b.c`.
        let c = unsafe {
            [
                _mm256_loadu_ps(b.c[0].as_ptr()),
                _mm256_loadu_ps(b.c[1].as_ptr()),
                _mm256_loadu_ps(b.c[2].as_ptr()),
                _mm256_loadu_ps(b.c[3].as_ptr()),
                _mm256_loadu_ps(b.c[4].as_ptr()),
                _mm256_loadu_ps(b.c[5].as_ptr()),
            ]
        };
        let mut kept = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
        for p in &self.planes {
            let mut along = _mm256_add_ps(
                _mm256_mul_ps(_mm256_set1_ps(p.pos[0]), c[3]),
                _mm256_mul_ps(_mm256_set1_ps(p.neg[0]), c[0]),
            );
            along = _mm256_add_ps(along, _mm256_mul_ps(_mm256_set1_ps(p.pos[1]), c[4]));
            along = _mm256_add_ps(along, _mm256_mul_ps(_mm256_set1_ps(p.neg[1]), c[1]));
            along = _mm256_add_ps(along, _mm256_mul_ps(_mm256_set1_ps(p.pos[2]), c[5]));
            along = _mm256_add_ps(along, _mm256_mul_ps(_mm256_set1_ps(p.neg[2]), c[2]));
            let reaches = _mm256_cmp_ps::<_CMP_GE_OQ>(along, _mm256_set1_ps(p.keep));
            kept = _mm256_and_ps(kept, reaches);
        }
        _mm256_movemask_ps(kept) as u8
    }
}

/// An f32 below the third f32 under `x` (at most `f32::MAX`), without a
/// branch: `x` less 2^-21 of its size (four f32 steps or more: a step at
/// size m is at most m 2^-23) and 2^-140 (for `x` near 0: 512 steps of
/// the smallest f32), rounded to the nearest f32 (up by half a step at
/// most), so at least 3.5 steps down where three steps reach at most 3.
fn below(x: f64) -> f32 {
    (x - x.abs() * 2f64.powi(-21) - 2f64.powi(-140)) as f32
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
                // Eight at a time, portable and in AVX registers: the
                // same answers, box for box.
                for group in boxes.chunks(8) {
                    let mut eight = Boxes8::UNBOUNDED;
                    for (i, b) in group.iter().enumerate() {
                        eight.set(i, &corners(b));
                    }
                    let one_by_one =
                        (0..8).fold(0u8, |m, i| m | (u8::from(cull.keeps(&eight.get(i))) << i));
                    assert_eq!(cull.keeps8(&eight), one_by_one);
                    #[cfg(target_arch = "x86_64")]
                    if std::arch::is_x86_feature_detected!("avx") {
                        // SAFETY: the CPU has AVX.
                        assert_eq!(unsafe { cull.keeps8_avx(&eight) }, one_by_one);
                    }
                }
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
