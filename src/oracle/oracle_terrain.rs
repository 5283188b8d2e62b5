//! Terrains as solids: an object whose triangles cover a rectangle of the
//! ground once each, a continuous height field `z = h(x, y)` over it (a
//! city's hills), hides what lies below its surface from viewpoints above
//! it, as a closed solid hides its inside.
//!
//! **Why.** Over the rectangle `R`, every point `(x, y)` lies under exactly
//! one triangle of the surface (below), so `h` is single-valued and
//! continuous there. A segment whose ends project into `R` (convex, so the
//! whole segment does) and which starts above the surface and ends below
//! it meets the surface between them: `z - h` changes sign along it. The
//! tracer, watertight on the welded mesh, hits a triangle there. The
//! tracer's f32 rounding moves a ray by up to the slack `s` (see
//! [`super::tracer_slack`]), which moves a point's height above the
//! surface by at most `s (1 + g)`, `g` the steepest slope of a triangle:
//! with both ends farther than that from the surface, on their sides,
//! the rounded ray crosses it too. So a Depth Map may hold a terrain's cut
//! on its plane at Depth 0, where the plane lies below the surface by that
//! margin, for cells above the surface by it: a ray from the cell through
//! such a pixel has hit the terrain before the plane.
//!
//! **Covering once.** The object's triangles are welded by their corners'
//! bits; each must have a positive area seen from above (all of them, or
//! all negative: a surface facing down), and no directed edge may occur
//! twice. The edges whose reverse is missing bound the surface; none may
//! meet `R`. Then over `R` the number of triangles above a point is the
//! winding number of that boundary around it (all triangles count with
//! the same sign), constant on `R`, and it must be one at `R`'s centre.
//! `R` is the largest rectangle of the surface's box's shape about its
//! centre that no boundary edge meets (a terrain cut from a slightly
//! rotated grid has a ragged rim; a hole shrinks `R` to clear it), and it
//! must keep a quarter of the box; it depends on no order (an earlier
//! greedy pull-in did, and a hash map's order differs from run to run, a
//! review found).
//! The area signs are exact (differences of f32 corners are exact in
//! f64); the edge-against-`R` and winding tests are rounded, which an
//! edge counting as meeting `R` within a billionth of its size, and the
//! cells' and pixels' distance from `R`'s sides (the slack) absorb.
//!
//! **Heights.** A grid over `R` holds, per cell, the lowest corner of
//! the triangles whose boxes meet the cell (grown by a billionth of `R`,
//! past the rounding of finding the cells), and in levels of 2 x 2
//! blocks above it the lowest of each block: the surface over any part
//! of a cell or block is no lower. The highest point over a cell's ground
//! is found exactly, by clipping the triangles listed in its grid cells.

use glam::{DVec2, DVec3, Vec3};
use std::collections::HashMap;

use super::oracle_project::Frame;
use super::oracle_shaft::clip_to_rect;

/// The fewest triangles an object needs to be tried as a terrain (a
/// ground plane of two triangles hides only what is under the ground).
const MIN_TRIANGLES: usize = 2;

/// The steepest slope a terrain's triangle may have (a cliff's nearly
/// vertical faces make the margin grow past any use).
const MAX_SLOPE: f64 = 100.0;

/// The most grid cells along a side of a terrain's height grid.
const MAX_GRID: usize = 1024;

/// A terrain: a height field over the rectangle `[lo, hi]` of the ground.
#[derive(Debug, Clone)]
pub struct Terrain {
    /// The object whose surface it is.
    pub object: u32,
    /// The rectangle (x, y) over which the surface covers the ground once.
    pub lo: DVec2,
    /// See `lo`.
    pub hi: DVec2,
    /// The lowest and highest height of the surface over `R`.
    pub zmin: f64,
    /// See `zmin`.
    pub zmax: f64,
    /// The steepest slope of a triangle over `R`.
    slope: f64,
    /// The height grid: `n.x` by `n.y` cells of `step` from `lo`.
    n: [usize; 2],
    step: DVec2,
    /// Per grid cell, a height at or below the surface anywhere over it
    /// (row by row, `y` slowest); then the same over blocks of 2 x 2, 4 x
    /// 4, ... cells (`lows[k]` for blocks of `2^k`, `lows[0]` the grid's).
    lows: Vec<Vec<f64>>,
    /// Per grid cell, the triangles whose boxes meet it (`first[k]..first[k
    /// + 1]` of `listed`), for the exact highest point over a rectangle.
    first: Vec<u32>,
    listed: Vec<u32>,
    /// The triangles over `R`, their corners.
    triangles: Vec<[DVec3; 3]>,
}

impl Terrain {
    /// The object's triangles as a terrain, when they cover a rectangle of
    /// the ground once (see the module's doc); `None` otherwise.
    pub fn detect(object: u32, triangles: &[[Vec3; 3]]) -> Option<Terrain> {
        if triangles.len() < MIN_TRIANGLES {
            return None;
        }
        // First the cheap refusal (most objects have upright faces): one
        // orientation seen from above, no triangle on edge (the same test
        // is made exactly below, on the welded corners).
        let seen_from_above = |t: &[Vec3; 3]| {
            let [a, b, c] = t.map(|v| v.as_dvec3().truncate());
            (b - a).perp_dot(c - a)
        };
        let first = seen_from_above(&triangles[0]).signum();
        if triangles.iter().any(|t| {
            (seen_from_above(t) * first).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        }) {
            return None;
        }
        // Welded (no triangle is left out: one whose welded corners
        // repeat has no area, refused above).
        let super::oracle_occluders::Mesh {
            vertices,
            triangles: tris,
        } = super::oracle_occluders::weld(triangles);
        if vertices.iter().any(|v| !v.is_finite()) {
            return None;
        }
        // One orientation seen from above, no triangle on edge.
        let area = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|i| vertices[i as usize].truncate());
            (b - a).perp_dot(c - a)
        };
        let sign = area(&tris[0]).signum();
        if tris.iter().any(|t| area(t) * sign <= 0.0) {
            return None;
        }
        // Directed edges, each once; those without their reverse bound
        // the surface.
        let mut edges: HashMap<(u32, u32), ()> = HashMap::with_capacity(3 * tris.len());
        for t in &tris {
            for k in 0..3 {
                if edges.insert((t[k], t[(k + 1) % 3]), ()).is_some() {
                    return None;
                }
            }
        }
        // (Sorted, so that nothing below sees a hash map's order, which
        // differs from run to run.)
        let mut pairs: Vec<(u32, u32)> = edges
            .keys()
            .filter(|&&(a, b)| !edges.contains_key(&(b, a)))
            .copied()
            .collect();
        pairs.sort_unstable();
        let boundary: Vec<[DVec2; 2]> = pairs
            .iter()
            .map(|&(a, b)| [a, b].map(|i| vertices[i as usize].truncate()))
            .collect();
        // The rectangle, within the surface's box.
        let (mut lo, mut hi) = vertices
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), v| {
                (a.min(v.truncate()), b.max(v.truncate()))
            });
        let full = (hi - lo).x * (hi - lo).y;
        if full <= 0.0 || !full.is_finite() {
            return None;
        }
        // An edge counts as meeting `R` within half of `span` of it (past
        // the rounding of the clipping test); `R` is drawn to clear the
        // nearest by about `span`.
        let span = (hi - lo) * 1e-9;
        let meets = |[a, b]: [DVec2; 2], lo: DVec2, hi: DVec2| {
            clip_to_rect(a, b, lo - 0.5 * span, hi + 0.5 * span).is_some()
        };
        // The largest rectangle of the box's shape about its centre that
        // clears every boundary edge: the least, over the edges, of their
        // distance from the centre in the box's half-sizes (the larger of
        // the two axes' shares), less a margin past `span`.
        let (centre, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
        let reach = boundary
            .iter()
            .map(|&[a, b]| scaled_distance(a, b, centre, half))
            .fold(1.0f64, f64::min)
            - 4e-9;
        if reach <= 0.0 {
            return None;
        }
        (lo, hi) = (centre - reach * half, centre + reach * half);
        let size = hi - lo;
        if boundary.iter().any(|&edge| meets(edge, lo, hi)) || size.x * size.y < 0.25 * full {
            return None;
        }
        // Covered once: the boundary winds once around the centre.
        if winding(&boundary, 0.5 * (lo + hi)) != sign as i64 {
            return None;
        }
        // The triangles over the rectangle: slope and heights.
        let over_r = |t: &[u32; 3]| {
            let p = t.map(|i| vertices[i as usize]);
            let (a, b) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
            a.x <= hi.x && b.x >= lo.x && a.y <= hi.y && b.y >= lo.y
        };
        let over: Vec<&[u32; 3]> = tris.iter().filter(|t| over_r(t)).collect();
        let mut slope: f64 = 0.0;
        for t in &over {
            let [a, b, c] = t.map(|i| vertices[i as usize]);
            let n = (b - a).cross(c - a);
            slope = slope.max(n.truncate().length() / n.z.abs());
        }
        if slope > MAX_SLOPE {
            return None;
        }
        // (The heights' grid: about two cells a side per triangle.)
        let side = (2 * (over.len() as f64).sqrt().ceil() as usize).clamp(1, MAX_GRID);
        let cells = [side, side];
        let step = size / DVec2::new(side as f64, side as f64);
        let triangles: Vec<[DVec3; 3]> = over
            .iter()
            .map(|t| t.map(|i| vertices[i as usize]))
            .collect();
        // Each triangle's box, grown by a billionth of `R` (past the
        // rounding of the spans below), in grid cells.
        let grow = 1e-9 * (size.x + size.y);
        let span = |x: f64, axis: usize| {
            ((x - lo[axis]) / step[axis])
                .floor()
                .clamp(0.0, cells[axis] as f64 - 1.0) as usize
        };
        let ranges: Vec<[usize; 4]> = triangles
            .iter()
            .map(|p| {
                let (a, b) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
                [
                    span(a.x - grow, 0),
                    span(b.x + grow, 0),
                    span(a.y - grow, 1),
                    span(b.y + grow, 1),
                ]
            })
            .collect();
        let mut first = vec![0u32; side * side + 1];
        for &[i0, i1, j0, j1] in &ranges {
            for j in j0..=j1 {
                for i in i0..=i1 {
                    first[j * side + i + 1] += 1;
                }
            }
        }
        for k in 0..side * side {
            first[k + 1] += first[k];
        }
        let mut listed = vec![0u32; first[side * side] as usize];
        let mut fill = first.clone();
        let mut low = vec![f64::INFINITY; side * side];
        for (t, &[i0, i1, j0, j1]) in ranges.iter().enumerate() {
            let z = triangles[t].map(|p| p.z);
            let zlo = z[0].min(z[1]).min(z[2]);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let k = j * side + i;
                    listed[fill[k] as usize] = t as u32;
                    fill[k] += 1;
                    low[k] = low[k].min(zlo);
                }
            }
        }
        let (zmin, zmax) = triangles
            .iter()
            .flatten()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.z), b.max(p.z))
            });
        // Every cell is under some triangle (the surface covers `R`).
        if low.iter().any(|z| !z.is_finite()) {
            return None;
        }
        Some(Terrain {
            object,
            lo,
            hi,
            zmin,
            zmax,
            slope,
            n: cells,
            step,
            lows: min_levels(low, side),
            first,
            listed,
            triangles,
        })
    }

    /// How far from the surface a point must be, along `z`, for the
    /// tracer's rounding (`slack`) to keep it on its side.
    pub fn margin(&self, slack: f64) -> f64 {
        2.0 * slack * (1.0 + self.slope)
    }

    /// The grid column (along `axis`) of coordinate `x`, clamped to the
    /// grid: its floor, taken by truncation where it is positive (the
    /// same index; `floor` is a library call on baseline x86-64, and the
    /// shafts ask for these many times a test).
    fn column(&self, x: f64, axis: usize) -> usize {
        let v = (x - self.lo[axis]) / self.step[axis];
        let i = if v > 0.0 { v as usize } else { 0 };
        i.min(self.n[axis] - 1)
    }

    /// The grid cells over the ground rectangle `[a, b]` (within `R`).
    fn cells(&self, a: DVec2, b: DVec2) -> impl Iterator<Item = usize> + '_ {
        let at = |x: f64, axis: usize| self.column(x, axis);
        let (i0, i1, j0, j1) = (at(a.x, 0), at(b.x, 0), at(a.y, 1), at(b.y, 1));
        (j0..=j1).flat_map(move |j| (i0..=i1).map(move |i| j * self.n[0] + i))
    }

    /// A height at or below the surface over the ground rectangle `[a, b]`
    /// (within `R`): the lowest of the blocks over it, of the level where
    /// at most three span it a side.
    fn low_over(&self, a: DVec2, b: DVec2) -> f64 {
        let at = |x: f64, axis: usize| self.column(x, axis);
        let (mut i0, mut i1, mut j0, mut j1) = (at(a.x, 0), at(b.x, 0), at(a.y, 1), at(b.y, 1));
        let mut level = 0;
        while (i1 - i0).max(j1 - j0) > 2 && level + 1 < self.lows.len() {
            (i0, i1, j0, j1) = (i0 / 2, i1 / 2, j0 / 2, j1 / 2);
            level += 1;
        }
        let side = self.n[0].div_ceil(1 << level);
        let low = &self.lows[level];
        let mut out = f64::INFINITY;
        for j in j0..=j1 {
            for i in i0..=i1 {
                out = out.min(low[j * side + i]);
            }
        }
        out
    }

    /// The highest point of the surface over the ground rectangle `[a, b]`
    /// (within `R`): of each triangle that may lie over it, the highest
    /// corner of its part over the rectangle.
    fn highest(&self, a: DVec2, b: DVec2) -> f64 {
        let mut top = f64::NEG_INFINITY;
        let mut poly: Vec<DVec3> = Vec::with_capacity(8);
        let mut next: Vec<DVec3> = Vec::with_capacity(8);
        for k in self.cells(a, b) {
            for &t in &self.listed[self.first[k] as usize..self.first[k + 1] as usize] {
                poly.clear();
                poly.extend_from_slice(&self.triangles[t as usize]);
                // Clipped by x >= a.x, x <= b.x, y >= a.y, y <= b.y.
                for (axis, bound, keep_above) in [
                    (0, a.x, true),
                    (0, b.x, false),
                    (1, a.y, true),
                    (1, b.y, false),
                ] {
                    next.clear();
                    let inside = |p: &DVec3| {
                        if keep_above {
                            p[axis] >= bound
                        } else {
                            p[axis] <= bound
                        }
                    };
                    for i in 0..poly.len() {
                        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
                        if inside(&p) {
                            next.push(p);
                        }
                        if inside(&p) != inside(&q) {
                            let t = (bound - p[axis]) / (q[axis] - p[axis]);
                            next.push(p + (q - p) * t);
                        }
                    }
                    std::mem::swap(&mut poly, &mut next);
                    if poly.is_empty() {
                        break;
                    }
                }
                for p in &poly {
                    top = top.max(p.z);
                }
            }
        }
        top
    }

    /// Whether the ground rectangle `[a, b]` lies within `R` by `pad`.
    fn within(&self, a: DVec2, b: DVec2, pad: f64) -> bool {
        a.cmpge(self.lo + pad).all() && b.cmple(self.hi - pad).all()
    }

    /// Whether the cell `[cmin, cmax]` may use the terrain: over `R` and
    /// above the surface, both by the slack's margin.
    pub fn usable(&self, cmin: DVec3, cmax: DVec3, slack: f64) -> bool {
        let m = self.margin(slack);
        let (a, b) = (cmin.truncate() - slack, cmax.truncate() + slack);
        self.within(a, b, slack) && self.highest(a, b) + m < cmin.z
    }

    /// Whether the part of the upright plane `p[axis] = c` (`axis` x or
    /// y) over the ground from `u0` to `u1` across it and up to `ztop`
    /// lies over `R` and below the surface, both by the slack's margin.
    pub fn upright_below(
        &self,
        axis: usize,
        c: f64,
        (u0, u1): (f64, f64),
        ztop: f64,
        slack: f64,
    ) -> bool {
        let across = 1 - axis;
        let (mut a, mut b) = (DVec2::ZERO, DVec2::ZERO);
        (a[axis], b[axis], a[across], b[across]) = (c, c, u0, u1);
        u0 <= u1 && self.within(a, b, slack) && ztop < self.low_over(a, b) - self.margin(slack)
    }

    /// Where planes of an upright `frame` (`x` or `y`) in front of the cell
    /// `[cmin, cmax]` would best hold the terrain's cut: the `count`
    /// positions (`w` in the frame) of 32, spaced geometrically from the
    /// cell to the far side of `R`, where the ground across the cell's
    /// width rises highest as seen from the cell's top (its horizon).
    /// None for level frames.
    pub fn crests(&self, frame: Frame, cmin: DVec3, cmax: DVec3, count: usize) -> Vec<f64> {
        const SAMPLES: usize = 32;
        if frame.axis == 2 {
            return Vec::new();
        }
        let (lmin, lmax) = frame.local_box(cmin, cmax);
        let (a, b) = frame.local_box(self.lo.extend(self.zmin), self.hi.extend(self.zmax));
        let near = 0.5 * (lmax.z - lmin.z).max(1e-6);
        let far = b.z - lmax.z;
        if a.z > lmax.z || far <= near {
            return Vec::new();
        }
        let across = 1 - frame.axis;
        let (c0, c1) = (cmin[across], cmax[across]);
        let mut found: Vec<(f64, f64)> = (1..=SAMPLES)
            .filter_map(|k| {
                let d = near * (far / near).powf(k as f64 / SAMPLES as f64);
                let wp = lmax.z + d;
                let at = frame.world(DVec3::new(0.0, 0.0, wp))[frame.axis];
                let mut lo = DVec2::ZERO;
                let mut hi = DVec2::ZERO;
                lo[frame.axis] = at;
                hi[frame.axis] = at;
                lo[across] = c0;
                hi[across] = c1;
                self.within(lo, hi, 0.0)
                    .then(|| ((self.low_over(lo, hi) - cmax.z) / d, wp))
            })
            .collect();
        found.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.total_cmp(&y.1)));
        found.iter().take(count).map(|f| f.1).collect()
    }

    /// Draws the terrain's cut by the plane `w = wp` of `frame` into the
    /// `n` x `n` level-0 map over the plane rectangle `rect`, at Depth 0:
    /// the pixels over `R` (by the slack) wholly below the surface by the
    /// margin. Returns how many; only for cells it is
    /// [`Terrain::usable`] from.
    pub fn draw(
        &self,
        frame: Frame,
        wp: f64,
        rect: (DVec2, DVec2),
        n: usize,
        slack: f64,
        level0: &mut [f64],
    ) -> usize {
        let rmin = rect.0;
        let Some(pixel) = super::oracle_plane::pixel_size(rect, n) else {
            return 0;
        };
        let m = self.margin(slack);
        let at = frame.world(DVec3::new(0.0, 0.0, wp))[frame.axis];
        // Pixel `k`'s span along local `u` (k < n) or `v`.
        let span = |k: usize, axis: usize| {
            (
                rmin[axis] + k as f64 * pixel[axis],
                rmin[axis] + (k + 1) as f64 * pixel[axis],
            )
        };
        let mut count = 0;
        match frame.axis {
            // A level plane: local u = x, v = y; a pixel is below the
            // surface where the surface over it is above the plane.
            2 => {
                if at + m >= self.zmax {
                    return 0;
                }
                for j in 0..n {
                    let (y0, y1) = span(j, 1);
                    for i in 0..n {
                        let (x0, x1) = span(i, 0);
                        let (a, b) = (DVec2::new(x0, y0), DVec2::new(x1, y1));
                        if self.within(a, b, slack) && self.low_over(a, b) > at + m {
                            let d = &mut level0[j * n + i];
                            if *d > 0.0 {
                                *d = 0.0;
                            }
                            count += 1;
                        }
                    }
                }
            }
            // An upright plane x = at (local u = y, v = z) or y = at
            // (local u = z, v = x): per column of the horizontal axis, the
            // pixels wholly below the lowest surface over it.
            axis => {
                let (h, z) = if axis == 0 { (0, 1) } else { (1, 0) };
                let across = if axis == 0 { 0 } else { 1 };
                if !(at >= self.lo[across] + slack && at <= self.hi[across] - slack) {
                    return 0;
                }
                for c in 0..n {
                    let (g0, g1) = span(c, h);
                    let (a, b) = if axis == 0 {
                        (DVec2::new(at, g0), DVec2::new(at, g1))
                    } else {
                        (DVec2::new(g0, at), DVec2::new(g1, at))
                    };
                    if !self.within(a, b, slack) {
                        continue;
                    }
                    let top = self.low_over(a, b) - m;
                    for r in 0..n {
                        let (_, z1) = span(r, z);
                        if z1 < top {
                            let (i, j) = if axis == 0 { (c, r) } else { (r, c) };
                            let d = &mut level0[j * n + i];
                            if *d > 0.0 {
                                *d = 0.0;
                            }
                            count += 1;
                        }
                    }
                }
            }
        }
        count
    }
}

/// The levels of lowest heights over a `side` x `side` grid: the grid's,
/// then each block of 2 x 2 of the last level's (fewer at odd edges),
/// down to one.
fn min_levels(grid: Vec<f64>, side: usize) -> Vec<Vec<f64>> {
    let mut levels = vec![grid];
    let mut n = side;
    while n > 1 {
        let m = n.div_ceil(2);
        let last = levels.last().expect("a level");
        let mut next = vec![f64::INFINITY; m * m];
        for j in 0..n {
            for i in 0..n {
                let k = (j / 2) * m + i / 2;
                next[k] = next[k].min(last[j * n + i]);
            }
        }
        levels.push(next);
        n = m;
    }
    levels
}

/// The least over the segment `[a, b]` of a point's distance from
/// `centre`, each axis's in units of `half` and the larger of the two: the
/// segment stays outside the open rectangle `centre +- t half` for `t` up
/// to it. (The distance is convex and piecewise linear along the
/// segment: its least is at an end, where one axis's share is zero, or
/// where the two shares are equal.)
fn scaled_distance(a: DVec2, b: DVec2, centre: DVec2, half: DVec2) -> f64 {
    let (p, d) = ((a - centre) / half, (b - a) / half);
    let at = |s: f64| {
        let q = p + d * s;
        q.x.abs().max(q.y.abs())
    };
    let mut ss = vec![0.0, 1.0];
    for axis in 0..2 {
        if d[axis] != 0.0 {
            ss.push(-p[axis] / d[axis]);
        }
    }
    // p.x + d.x s = +-(p.y + d.y s).
    for sign in [1.0, -1.0] {
        let k = d.x - sign * d.y;
        if k != 0.0 {
            ss.push((sign * p.y - p.x) / k);
        }
    }
    ss.into_iter()
        .filter(|s| (0.0..=1.0).contains(s))
        .map(at)
        .fold(f64::INFINITY, f64::min)
}

/// The winding number of the directed edges `boundary` around `p` (not on
/// any of them): the signed crossings of the ray from `p` along +x.
fn winding(boundary: &[[DVec2; 2]], p: DVec2) -> i64 {
    let mut w = 0;
    for &[a, b] in boundary {
        if (a.y <= p.y) != (b.y <= p.y) {
            let x = a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y);
            if x > p.x {
                w += if b.y > a.y { 1 } else { -1 };
            }
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The height of the hill at `(x, y)`.
    fn hill(x: f32, y: f32) -> f32 {
        8.0 * (-((x - 20.0).powi(2) + (y - 20.0).powi(2)) / 80.0).exp()
    }

    /// A grid of `k` x `k` squares over `[0, 40]^2`, two triangles each
    /// (counter-clockwise from above), turned by `turn` radians about the
    /// centre and with heights from `hill`; its rim is ragged once turned.
    fn grid(k: usize, turn: f32) -> Vec<[Vec3; 3]> {
        let (s, c) = turn.sin_cos();
        let at = |i: usize, j: usize| {
            let (x, y) = (40.0 * i as f32 / k as f32, 40.0 * j as f32 / k as f32);
            let (u, v) = (x - 20.0, y - 20.0);
            let (x, y) = (20.0 + c * u - s * v, 20.0 + s * u + c * v);
            Vec3::new(x, y, hill(x, y))
        };
        let mut out = Vec::new();
        for j in 0..k {
            for i in 0..k {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                out.push([a, b, c]);
                out.push([a, c, d]);
            }
        }
        out
    }

    /// The surface's height at `p` (its triangle over `p`, by brute force).
    fn height(tris: &[[Vec3; 3]], p: DVec2) -> Option<f64> {
        tris.iter().find_map(|t| {
            let [a, b, c] = t.map(|v| v.as_dvec3());
            let (e, f, q) = ((b - a).truncate(), (c - a).truncate(), p - a.truncate());
            let d = e.perp_dot(f);
            let (u, v) = (q.perp_dot(f) / d, e.perp_dot(q) / d);
            (u >= -1e-12 && v >= -1e-12 && u + v <= 1.0 + 1e-12)
                .then_some(a.z + u * (b.z - a.z) + v * (c.z - a.z))
        })
    }

    #[test]
    fn a_hill_on_a_turned_grid_is_a_terrain_within_its_ragged_rim() {
        for turn in [0.0f32, 0.01, -0.3] {
            let tris = grid(24, turn);
            let t = Terrain::detect(7, &tris).expect("a terrain");
            assert_eq!(t.object, 7);
            // R lies within the surface's cover: every point of it (a
            // lattice) is under a triangle.
            for i in 0..=20 {
                for j in 0..=20 {
                    let p = t.lo + (t.hi - t.lo) * DVec2::new(i as f64, j as f64) / 20.0;
                    assert!(height(&tris, p).is_some(), "{turn}: {p} not covered");
                }
            }
            let area = (t.hi - t.lo).x * (t.hi - t.lo).y;
            assert!(
                area > 0.8 * 1600.0 * (1.0 - 2.0 * turn.abs() as f64),
                "{turn}: {area}"
            );
            assert!(t.zmax > 7.9 && t.zmin < 0.1);
        }
        // Facing down (every triangle reversed) is one too.
        let down: Vec<[Vec3; 3]> = grid(8, 0.1).iter().map(|t| [t[0], t[2], t[1]]).collect();
        assert!(Terrain::detect(0, &down).is_some());
    }

    #[test]
    fn what_is_not_a_height_field_is_no_terrain() {
        let tris = grid(10, 0.0);
        // One triangle turned over: two layers over its part.
        let mut flipped = tris.clone();
        flipped[57] = [flipped[57][0], flipped[57][2], flipped[57][1]];
        assert!(Terrain::detect(0, &flipped).is_none());
        // A second layer above: the rim winds twice around the centre.
        let mut doubled = tris.clone();
        doubled.extend(tris.iter().map(|t| t.map(|v| v + Vec3::new(0.0, 0.0, 5.0))));
        assert!(Terrain::detect(0, &doubled).is_none());
        // A triangle twice: a directed edge twice.
        let mut twice = tris.clone();
        twice.push(tris[3]);
        assert!(Terrain::detect(0, &twice).is_none());
        // A box: upright faces cover no ground.
        let mut cube = Vec::new();
        crate::scene::procedural::shapes::push_box(&mut cube, Vec3::ZERO, Vec3::ONE);
        assert!(Terrain::detect(0, &cube).is_none());
        // A non-finite corner.
        let mut nan = tris.clone();
        nan[0][0].z = f32::NAN;
        assert!(Terrain::detect(0, &nan).is_none());
    }

    #[test]
    fn a_hole_is_left_outside_the_rectangle() {
        let mut tris = grid(20, 0.0);
        // The two triangles of the square at (17, 3) removed.
        let k = 2 * (3 * 20 + 17);
        tris.drain(k..k + 2);
        let t = Terrain::detect(0, &tris).expect("a terrain beside the hole");
        let (hole_lo, hole_hi) = (DVec2::new(34.0, 6.0), DVec2::new(36.0, 8.0));
        assert!(
            t.hi.x <= hole_lo.x
                || t.lo.x >= hole_hi.x
                || t.hi.y <= hole_lo.y
                || t.lo.y >= hole_hi.y,
            "{} {}",
            t.lo,
            t.hi
        );
        // One near the middle leaves less than a quarter: no terrain.
        let mut tris = grid(20, 0.0);
        let k = 2 * (9 * 20 + 14);
        tris.drain(k..k + 2);
        assert!(Terrain::detect(0, &tris).is_none());
    }

    /// The rectangle depends on nothing but the triangles (an earlier
    /// pull-in took the rim's edges in a hash map's order, which changes
    /// from run to run), and is the same with the triangles listed in
    /// another order.
    #[test]
    fn the_rectangle_is_the_same_whatever_the_order() {
        let tris = grid(20, 0.13);
        let t = Terrain::detect(0, &tris).unwrap();
        let mut reversed = tris.clone();
        reversed.reverse();
        for _ in 0..4 {
            for other in [&tris, &reversed] {
                let u = Terrain::detect(0, other).unwrap();
                assert_eq!((t.lo, t.hi), (u.lo, u.hi));
            }
        }
    }

    /// Every pixel `draw` fills lies below the surface (points of it, by
    /// brute force), over every frame and plane of a sweep through the hill,
    /// and a cell is usable only above the surface.
    #[test]
    fn the_cuts_lie_below_the_surface() {
        let tris = grid(16, 0.2);
        let t = Terrain::detect(0, &tris).unwrap();
        let slack = 1e-5;
        let rect = (DVec2::new(-5.0, -5.0), DVec2::new(45.0, 45.0));
        let mut filled = 0;
        // (Pixels of 8 m span about ten grid cells: the coarser levels.)
        for (n, frame) in [48, 6].into_iter().flat_map(|n| Frame::ALL.map(|f| (n, f))) {
            for k in 0..12 {
                let at = -2.0 + 12.0 * k as f64 / 11.0;
                let at = if frame.axis == 2 { at } else { 3.0 * at + 5.0 };
                let wp = frame.local(DVec3::splat(at)).z;
                let mut map = vec![f64::INFINITY; n * n];
                filled += t.draw(frame, wp, rect, n, slack, &mut map);
                let pixel = (rect.1 - rect.0) / n as f64;
                for j in 0..n {
                    for i in 0..n {
                        if map[j * n + i] != 0.0 {
                            continue;
                        }
                        for (fu, fv) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]
                        {
                            let l = DVec3::new(
                                rect.0.x + (i as f64 + fu) * pixel.x,
                                rect.0.y + (j as f64 + fv) * pixel.y,
                                wp,
                            );
                            let p = frame.world(l);
                            let h = height(&tris, p.truncate()).expect("over the surface");
                            assert!(p.z < h, "{} at {at}: {p} above {h}", frame.name());
                        }
                    }
                }
            }
        }
        assert!(filled > 1000, "{filled}");
        // Usable: above the surface over the whole cell only.
        // The mesh's highest point over the cell's ground, by a lattice
        // 2.5 cm apart (on triangles 2.5 m wide, of slopes below one).
        let mut hmax = f64::NEG_INFINITY;
        for i in 0..=40 {
            for j in 0..=40 {
                let p = DVec2::new(11.5 + i as f64 / 40.0, 19.5 + j as f64 / 40.0);
                hmax = hmax.max(height(&tris, p).unwrap());
            }
        }
        let (a, b) = (DVec2::new(11.5, 19.5), DVec2::new(12.5, 20.5));
        assert!(t.usable(a.extend(hmax + 0.05), b.extend(hmax + 1.0), slack));
        assert!(!t.usable(a.extend(hmax - 0.05), b.extend(hmax + 1.0), slack));
        // On the hill's flank, a cell whose lower corner is above the
        // surface there but whose uphill side dips into it.
        let (a, b) = (
            DVec3::new(14.0, 14.0, hill(14.0, 14.0) as f64 + 0.1),
            DVec3::new(18.0, 18.0, 9.0),
        );
        assert!(!t.usable(a, b, slack));
        // Beyond the rectangle.
        assert!(!t.usable(
            DVec3::new(-3.0, 5.0, 10.0),
            DVec3::new(-1.0, 6.0, 11.0),
            slack
        ));
    }
}
