//! A projection plane's Depth Map (papers/001 sec. 2.3-2.4): a pixel grid
//! over a finite rectangle of the plane, each pixel holding the smallest
//! Depth of the occluders whose Projection covers it *entirely*, and a max
//! pyramid over it (the Hierarchical Depth Map) to test occludee
//! rectangles.
//!
//! Conservative rasterisation both ways: an occluder counts only in pixels
//! its Projection covers fully (all four corners inside the convex polygon,
//! with a margin against rounding); an occludee counts in every pixel its
//! rectangle touches (with a margin).
//!
//! Coordinates here are the plane's own 2D (u, v); `polygon` helpers work
//! on convex polygons in counter-clockwise order.

use glam::DVec2;

/// Relative margin against rounding, in pixels.
const MARGIN: f64 = 1e-6;

/// The x range where the horizontal line at `y` meets a convex polygon.
fn span_at(poly: &[DVec2], y: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        if p.y == y {
            lo = lo.min(p.x);
            hi = hi.max(p.x);
        }
        if (p.y - y) * (q.y - y) < 0.0 {
            let x = p.x + (y - p.y) * (q.x - p.x) / (q.y - p.y);
            lo = lo.min(x);
            hi = hi.max(x);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// One occluder ready for rasterisation: its views from the cell's
/// corners, convex counter-clockwise polygons in the map's pixel
/// coordinates (pixel `(i, j)` covers `[i, i + 1] x [j, j + 1]`), and its
/// Depth. Its Projection is the intersection of the views.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProjectedOccluder {
    /// The views, one per cell corner.
    pub views: Vec<Vec<DVec2>>,
    /// The occluder's maximum depth.
    pub depth: f64,
}

/// One Depth Map to rasterise: its side in pixels and its occluders.
pub type MapJob<'a> = (usize, &'a [ProjectedOccluder]);

/// The size of a pixel of an `n` x `n` map over the plane rectangle
/// `rect`, or `None` when the rectangle has no area (or is not a number):
/// such a map holds nothing.
pub fn pixel_size((rmin, rmax): (DVec2, DVec2), n: usize) -> Option<DVec2> {
    let pixel = (rmax - rmin) / n as f64;
    (pixel.x > 0.0 && pixel.y > 0.0).then_some(pixel)
}

/// The CPU rasteriser: the `n` x `n` level-0 map (row `j` at `j * n..`)
/// holding in each pixel the smallest Depth among the occluders whose
/// Projection (intersection of views, computed exactly by clipping)
/// covers the pixel entirely; +inf elsewhere. The reference for the GPU.
pub fn cpu_rasterise(n: usize, occluders: &[ProjectedOccluder]) -> Vec<f64> {
    let mut map = vec![f64::INFINITY; n * n];
    let mut buffers = super::oracle_project::ViewBuffers::default();
    for o in occluders {
        super::oracle_project::intersect_views_into(&o.views, &mut buffers);
        draw_pixels(&mut map, n, &buffers.out, o.depth);
    }
    map
}

/// Writes `depth` into the pixels of the `n` x `n` `map` that the convex
/// counter-clockwise polygon `poly` (pixel coordinates) covers entirely,
/// where it is smaller; returns how many pixels it covers.
fn draw_pixels(map: &mut [f64], n: usize, poly: &[DVec2], depth: f64) -> usize {
    if poly.len() < 3 {
        return 0;
    }
    let (lo, hi) = poly
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let j0 = (lo.y + MARGIN).ceil().max(0.0) as usize;
    let j1 = (hi.y - MARGIN).floor().min(n as f64).max(0.0) as usize;
    let mut covered = 0;
    for j in j0..j1 {
        let (y0, y1) = (j as f64, (j + 1) as f64);
        let (Some((a0, b0)), Some((a1, b1))) = (span_at(poly, y0), span_at(poly, y1)) else {
            continue;
        };
        let (a, b) = (a0.max(a1), b0.min(b1));
        let i0 = (a + MARGIN).ceil().max(0.0) as usize;
        let i1 = (b - MARGIN).floor().min(n as f64);
        if i1 < 0.0 {
            continue;
        }
        let row = &mut map[j * n..(j + 1) * n];
        for d in row.iter_mut().take(i1 as usize).skip(i0) {
            *d = d.min(depth);
            covered += 1;
        }
    }
    covered
}

/// A Depth Map over the rectangle `[min, max]` of a plane, `n` x `n`
/// pixels (`n` a power of two), with its max pyramid.
#[derive(Clone, Debug)]
pub struct DepthMap {
    min: DVec2,
    max: DVec2,
    n: usize,
    /// Pyramid levels; level 0 is the full map, each level's texel the max
    /// of its 2x2 children; the last is 1 x 1. Empty pixels are +inf.
    levels: Vec<Vec<f64>>,
}

impl DepthMap {
    /// An empty map (every pixel +inf: nothing occludes).
    #[cfg(test)]
    pub fn new(min: DVec2, max: DVec2, n: usize) -> Self {
        debug_assert!(n.is_power_of_two());
        Self {
            min,
            max,
            n,
            levels: vec![vec![f64::INFINITY; n * n]],
        }
    }

    /// A pixel's size on the plane.
    fn pixel(&self) -> DVec2 {
        (self.max - self.min) / self.n as f64
    }

    /// A plane point in pixel coordinates (pixel `(i, j)` covers
    /// `[i, i + 1] x [j, j + 1]`).
    #[cfg(test)]
    pub fn to_pixels(&self, p: DVec2) -> DVec2 {
        (p - self.min) / self.pixel()
    }

    /// A map from its level-0 pixels (row `j` at `j * n..`; +inf where no
    /// occluder), as the GPU rasteriser returns them.
    pub fn from_level0(min: DVec2, max: DVec2, n: usize, level0: Vec<f64>) -> Self {
        assert_eq!(level0.len(), n * n, "a depth map of {n} x {n} pixels");
        Self {
            min,
            max,
            n,
            levels: vec![level0],
        }
    }

    /// Writes `depth` into the pixels the convex counter-clockwise `poly`
    /// (in plane coordinates) covers entirely, where it is smaller than
    /// what is there; returns how many pixels it covers (the CPU
    /// rasteriser's rule; tests draw with it).
    #[cfg(test)]
    pub fn draw_occluder(&mut self, poly: &[DVec2], depth: f64) -> usize {
        let px: Vec<DVec2> = poly.iter().map(|&p| self.to_pixels(p)).collect();
        draw_pixels(&mut self.levels[0], self.n, &px, depth)
    }

    /// The rectangle the map covers, `(min, max)`.
    pub fn rect(&self) -> (DVec2, DVec2) {
        (self.min, self.max)
    }

    /// Pixels on a side.
    pub fn resolution(&self) -> usize {
        self.n
    }

    /// The full-resolution pixels (row `j` at `j * n..`; +inf where empty).
    pub fn level0(&self) -> &[f64] {
        &self.levels[0]
    }

    /// Pixels holding some occluder.
    pub fn filled(&self) -> usize {
        self.levels[0].iter().filter(|d| d.is_finite()).count()
    }

    /// Builds the max pyramid; call after the last occluder.
    pub fn build_pyramid(&mut self) {
        self.levels.truncate(1);
        let mut n = self.n;
        while n > 1 {
            let prev = self.levels.last().expect("level 0 exists");
            let m = n / 2;
            let mut next = vec![0.0; m * m];
            for j in 0..m {
                for i in 0..m {
                    let at = |x: usize, y: usize| prev[y * n + x];
                    next[j * m + i] = at(2 * i, 2 * j)
                        .max(at(2 * i + 1, 2 * j))
                        .max(at(2 * i, 2 * j + 1))
                        .max(at(2 * i + 1, 2 * j + 1));
                }
            }
            self.levels.push(next);
            n = m;
        }
    }

    /// Whether every pixel that the rectangle `[lo, hi]` touches holds a
    /// depth below `depth` (false when the rectangle leaves the map). Uses
    /// the pyramid from the top.
    pub fn hides(&self, lo: DVec2, hi: DVec2, depth: f64) -> bool {
        self.test_rect(lo, hi, depth).is_ok()
    }

    /// [`DepthMap::hides`], saying on failure which level-0 pixel failed
    /// (`None` when the rectangle leaves the map).
    pub fn test_rect(&self, lo: DVec2, hi: DVec2, depth: f64) -> Result<(), Option<[i64; 2]>> {
        if lo.x < self.min.x || lo.y < self.min.y || hi.x > self.max.x || hi.y > self.max.y {
            return Err(None);
        }
        let px = self.pixel();
        let to_pixel = |v: f64, min: f64, size: f64| ((v - min) / size).floor() as i64;
        let i0 = to_pixel(lo.x, self.min.x, px.x) - 1;
        let i1 = to_pixel(hi.x, self.min.x, px.x) + 1;
        let j0 = to_pixel(lo.y, self.min.y, px.y) - 1;
        let j1 = to_pixel(hi.y, self.min.y, px.y) + 1;
        // One pixel more on every side: touched pixels, with room for
        // rounding. Outside the map (the rectangle fits, the margin does
        // not) clamp: those pixels are within the rectangle's touch anyway.
        let n = self.n as i64;
        let (i0, i1, j0, j1) = (i0.max(0), i1.min(n - 1), j0.max(0), j1.min(n - 1));
        match self.below(self.levels.len() - 1, 0, 0, [i0, i1, j0, j1], depth) {
            None => Ok(()),
            Some(p) => Err(Some(p)),
        }
    }

    /// Whether the level-0 pixel `p`, grown by a pixel on every side, meets
    /// the convex counter-clockwise polygon `poly` (plane coordinates):
    /// then [`DepthMap::hides_polygon`] tests that pixel.
    pub fn pixel_meets_polygon(&self, p: [i64; 2], poly: &[DVec2]) -> bool {
        let px = self.pixel();
        let pixels: Vec<DVec2> = poly.iter().map(|&q| (q - self.min) / px).collect();
        let (x0, y0) = (p[0] as f64 - 1.0, p[1] as f64 - 1.0);
        square_meets_convex(x0, y0, x0 + 3.0, y0 + 3.0, &pixels)
    }

    /// Whether every pixel that the convex counter-clockwise polygon `poly`
    /// (plane coordinates) touches, grown by a pixel on every side as in
    /// [`DepthMap::hides`], holds a depth below `depth` (false when the
    /// polygon leaves the map or is degenerate).
    pub fn hides_polygon(&self, poly: &[DVec2], depth: f64) -> bool {
        if poly.len() < 3 {
            return false;
        }
        let (lo, hi) = poly
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        if !(lo.is_finite() && hi.is_finite())
            || lo.x < self.min.x
            || lo.y < self.min.y
            || hi.x > self.max.x
            || hi.y > self.max.y
        {
            return false;
        }
        let px = self.pixel();
        let pixels: Vec<DVec2> = poly.iter().map(|&p| (p - self.min) / px).collect();
        self.below_polygon(self.levels.len() - 1, 0, 0, &pixels, depth)
    }

    fn below_polygon(&self, level: usize, i: i64, j: i64, poly: &[DVec2], depth: f64) -> bool {
        let span = (1i64 << level) as f64;
        let (x0, y0) = (i as f64 * span - 1.0, j as f64 * span - 1.0);
        let (x1, y1) = (x0 + span + 2.0, y0 + span + 2.0);
        if !square_meets_convex(x0, y0, x1, y1, poly) {
            return true;
        }
        let size = (self.n >> level) as i64;
        if self.levels[level][(j * size + i) as usize] < depth {
            return true;
        }
        if level == 0 {
            return false;
        }
        (0..2).all(|dj| {
            (0..2).all(|di| self.below_polygon(level - 1, 2 * i + di, 2 * j + dj, poly, depth))
        })
    }

    /// `None` when every pixel of the range `r` under the node holds a
    /// depth below `depth`, else a pixel that does not.
    fn below(&self, level: usize, i: i64, j: i64, r: [i64; 4], depth: f64) -> Option<[i64; 2]> {
        let span = 1i64 << level;
        let (x0, y0) = (i * span, j * span);
        if x0 > r[1] || x0 + span - 1 < r[0] || y0 > r[3] || y0 + span - 1 < r[2] {
            return None;
        }
        let size = (self.n >> level) as i64;
        if self.levels[level][(j * size + i) as usize] < depth {
            return None;
        }
        if level == 0 {
            return Some([i, j]);
        }
        (0..2)
            .flat_map(|dj| (0..2).map(move |di| (di, dj)))
            .find_map(|(di, dj)| self.below(level - 1, 2 * i + di, 2 * j + dj, r, depth))
    }
}

/// Whether the square `[x0, x1] x [y0, y1]` meets the convex
/// counter-clockwise polygon `poly` (separating axes: the square's, then
/// the polygon's edge normals; touching counts as meeting).
fn square_meets_convex(x0: f64, y0: f64, x1: f64, y1: f64, poly: &[DVec2]) -> bool {
    let (lo, hi) = poly
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    if hi.x < x0 || hi.y < y0 || lo.x > x1 || lo.y > y1 {
        return false;
    }
    let corners = [
        DVec2::new(x0, y0),
        DVec2::new(x1, y0),
        DVec2::new(x1, y1),
        DVec2::new(x0, y1),
    ];
    for k in 0..poly.len() {
        let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
        if corners.iter().all(|&c| (q - p).perp_dot(c - p) < 0.0) {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sq(a: f64, b: f64) -> Vec<DVec2> {
        crate::geom::polygon::rectangle(DVec2::splat(a), DVec2::splat(b))
    }

    #[test]
    fn occluders_cover_only_whole_pixels_and_occludees_every_touched_one() {
        let mut m = DepthMap::new(DVec2::ZERO, DVec2::splat(8.0), 8);
        // A square from 1.5 to 5.5 covers pixels 2..5 fully (3 x 3).
        assert_eq!(m.draw_occluder(&sq(1.5, 5.5), 1.0), 9);
        // Exactly on pixel edges, the edge pixels are dropped (a margin
        // against rounding); just beyond them they count.
        let mut edge = DepthMap::new(DVec2::ZERO, DVec2::splat(8.0), 8);
        assert_eq!(edge.draw_occluder(&sq(2.0, 6.0), 1.0), 4);
        let mut m2 = DepthMap::new(DVec2::ZERO, DVec2::splat(8.0), 8);
        assert_eq!(m2.draw_occluder(&sq(1.999, 6.001), 1.0), 16);
        m.build_pyramid();
        m2.build_pyramid();
        // An occludee inside the fully covered pixels, behind: hidden.
        assert!(m.hides(DVec2::splat(3.2), DVec2::splat(3.8), 2.0));
        // In front of the occluder: not hidden.
        assert!(!m.hides(DVec2::splat(3.2), DVec2::splat(3.8), 0.5));
        // Touching a partly covered pixel: not hidden.
        assert!(!m.hides(DVec2::splat(3.0), DVec2::splat(5.2), 2.0));
        // Occludee rectangles are grown by a pixel: inside with room.
        assert!(m2.hides(DVec2::splat(3.5), DVec2::splat(4.5), 2.0));
        assert!(!m2.hides(DVec2::splat(2.5), DVec2::splat(4.5), 2.0));
        // Leaving the map: never hidden.
        assert!(!m.hides(DVec2::splat(-0.5), DVec2::splat(3.0), 2.0));
    }

    #[test]
    fn a_slanted_polygon_is_tested_on_its_own_pixels_not_its_rectangle() {
        // Covered: everything but the corner pixels (0, 7) and (7, 0).
        let mut level0 = vec![1.0; 64];
        level0[7 * 8] = f64::INFINITY;
        level0[7] = f64::INFINITY;
        let mut m = DepthMap::from_level0(DVec2::ZERO, DVec2::splat(8.0), 8, level0);
        m.build_pyramid();
        // A thin diagonal band from (1.5, 1.5) to (6.5, 6.5): its rectangle
        // touches the empty corners, its pixels (grown by one) do not.
        let band = vec![
            DVec2::new(1.5, 1.0),
            DVec2::new(6.5, 6.0),
            DVec2::new(6.5, 6.5),
            DVec2::new(1.0, 1.5),
        ];
        assert!(!m.hides(DVec2::splat(1.0), DVec2::splat(6.5), 2.0));
        assert!(m.hides_polygon(&band, 2.0));
        // In front of the occluders, or reaching an empty pixel: not hidden.
        assert!(!m.hides_polygon(&band, 0.5));
        let wide = vec![
            DVec2::new(0.5, 6.5),
            DVec2::new(1.0, 6.5),
            DVec2::new(1.0, 7.0),
        ];
        assert!(!m.hides_polygon(&wide, 2.0));
        // Degenerate or off the map: not hidden.
        assert!(!m.hides_polygon(&band[..2], 2.0));
        assert!(!m.hides_polygon(
            &[
                DVec2::new(-1.0, 1.0),
                DVec2::new(3.0, 1.0),
                DVec2::new(3.0, 3.0)
            ],
            2.0
        ));
    }
}
