//! Reprojection and the occlusion sweep (papers/001 sec. 5).
//!
//! Planes parallel to a face of the cell are visited in order away from
//! it. Each plane's Depth Map holds what the previous plane's map proves,
//! *reprojected* onto it, and what lies between the two planes: the convex
//! occluders there (projected as on any plane), the cuts of solids through
//! the plane, and the axis-aligned patches lying in it
//! (`oracle_patches.rs`). Many small occluders then fuse: each is drawn
//! once, near its plane, where its umbra is still whole, and the fused
//! umbra travels on.
//!
//! **Reprojection, exactly per pixel.** The paper convolves the previous
//! map with the inverse image of an "equivalent cell". Here each target
//! pixel X at `w = wb` gets the range of source pixels, at `w = wa`, that
//! the segments from the cell to X cross: along `u`, the crossing
//! `c + (x - c) (wa - cw) / (wb - cw)` is monotone in each of `c`, `cw`,
//! `x` (as in `occludee_rect`), so its extremes are at the corners of the
//! cell and of X. If every source pixel in that rectangle holds an
//! occluder, every segment from the cell to X crosses an occluder, no
//! further than `wa` plus the rectangle's largest Depth: that is X's
//! Depth. The rectangles of neighbouring pixels are windows that move
//! monotonically along each axis, so the map is two passes of sliding
//! window maxima, O(n^2) per plane.
//!
//! **Reaching back** (`OracleParams::sweep_reach`). A reprojection loses
//! up to a pixel at the edges of what it carries, since each target pixel
//! is covered only where its whole window is: through a chain of k planes,
//! an umbra shrinks by up to k pixels, so more, thinner steps (which a
//! forest's leaves need to fuse) lose more. A plane may also take the
//! reprojections of the planes 2, 4, 8, ... back, each its own bound by
//! the same argument (a segment from the cell to the plane crosses every
//! earlier plane, in its window there), keeping the smallest Depth: what
//! an early plane proves then reaches a late one through about log2(k)
//! reprojections.
//!
//! Why a reprojected map is conservative: a source pixel's Depth `d` means
//! that every segment from a cell point to a point of the pixel meets an
//! occluder at `w <= wa + d` (true of occluders, slices and patches, and,
//! by this argument, of reprojections); a segment from the cell to X
//! crosses `w = wa` in the window, so its part up to there meets one. This
//! is appendix B's "the shadow of a subset of the umbra lies in the umbra".
//!
//! Where the work is done: each plane's convex occluders go through the
//! oracle's [`super::Rasteriser`] (the GPU where there is one, a
//! submission per plane); the reprojection, the patches and the cuts of
//! solids are drawn on the CPU in both cases.

use glam::{DVec2, DVec3};

use super::oracle_plane::DepthMap;
use super::oracle_project::Frame;

/// Relative margin against rounding, in pixels, on the side of a larger
/// window.
const MARGIN: f64 = 1e-6;

/// One plane of a sweep: its map and its position.
#[derive(Clone, Debug)]
pub struct SweepPlane {
    /// The Depth Map (pyramid built).
    pub map: DepthMap,
    /// The plane's `w`.
    pub wp: f64,
}

/// The sweep away from one face of a cell.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The face's frame.
    pub frame: Frame,
    /// The planes, nearest first (strictly increasing `wp`).
    pub planes: Vec<SweepPlane>,
}

/// For each of the `nb` pixels along one axis of the target plane (over
/// `[rb0, rb1]` at `w = wb`), the source pixels (of `na` over `[ra0, ra1]`
/// at `w = wa`) that segments from the cell (`[c0, c1]` along the axis,
/// `[cw0, cw1]` along `w`) to the pixel cross; `None` when some lie off
/// the source map. Windows are widened, never narrowed, until both ends
/// move monotonically.
#[allow(clippy::too_many_arguments)]
fn windows(
    c: (f64, f64),
    cw: (f64, f64),
    wa: f64,
    wb: f64,
    ra: (f64, f64),
    na: usize,
    rb: (f64, f64),
    nb: usize,
) -> Vec<Option<(usize, usize)>> {
    let pa = (ra.1 - ra.0) / na as f64;
    let pb = (rb.1 - rb.0) / nb as f64;
    let mut lo = vec![0i64; nb];
    let mut hi = vec![0i64; nb];
    for i in 0..nb {
        let (x0, x1) = (rb.0 + i as f64 * pb, rb.0 + (i + 1) as f64 * pb);
        let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
        for cu in [c.0, c.1] {
            for w in [cw.0, cw.1] {
                let t = (wa - w) / (wb - w);
                for x in [x0, x1] {
                    let u = cu + (x - cu) * t;
                    a = a.min(u);
                    b = b.max(u);
                }
            }
        }
        let (fa, fb) = ((a - ra.0) / pa - MARGIN, (b - ra.0) / pa + MARGIN);
        lo[i] = if fa.is_finite() {
            fa.floor() as i64
        } else {
            i64::MIN
        };
        hi[i] = if fb.is_finite() {
            fb.floor() as i64
        } else {
            i64::MAX
        };
    }
    for i in (0..nb.saturating_sub(1)).rev() {
        lo[i] = lo[i].min(lo[i + 1]);
    }
    for i in 1..nb {
        hi[i] = hi[i].max(hi[i - 1]);
    }
    lo.iter()
        .zip(&hi)
        .map(|(&l, &h)| (l >= 0 && h < na as i64 && l <= h).then_some((l as usize, h as usize)))
        .collect()
}

/// Sliding window maxima: `put(i, max of get(p) for p in windows[i])`
/// (+inf for `None`); windows must have both ends nondecreasing. `queue`
/// is scratch.
fn sliding_max(
    get: impl Fn(usize) -> f64,
    windows: &[Option<(usize, usize)>],
    queue: &mut Vec<usize>,
    mut put: impl FnMut(usize, f64),
) {
    // A monotone queue: `queue[head..]`, values decreasing.
    queue.clear();
    let mut head = 0;
    let mut next = 0;
    for (i, w) in windows.iter().enumerate() {
        let Some((p0, p1)) = *w else {
            put(i, f64::INFINITY);
            continue;
        };
        next = next.max(p0);
        while next <= p1 {
            let v = get(next);
            while queue.len() > head && get(queue[queue.len() - 1]) <= v {
                queue.pop();
            }
            queue.push(next);
            next += 1;
        }
        while head < queue.len() && queue[head] < p0 {
            head += 1;
        }
        put(i, queue.get(head).map_or(f64::INFINITY, |&f| get(f)));
    }
}

/// The level-0 map (`n` x `n` over `[rmin, rmax]` at `w = wb`, Depths
/// relative to `wb`) that the map `from` at `w = wa < wb` proves, seen from
/// the cell `[lmin, lmax]` (frame coordinates, `lmax.z < wa`).
#[allow(clippy::too_many_arguments)]
pub fn reproject(
    from: &DepthMap,
    wa: f64,
    lmin: DVec3,
    lmax: DVec3,
    wb: f64,
    rmin: DVec2,
    rmax: DVec2,
    n: usize,
) -> Vec<f64> {
    let mut out = vec![f64::INFINITY; n * n];
    if !(lmax.z < wa && wa < wb) {
        return out;
    }
    let (amin, amax) = from.rect();
    let na = from.resolution();
    let src = from.level0();
    let along = |k: usize| {
        windows(
            (lmin[k], lmax[k]),
            (lmin.z, lmax.z),
            wa,
            wb,
            (amin[k], amax[k]),
            na,
            (rmin[k], rmax[k]),
            n,
        )
    };
    let (wu, wv) = (along(0), along(1));
    if wu.iter().all(Option::is_none) || wv.iter().all(Option::is_none) {
        return out;
    }
    // Source rows the target's rows need.
    let (r0, r1) = wv
        .iter()
        .flatten()
        .fold((usize::MAX, 0), |(a, b), w| (a.min(w.0), b.max(w.1)));
    // Rows of the source, maxima over each target column's window, stored
    // column by column (`cols[i * na + r]`) for the second pass.
    let mut cols = vec![f64::INFINITY; na * n];
    let mut finite = vec![false; n];
    let mut queue = Vec::with_capacity(na.max(n));
    for r in r0..=r1 {
        let row = &src[r * na..(r + 1) * na];
        if row.iter().all(|d| d.is_infinite()) {
            continue;
        }
        sliding_max(
            |p| row[p],
            &wu,
            &mut queue,
            |i, v| {
                cols[i * na + r] = v;
                finite[i] |= v.is_finite();
            },
        );
    }
    // Then per target column, maxima over each target row's window
    // (columns with nothing stay empty).
    let shift = wa - wb;
    for i in 0..n {
        if !finite[i] {
            continue;
        }
        let col = &cols[i * na..(i + 1) * na];
        sliding_max(
            |r| col[r],
            &wv,
            &mut queue,
            |j, v| out[j * n + i] = v + shift,
        );
    }
    out
}

/// The rectangle at `w = wb` of the points every segment from the cell
/// `[lmin, lmax]` to which crosses `w = wa` inside the rectangle `rect`
/// (empty, `min > max`, when there is none): where a reprojection of a map
/// over `rect` can land.
pub fn image(rect: (DVec2, DVec2), wa: f64, lmin: DVec3, lmax: DVec3, wb: f64) -> (DVec2, DVec2) {
    let (mut lo, mut hi) = (DVec2::NEG_INFINITY, DVec2::INFINITY);
    for k in 0..2 {
        for c in [lmin[k], lmax[k]] {
            for cw in [lmin.z, lmax.z] {
                // The crossing c + (x - c) t equals an end at x = c + (end - c) / t.
                let t = (wa - cw) / (wb - cw);
                lo[k] = lo[k].max(c + (rect.0[k] - c) / t);
                hi[k] = hi[k].min(c + (rect.1[k] - c) / t);
            }
        }
    }
    (lo, hi)
}

/// Whether the box `[qmin, qmax]` (world) is proved hidden by one of the
/// sweeps, on the plane just in front of it or just behind its front.
pub fn sweep_hides(
    sweeps: &[Sweep],
    cmin: DVec3,
    cmax: DVec3,
    qmin: DVec3,
    qmax: DVec3,
    slack: f64,
) -> bool {
    sweeps.iter().any(|s| {
        let (lmin, lmax) = s.frame.local_box(cmin, cmax);
        let (a, b) = s.frame.local_box(qmin, qmax);
        if a.z <= lmax.z {
            return false;
        }
        let k = s.planes.partition_point(|p| p.wp <= a.z);
        [k.checked_sub(1), Some(k)]
            .into_iter()
            .flatten()
            .filter_map(|i| s.planes.get(i))
            .any(|p| super::box_hidden(&p.map, lmin, lmax, a, b, p.wp, slack))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    #[test]
    fn sliding_maxima_match_brute_force() {
        let mut rng = Pcg64::seed_from_u64(3);
        for _ in 0..200 {
            let n = rng.random_range(1..40usize);
            let src: Vec<f64> = (0..n)
                .map(|_| {
                    if rng.random_bool(0.1) {
                        f64::INFINITY
                    } else {
                        rng.random::<f64>()
                    }
                })
                .collect();
            let m = rng.random_range(1..40usize);
            let (mut a, mut b) = (0usize, 0usize);
            let windows: Vec<Option<(usize, usize)>> = (0..m)
                .map(|_| {
                    a = (a + rng.random_range(0..3usize)).min(n - 1);
                    b = (b.max(a) + rng.random_range(0..3usize)).min(n - 1);
                    rng.random_bool(0.9).then_some((a, b))
                })
                .collect();
            let mut got = vec![0.0; m];
            sliding_max(|p| src[p], &windows, &mut Vec::new(), |i, v| got[i] = v);
            for (i, w) in windows.iter().enumerate() {
                let want = w.map_or(f64::INFINITY, |(a, b)| {
                    src[a..=b].iter().copied().fold(f64::NEG_INFINITY, f64::max)
                });
                assert_eq!(got[i], want, "window {i} {w:?}");
            }
        }
    }

    /// Every segment from a random cell point to a random point of a
    /// covered target pixel crosses the source plane in a covered source
    /// pixel, whose Depth the target's does not undercut.
    #[test]
    fn reprojected_pixels_are_in_the_umbra_of_the_source() {
        let mut rng = Pcg64::seed_from_u64(11);
        for case in 0..40 {
            let lmin = DVec3::new(
                rng.random_range(-2.0..0.0),
                rng.random_range(-2.0..0.0),
                -1.0,
            );
            let lmax =
                lmin + DVec3::new(rng.random_range(0.1..2.0), rng.random_range(0.1..2.0), 1.0);
            let wa = lmax.z + rng.random_range(0.2..3.0);
            let wb = wa + rng.random_range(0.05..3.0);
            let na = 32;
            let (amin, amax) = (DVec2::splat(-6.0), DVec2::splat(6.0));
            // A source map: random blobs of random depths.
            let mut level0 = vec![f64::INFINITY; na * na];
            for _ in 0..6 {
                let (ci, cj, r) = (
                    rng.random_range(0..na as i64),
                    rng.random_range(0..na as i64),
                    rng.random_range(2..12i64),
                );
                let d = -rng.random_range(0.0..1.0);
                for j in 0..na as i64 {
                    for i in 0..na as i64 {
                        if (i - ci).abs() <= r && (j - cj).abs() <= r {
                            let p = &mut level0[(j as usize) * na + i as usize];
                            *p = p.min(d);
                        }
                    }
                }
            }
            let from = DepthMap::from_level0(amin, amax, na, level0.clone());
            let n = 16;
            let grow = rng.random_range(0.5..2.0);
            let (rmin, rmax) = (amin * grow, amax * grow);
            let out = reproject(&from, wa, lmin, lmax, wb, rmin, rmax, n);
            let pb = (rmax - rmin) / n as f64;
            let pa = (amax - amin) / na as f64;
            let mut covered = 0;
            for j in 0..n {
                for i in 0..n {
                    let d = out[j * n + i];
                    if !d.is_finite() {
                        continue;
                    }
                    covered += 1;
                    for _ in 0..50 {
                        let c = lmin
                            + (lmax - lmin) * DVec3::new(rng.random(), rng.random(), rng.random());
                        let x = rmin
                            + pb * DVec2::new(
                                i as f64 + rng.random::<f64>(),
                                j as f64 + rng.random::<f64>(),
                            );
                        let t = (wa - c.z) / (wb - c.z);
                        let p = c.truncate() + (x - c.truncate()) * t;
                        let s = ((p - amin) / pa).floor();
                        assert!(
                            s.x >= 0.0 && s.y >= 0.0 && s.x < na as f64 && s.y < na as f64,
                            "case {case}: off the source map"
                        );
                        let src = level0[s.y as usize * na + s.x as usize];
                        assert!(
                            src.is_finite(),
                            "case {case}: crosses an empty source pixel"
                        );
                        assert!(wa + src <= wb + d + 1e-12, "case {case}: Depth undercut");
                    }
                }
            }
            let _ = covered;
        }
    }

    #[test]
    fn a_full_source_reprojects_to_a_full_centre() {
        let na = 64;
        let from = DepthMap::from_level0(
            DVec2::splat(-10.0),
            DVec2::splat(10.0),
            na,
            vec![-0.5; na * na],
        );
        let (lmin, lmax) = (DVec3::new(-1.0, -1.0, -1.0), DVec3::ZERO);
        let out = reproject(
            &from,
            2.0,
            lmin,
            lmax,
            3.0,
            DVec2::splat(-4.0),
            DVec2::splat(4.0),
            8,
        );
        // Depth: the source's -0.5 at w = 2, from w = 3.
        assert!(out.iter().all(|&d| d == -1.5), "{out:?}");
        // Off the source map: nothing.
        let far = reproject(
            &from,
            2.0,
            lmin,
            lmax,
            3.0,
            DVec2::splat(-40.0),
            DVec2::splat(40.0),
            8,
        );
        assert!(far[0].is_infinite() && far[3 * 8 + 3].is_finite());
    }
}
