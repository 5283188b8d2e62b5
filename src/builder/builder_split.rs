//! Choosing a split (papers/003 sec. 4): candidate values on the q-bit
//! grid, scored by the effectiveness
//!
//! ```text
//! E(A, B) = (1 - |vis(A) n vis(B)| / |vis(C)|) * (1 - |vol(A) - vol(B)| / vol(C))
//! ```
//!
//! where vis(X) is estimated from the cell's cached rays that fall in X
//! (the objects their closest hits are on) and vol is the 5D measure.
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

use super::builder_node::{CachedRay, Ctx};
use crate::geom::cell::{Cell, DIMS, PHI, THETA, grid_value};

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
                    let (c0, c1) = (lo.cos(), hi.cos());
                    (c0 + f * (c1 - c0)).clamp(-1.0, 1.0).acos()
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
            let both = in_a + in_b - seen;
            let e_vis = 1.0 - both as f64 / seen as f64;
            let (ma, mb) = if d == PHI {
                ((lo.cos() - v.cos()) as f64, (v.cos() - hi.cos()) as f64)
            } else {
                ((v - lo) as f64, (hi - v) as f64)
            };
            let e_vol = 1.0 - (ma - mb).abs() / (ma + mb);
            let score = e_vis * e_vol;
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

    #[test]
    fn snapping_stays_inside() {
        assert_eq!(snap(0.0, 1.0, 0.5, 10), 512);
        assert_eq!(snap(0.0, 1.0, 0.0, 10), 1);
        assert_eq!(snap(0.0, 1.0, 1.0, 10), 1023);
        assert_eq!(snap(-1.0, 1.0, 0.0, 4), 8);
    }
}
