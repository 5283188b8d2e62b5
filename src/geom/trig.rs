//! The builder's f32 trigonometry: `atan2`, `acos`, `sin` and `cos` as
//! fixed sequences of IEEE operations (Cephes' polynomials after a range
//! reduction), and `hypot` through f64.
//!
//! Two reasons not to call the platform's libm in the sampler and the
//! cell arithmetic:
//! - **The same bytes on every machine.** A build's rays, and so its
//!   `.v5d`, depend on every angle it computes; glibc's `atan2f` and
//!   `cosf` have changed between versions, and other platforms' differ.
//!   These functions give the same bits wherever IEEE f32 and f64 do
//!   (Rust never fuses or reorders float operations), on any CPU.
//! - **Speed.** glibc's `atan2f` takes about 26 ns on this project's
//!   machine, and an aimed sample needs six. Written without branches on
//!   the data, the functions of arrays here compile to vector code (about
//!   4 ns an `atan2`), and the builder asks for a sample's angles in one
//!   call (notes/trace.md, step 6).
//!
//! Accuracy (checked on dense grids against f64 in the tests below):
//! `atan2` within 3e-7 rad for normal arguments under 1e38 (subnormal ones
//! within about 3e-6; past 1.7e38 the range reduction overflows), `acos`
//! within 4e-7 rad, `sin` and `cos` within 1e-7 for arguments in `[-2 pi,
//! 2 pi]` (the angles of view space and their sums; the quadrant is wrong
//! past 2^20). Scene coordinates are at most 1e14 and cell angles within
//! `[-pi, pi]`. `direction_bounds` pads its intervals by far more (1e-4
//! rad); the other callers draw samples and place them in cells, where an
//! angle this far off only moves a sample lying on a cell's boundary to
//! the cell beside it.

use std::f32::consts::{FRAC_2_PI, FRAC_PI_2, FRAC_PI_4, PI};

/// `a` where `c`, else `b` (a select, which vector code does per lane).
#[inline(always)]
fn pick(c: bool, a: f32, b: f32) -> f32 {
    if c { a } else { b }
}

/// `atan(a)` for `|a| <= tan(pi/8)` (Cephes' `atanf` polynomial).
#[inline(always)]
fn atan_reduced(a: f32) -> f32 {
    let z = a * a;
    (((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1) * z * a + a
}

/// `atan2(y, x)` of one pair, with libm's signs of zero and of pi.
#[inline(always)]
fn atan2_one(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let steep = ay > ax;
    let big = pick(steep, ay, ax);
    let small = pick(steep, ax, ay);
    // Past tan(pi/8), atan(s/b) = pi/4 + atan((s - b) / (s + b)).
    let upper = small > 0.414_213_57 * big;
    let ratio = pick(upper, small - big, small) / pick(upper, small + big, big);
    let a = pick(big == 0.0, 0.0, ratio);
    let p = atan_reduced(a);
    let r = pick(upper, FRAC_PI_4 + p, p);
    let r = pick(steep, FRAC_PI_2 - r, r);
    let r = pick(x.is_sign_negative(), PI - r, r);
    let r = pick(y.is_sign_negative(), -r, r);
    pick(x.is_nan() || y.is_nan(), f32::NAN, r)
}

/// `atan2(y[i], x[i])` for each `i` (within 3e-7 rad; 0 or pi with the
/// sign of `y` at `x = y = 0`, as libm).
#[inline]
pub(crate) fn atan2<const N: usize>(y: [f32; N], x: [f32; N]) -> [f32; N] {
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = atan2_one(y[i], x[i]);
    }
    out
}

/// `asin(a)` for `0 <= a <= 1/2` (Cephes' `asinf` polynomial).
#[inline(always)]
fn asin_reduced(a: f32) -> f32 {
    let z = a * a;
    ((((4.216_32e-2 * z + 2.418_131e-2) * z + 4.547_002_6e-2) * z + 7.495_300_3e-2) * z
        + 1.666_675_2e-1)
        * z
        * a
        + a
}

/// `acos(c)` in `[0, pi]`, `c` clamped to `[-1, 1]` first (within 4e-7
/// rad).
#[inline]
pub(crate) fn acos(c: f32) -> f32 {
    let c = c.clamp(-1.0, 1.0);
    let a = c.abs();
    // Past 1/2, acos(a) = 2 asin(sqrt((1 - a) / 2)); below, pi/2 - asin(a).
    let far = a > 0.5;
    let s = asin_reduced(pick(far, ((1.0 - a) * 0.5).sqrt(), a));
    let r = pick(far, 2.0 * s, FRAC_PI_2 - s);
    pick(c < 0.0, PI - r, r)
}

/// 1.5 * 2^23: added and taken away, it rounds an f32 below 2^22 to an
/// integer (ties to even), whose low bits are then those of the sum.
const ROUNDER: f32 = 12_582_912.0;

/// `(sin x[i], cos x[i])` for each `i`, for `|x| <= 2^20` (within 1e-7
/// for `|x| <= 2 pi`).
#[inline]
pub(crate) fn sin_cos<const N: usize>(x: [f32; N]) -> ([f32; N], [f32; N]) {
    let (mut sin, mut cos) = ([0.0; N], [0.0; N]);
    for i in 0..N {
        let x = x[i];
        // The quadrant k (x = k pi/2 + r, |r| <= pi/4), and r in f64.
        let shifted = x * FRAC_2_PI + ROUNDER;
        let quadrant = shifted.to_bits() & 3;
        let k = shifted - ROUNDER;
        let r = (f64::from(x) - f64::from(k) * std::f64::consts::FRAC_PI_2) as f32;
        let z = r * r;
        let s = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * r + r;
        let c =
            ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
        let odd = quadrant & 1 != 0;
        let (s1, c1) = (pick(odd, c, s), pick(odd, s, c));
        sin[i] = pick(quadrant & 2 != 0, -s1, s1);
        cos[i] = pick((quadrant + 1) & 2 != 0, -c1, c1);
    }
    (sin, cos)
}

/// `cos x` (see [`sin_cos`]).
#[inline]
pub(crate) fn cos(x: f32) -> f32 {
    sin_cos([x]).1[0]
}

/// `sqrt(x^2 + y^2)`, computed in f64 (no overflow, one rounding at the
/// end, the square root being IEEE's).
#[inline]
pub(crate) fn hypot(x: f32, y: f32) -> f32 {
    let (x, y) = (f64::from(x), f64::from(y));
    (x * x + y * y).sqrt() as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest error of `f` against `exact` over `args`.
    fn worst(
        args: impl Iterator<Item = f32>,
        f: impl Fn(f32) -> f32,
        exact: impl Fn(f64) -> f64,
    ) -> f64 {
        args.map(|a| (f64::from(f(a)) - exact(f64::from(a))).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn atan2_is_within_3e_7_everywhere() {
        let mut err = 0.0f64;
        let m = 600;
        for scale in [1e-30f32, 1e-3, 1.0, 7.3, 1e30] {
            for i in 0..=m {
                for j in 0..=m {
                    let y = (i as f32 / m as f32 * 2.0 - 1.0) * scale * 1.37;
                    let x = (j as f32 / m as f32 * 2.0 - 1.0) * scale;
                    let got = atan2([y], [x])[0];
                    err = err.max((f64::from(got) - f64::from(y).atan2(f64::from(x))).abs());
                }
            }
        }
        assert!(err < 3e-7, "atan2 off by {err:e}");
        // Next to the reduction's and the octants' boundaries.
        for t in [0.414_213_57f32, 1.0, 2.414_213_6] {
            for k in -50i32..=50 {
                let y = f32::from_bits((t.to_bits() as i32 + k) as u32);
                for (y, x) in [(y, 1.0), (1.0, y), (-y, 1.0), (y, -1.0)] {
                    let got = atan2([y], [x])[0];
                    let e = (f64::from(got) - f64::from(y).atan2(f64::from(x))).abs();
                    assert!(e < 3e-7, "atan2({y}, {x}) off by {e:e}");
                }
            }
        }
    }

    #[test]
    fn atan2_keeps_libm_signs_and_nan() {
        for (y, x) in [
            (0.0f32, 0.0f32),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-0.0, -0.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1e-30, 1e30),
            (1e30, -1e-30),
        ] {
            let got = atan2([y], [x])[0];
            let want = y.atan2(x);
            assert_eq!(
                got.is_sign_negative(),
                want.is_sign_negative(),
                "atan2({y}, {x})"
            );
            assert!(
                (got - want).abs() <= 3e-7,
                "atan2({y}, {x}) = {got}, libm {want}"
            );
        }
        assert!(atan2([f32::NAN], [1.0])[0].is_nan());
        assert!(atan2([1.0], [f32::NAN])[0].is_nan());
    }

    #[test]
    fn acos_is_within_4e_7_and_exact_at_the_ends() {
        let n = 2_000_000;
        let err = worst(
            (0..=n).map(|i| i as f32 / (n / 2) as f32 - 1.0),
            acos,
            f64::acos,
        );
        assert!(err < 4e-7, "acos off by {err:e}");
        // Next to 1 and -1, where acos is steepest.
        let ends = (0..100_000u32).flat_map(|k| {
            let c = f32::from_bits(1.0f32.to_bits() - k);
            [c, -c]
        });
        let err = worst(ends, acos, f64::acos);
        assert!(err < 4e-7, "acos off by {err:e} next to +-1");
        assert_eq!(acos(1.0), 0.0);
        assert_eq!(acos(-1.0), PI);
        assert_eq!(acos(1.5), 0.0);
        assert_eq!(acos(-7.0), PI);
    }

    #[test]
    fn sin_and_cos_are_within_1e_7() {
        let n = 4_000_000;
        let args = || (0..=n).map(|i| (i as f32 / n as f32 * 2.0 - 1.0) * 2.0 * PI);
        let sin = worst(args(), |x| sin_cos([x]).0[0], f64::sin);
        let cos = worst(args(), |x| sin_cos([x]).1[0], f64::cos);
        assert!(
            sin < 1e-7 && cos < 1e-7,
            "sin off by {sin:e}, cos by {cos:e}"
        );
        assert_eq!(sin_cos([0.0]), ([0.0], [1.0]));
        // Eight lanes agree with one at a time.
        let x: [f32; 8] = std::array::from_fn(|i| i as f32 * 0.9 - 3.0);
        let (s, c) = sin_cos(x);
        for i in 0..8 {
            assert_eq!((s[i], c[i]), (sin_cos([x[i]]).0[0], super::cos(x[i])));
        }
    }

    #[test]
    fn hypot_does_not_overflow() {
        assert_eq!(hypot(3.0, 4.0), 5.0);
        assert_eq!(hypot(3e30, 4e30), 5e30);
        assert_eq!(hypot(-3e-30, 4e-30), 5e-30);
    }
}
