//! Choosing a split (papers/003 sec. 4): candidate values on the q-bit
//! grid, scored by papers/003's effectiveness E (the default) or by the
//! share of the expected set they remove (S)
//!
//! ```text
//! S(A, B) = 1 - (|vis(A)| vol(A) + |vis(B)| vol(B)) / (|vis(C)| vol(C))
//! E(A, B) = (1 - |vis(A) n vis(B)| / |vis(C)|) * (1 - |vol(A) - vol(B)| / vol(C))
//! ```
//!
//! where vis(X) is estimated from the cell's cached rays that fall in X
//! (the objects their closest hits are on) and vol is the 5D measure
//! ([`SplitScore`]).
//!
//! Candidates: in x, y, z the planes of the bounding boxes of the objects
//! that overlap the cell's box, plus the midpoint; in theta and phi
//! `angular_candidates` equal-measure quantiles. Every value is snapped to
//! the grid, and both children must keep at least the minimum width.
//!
//! For one dimension, with the smallest and largest coordinate of each
//! seen object's rays, an object is in vis(A) iff its smallest coordinate
//! is below the value and in vis(B) iff its largest is not; every seen
//! object is in one of them, so |A n B| = |A| + |B| - |C|, and each
//! candidate costs two binary searches.

use super::SplitScore;
use super::builder_node::{CachedRay, Ctx};
use crate::geom::cell::{Cell, DIMS, PHI, THETA, grid_value};
use crate::geom::trig;

/// A chosen split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Candidate {
    pub dim: usize,
    pub code: u32,
    pub score: f64,
}

/// The grid code nearest to `value` in `[lo, hi]`, kept inside
/// `1..2^bits`.
fn snap(lo: f32, hi: f32, value: f32, bits: u32) -> u32 {
    let k = ((value - lo) / (hi - lo) * (1u32 << bits) as f32).round();
    (k.max(1.0) as u32).min((1 << bits) - 1)
}

/// The score of a cut whose sides see `[a, b]` objects of the `c` seen
/// in the cell and have measures `[ma, mb]` ([`SplitScore`]).
fn score(kind: SplitScore, [a, b, c]: [usize; 3], [ma, mb]: [f64; 2]) -> f64 {
    match kind {
        SplitScore::ExpectedSet => {
            let fa = ma / (ma + mb);
            1.0 - (a as f64 * fa + b as f64 * (1.0 - fa)) / c as f64
        }
        SplitScore::Effectiveness => {
            // Every seen object is on one side or both.
            let both = a + b - c;
            let e_vis = 1.0 - both as f64 / c as f64;
            let e_vol = 1.0 - (ma - mb).abs() / (ma + mb);
            e_vis * e_vol
        }
    }
}

/// The best split of `cell` whose score exceeds the threshold, if any.
pub(super) fn best_split(ctx: &Ctx, cell: &Cell, cache: &[CachedRay]) -> Option<Candidate> {
    let params = ctx.params;
    let q = params.grid_bits;
    // Coordinate ranges of the rays of each object seen.
    let mut slot = vec![u32::MAX; ctx.scene.objects().len()];
    let mut lo_of: Vec<[f32; DIMS]> = Vec::new();
    let mut hi_of: Vec<[f32; DIMS]> = Vec::new();
    for r in cache {
        let Some(o) = r.hit else { continue };
        let s = &mut slot[o as usize];
        if *s == u32::MAX {
            *s = lo_of.len() as u32;
            lo_of.push(r.p);
            hi_of.push(r.p);
        } else {
            let (l, h) = (&mut lo_of[*s as usize], &mut hi_of[*s as usize]);
            for d in 0..DIMS {
                l[d] = l[d].min(r.p[d]);
                h[d] = h[d].max(r.p[d]);
            }
        }
    }
    let seen = lo_of.len();
    if seen == 0 {
        return None;
    }
    let space = cell.space();
    let dims = if params.spatial_only { 3 } else { DIMS };
    let mut best: Option<Candidate> = None;
    let mut codes = Vec::new();
    for d in 0..dims {
        let (lo, hi) = (cell.lo[d], cell.hi[d]);
        codes.clear();
        if d < THETA {
            codes.push(1 << (q - 1));
            for o in ctx.scene.objects() {
                let b = o.bounds;
                if !b.overlaps(&space) {
                    continue;
                }
                for v in [b.min[d], b.max[d]] {
                    if v > lo && v < hi {
                        codes.push(snap(lo, hi, v, q));
                    }
                }
            }
        } else {
            let n = params.angular_candidates;
            for i in 1..=n {
                let f = i as f32 / (n + 1) as f32;
                let v = if d == PHI {
                    let (_, [c0, c1]) = trig::sin_cos([lo, hi]);
                    trig::acos(c0 + f * (c1 - c0))
                } else {
                    lo + f * (hi - lo)
                };
                codes.push(snap(lo, hi, v, q));
            }
        }
        codes.sort_unstable();
        codes.dedup();
        let mut mins: Vec<f32> = lo_of.iter().map(|p| p[d]).collect();
        let mut maxs: Vec<f32> = hi_of.iter().map(|p| p[d]).collect();
        mins.sort_unstable_by(f32::total_cmp);
        maxs.sort_unstable_by(f32::total_cmp);
        for &code in &codes {
            let v = grid_value(lo, hi, code, q);
            if v - lo < ctx.min_width[d] || hi - v < ctx.min_width[d] {
                continue;
            }
            let in_a = mins.partition_point(|&m| m < v);
            let in_b = seen - maxs.partition_point(|&m| m < v);
            let (ma, mb) = if d == PHI {
                let (_, [cl, cv, ch]) = trig::sin_cos([lo, v, hi]);
                ((cl - cv) as f64, (cv - ch) as f64)
            } else {
                ((v - lo) as f64, (hi - v) as f64)
            };
            let score = score(params.split_score, [in_a, in_b, seen], [ma, mb]);
            if score.is_finite() && best.is_none_or(|b| score > b.score) {
                best = Some(Candidate {
                    dim: d,
                    code,
                    score,
                });
            }
        }
    }
    best.filter(|b| b.score > params.split_threshold)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two rooms of 20 objects each and the wall between them, seen from
    /// both: a cut along the wall at a tenth of the cell separates the
    /// rooms. The expected set loses 45%; E's balance factor holds it
    /// under its 0.3 threshold. A cut that separates nothing scores 0
    /// either way, and both take the cut when it halves the cell.
    #[test]
    fn the_expected_set_cuts_a_thin_slab_behind_a_wall() {
        let (es, e) = (SplitScore::ExpectedSet, SplitScore::Effectiveness);
        let slab = score(es, [21, 21, 41], [0.1, 0.9]);
        assert!((slab - (1.0 - 21.0 / 41.0)).abs() < 1e-12, "{slab}");
        assert!(slab > es.default_threshold());
        assert!(score(e, [21, 21, 41], [0.1, 0.9]) < e.default_threshold());
        for kind in [es, e] {
            assert_eq!(score(kind, [41, 41, 41], [0.5, 0.5]), 0.0);
        }
        // The same cut in the middle of the cell: both take it.
        for kind in [es, e] {
            assert!(score(kind, [21, 21, 41], [0.5, 0.5]) > kind.default_threshold());
        }
    }

    #[test]
    fn snapping_stays_inside() {
        assert_eq!(snap(0.0, 1.0, 0.5, 10), 512);
        assert_eq!(snap(0.0, 1.0, 0.0, 10), 1);
        assert_eq!(snap(0.0, 1.0, 1.0, 10), 1023);
        assert_eq!(snap(-1.0, 1.0, 0.0, 4), 8);
    }
}
