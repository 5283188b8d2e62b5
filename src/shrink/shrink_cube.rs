//! Visibility from one point against shrunk solids: a cube map of
//! conservative depths (papers/004 sec. 4.2, on the CPU).
//!
//! Each of the six faces of a cube around the eye is an `n` x `n` grid of
//! pixels; a pixel is the pyramid of rays from the eye through it. A pixel
//! holds `(D, F)` when every ray of it meets a kept shrunk face within
//! distance `D` of the eye, of a solid whose floor (for one on a floor) is
//! at most `F`; else `D` is infinite. It also holds the `D` of the solids
//! not on floors alone, which binds occludees at any height.
//!
//! **Coverage of a union.** From the eye, an edge of a shrunk solid is
//! *inside* the solid's outline when its two faces lie on opposite sides
//! of the plane through the eye and the edge (clearly, by more than
//! rounding); every other edge (a contour edge, an edge of a removed
//! face's hole, an edge seen edge-on) is an *outline* edge. Where the
//! outline edges' projections do not touch a pixel, the projection of the
//! solid's faces either covers the whole pixel or none of it (the union's
//! boundary lies on its outline edges: across an inside edge the two
//! faces cover both sides, and around a vertex whose edges are all inside
//! the faces close up), so the pixel is covered when its centre is inside
//! one face. Its `D` is then the largest distance of any face touching
//! it, since the face a ray meets first touches the pixel. Pixels are
//! touched and centres tested with a margin that only ever touches more
//! (outline edges, faces for `D`) and so covers less.
//!
//! Each solid is drawn alone and its pixels merged into the map by the
//! smaller `D`: solids fuse where one lies behind another's outline, not
//! across a seam between two (shrinking opens a gap of `2e` between
//! touching solids anyway; papers/004 sec. 4.1.4).
//!
//! **Occludees.** A box is hidden when every pixel its faces touch holds
//! a `D` of solids not on floors below the box's smallest distance from
//! the eye, or such a `D` of any solids with an `F` at or below the box's
//! lowest point.

use glam::{DVec2, DVec3};

use super::shrink_mesh::Shrunk;

/// Margin, in pixels, by which touching is widened.
const MARGIN: f64 = 1e-7;

/// The six faces of a box as quads of its corners (numbered as by
/// `oracle::corners`), wound outward: -z first, then +z, -y, +y, -x, +x.
pub(super) const BOX_QUADS: [[usize; 4]; 6] = [
    [0, 2, 3, 1],
    [4, 5, 7, 6],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 4, 6, 2],
    [1, 3, 7, 5],
];

/// The six faces: the axis and its sign.
pub(super) const FACES: [(usize, f64); 6] = [
    (0, 1.0),
    (0, -1.0),
    (1, 1.0),
    (1, -1.0),
    (2, 1.0),
    (2, -1.0),
];

/// A cube map of conservative depths around an eye.
#[derive(Clone, Debug)]
pub struct CubeMap {
    eye: DVec3,
    n: usize,
    /// `D` per pixel (face-major, then row, then column), of solids not
    /// on a floor (any occludee point farther is hidden).
    depth: Vec<f64>,
    /// `D` per pixel of solids on floors (with those of `depth`).
    depth_floor: Vec<f64>,
    /// `F` per pixel: the floor of the solid `depth_floor` came from
    /// (minus infinity for one not on a floor).
    floor: Vec<f64>,
    scratch: Scratch,
}

/// Per-solid working pixels, stamped so that they need no clearing.
#[derive(Clone, Debug, Default)]
struct Scratch {
    stamp: Vec<u32>,
    inside: Vec<bool>,
    outline: Vec<bool>,
    far: Vec<f64>,
    touched: Vec<u32>,
    current: u32,
}

/// Something a projection could not handle: a polygon through the eye.
#[derive(Debug)]
pub struct ThroughEye;

impl CubeMap {
    /// An empty map (nothing covered) of `n` x `n` pixels a face around
    /// `eye`.
    pub fn new(eye: DVec3, n: usize) -> Self {
        let len = 6 * n * n;
        Self {
            eye,
            n,
            depth: vec![f64::INFINITY; len],
            depth_floor: vec![f64::INFINITY; len],
            floor: vec![f64::NEG_INFINITY; len],
            scratch: Scratch {
                stamp: vec![0; len],
                inside: vec![false; len],
                outline: vec![false; len],
                far: vec![0.0; len],
                touched: Vec::new(),
                current: 0,
            },
        }
    }

    /// A map of `n` x `n` pixels a face around `eye` made elsewhere (on
    /// the GPU, `shrink_gpu.rs`): `depth`, `depth_floor` and `floor` per
    /// pixel, face-major, then row, then column, as [`CubeMap::draw`]
    /// leaves them.
    #[cfg(feature = "gpu")]
    pub(super) fn from_maps(
        eye: DVec3,
        n: usize,
        depth: Vec<f64>,
        depth_floor: Vec<f64>,
        floor: Vec<f64>,
    ) -> Self {
        let len = 6 * n * n;
        assert!(depth.len() == len && depth_floor.len() == len && floor.len() == len);
        Self {
            eye,
            n,
            depth,
            depth_floor,
            floor,
            scratch: Scratch::default(),
        }
    }

    /// The map's side, and its `depth`, `depth_floor` and `floor` per pixel.
    #[cfg(all(test, feature = "gpu"))]
    pub(super) fn maps(&self) -> (usize, &[f64], &[f64], &[f64]) {
        (self.n, &self.depth, &self.depth_floor, &self.floor)
    }

    /// The pixels covered (finite `D`, on floors or not).
    pub fn covered(&self) -> usize {
        self.depth_floor.iter().filter(|d| d.is_finite()).count()
    }

    /// Draws one shrunk solid (its kept faces and outline), merging its
    /// covered pixels into the map. A solid with a face through the eye
    /// (which the callers rule out: the eye is outside its box) is skipped.
    pub fn draw(&mut self, solid: &Shrunk) {
        let eye = self.eye;
        let n = self.n;
        let s = &mut self.scratch;
        if s.stamp.len() != 6 * n * n {
            // A map made elsewhere (`from_maps`) gets its scratch now.
            *s = Scratch {
                stamp: vec![0; 6 * n * n],
                inside: vec![false; 6 * n * n],
                outline: vec![false; 6 * n * n],
                far: vec![0.0; 6 * n * n],
                touched: Vec::new(),
                current: 0,
            };
        }
        s.current += 1;
        s.touched.clear();
        let stamp = s.current;
        let v: Vec<DVec3> = solid.vertices.iter().map(|p| *p - eye).collect();
        let mut ok = true;
        // Faces: touched pixels take the face's farthest corner; centres
        // inside a face are marked.
        for t in &solid.triangles {
            let tri = t.map(|i| v[i as usize]);
            let far = tri.iter().map(|p| p.length()).fold(0.0, f64::max);
            for face in 0..6 {
                let Ok(poly) = project(&tri, face, n) else {
                    ok = false;
                    break;
                };
                if poly.len() < 3 {
                    continue;
                }
                touch(&poly, n, &mut |row, lo, hi| {
                    for col in lo..=hi {
                        let p = pixel(face, row, col, n);
                        s.visit(p, stamp);
                        s.far[p] = s.far[p].max(far);
                    }
                });
                centres_inside(&poly, n, &mut |row, lo, hi| {
                    for col in lo..=hi {
                        let p = pixel(face, row, col, n);
                        s.visit(p, stamp);
                        s.inside[p] = true;
                    }
                });
            }
            if !ok {
                break;
            }
        }
        // Outline edges block the pixels they touch.
        if ok {
            'edges: for e in &solid.edges {
                if !edge_inside(&v, e.a, e.b, e.third) {
                    let seg = [v[e.a as usize], v[e.b as usize]];
                    for face in 0..6 {
                        let Ok(poly) = project(&seg, face, n) else {
                            ok = false;
                            break 'edges;
                        };
                        if poly.is_empty() {
                            continue;
                        }
                        touch(&poly, n, &mut |row, lo, hi| {
                            for col in lo..=hi {
                                let p = pixel(face, row, col, n);
                                s.visit(p, stamp);
                                s.outline[p] = true;
                            }
                        });
                    }
                }
            }
        }
        if !ok {
            return;
        }
        let floor = solid.floor.unwrap_or(f64::NEG_INFINITY);
        for &p in &s.touched {
            let p = p as usize;
            if s.inside[p] && !s.outline[p] {
                let d = s.far[p];
                if solid.floor.is_none() {
                    self.depth[p] = self.depth[p].min(d);
                }
                // Both claims hold (every ray meets this solid by d and
                // the one before by its D): keep the nearer.
                if d < self.depth_floor[p] || (d == self.depth_floor[p] && floor < self.floor[p]) {
                    self.depth_floor[p] = d;
                    self.floor[p] = floor;
                }
            }
        }
    }

    /// Whether the box `[min, max]` is hidden: every pixel its faces touch
    /// holds a `D` below `near` (the box's smallest distance from the eye,
    /// less any margin the caller wants) and an `F` at or below `min.z` (a
    /// segment from above a floor to a point on its plane stays above it
    /// but for that point). A box around the eye is never hidden.
    pub fn box_hidden(&self, min: DVec3, max: DVec3, near: f64) -> bool {
        let (a, b) = (min - self.eye, max - self.eye);
        if (0..3).all(|k| a[k] <= 0.0 && b[k] >= 0.0) {
            return false;
        }
        let c = crate::oracle::corners(a, b);
        let n = self.n;
        for q in BOX_QUADS {
            let quad = q.map(|i| c[i]);
            for face in 0..6 {
                let Ok(poly) = project(&quad, face, n) else {
                    return false;
                };
                if poly.is_empty() {
                    continue;
                }
                let mut hidden = true;
                touch(&poly, n, &mut |row, lo, hi| {
                    if !hidden {
                        return;
                    }
                    for col in lo..=hi {
                        let p = pixel(face, row, col, n);
                        let free = self.depth[p] < near;
                        if !(free || (self.depth_floor[p] < near && self.floor[p] <= min.z)) {
                            hidden = false;
                            return;
                        }
                    }
                });
                if !hidden {
                    return false;
                }
            }
        }
        true
    }
}

impl Scratch {
    fn visit(&mut self, p: usize, stamp: u32) {
        if self.stamp[p] != stamp {
            self.stamp[p] = stamp;
            self.inside[p] = false;
            self.outline[p] = false;
            self.far[p] = 0.0;
            self.touched.push(p as u32);
        }
    }
}

pub(super) fn pixel(face: usize, row: usize, col: usize, n: usize) -> usize {
    (face * n + row) * n + col
}

/// Whether the edge `a b` (eye-relative vertices `v`) lies inside its
/// solid's outline from the eye: two faces, their third corners clearly
/// on opposite sides of the plane through the eye and the edge.
pub(super) fn edge_inside(v: &[DVec3], a: u32, b: u32, third: [Option<u32>; 2]) -> bool {
    let [Some(p), Some(q)] = third else {
        return false;
    };
    let (a, b) = (v[a as usize], v[b as usize]);
    let m = a.cross(b);
    let (p, q) = (v[p as usize], v[q as usize]);
    let (sp, sq) = (m.dot(p), m.dot(q));
    // Rounding of the triple products is far below this.
    let tol = 1e-10 * a.length() * b.length() * p.length().max(q.length());
    (sp > tol && sq < -tol) || (sp < -tol && sq > tol)
}

/// The polygon (or segment, for two points) `points` (eye-relative)
/// clipped to the pyramid of cube face `face` widened by two pixels, in
/// that face's pixel coordinates. Empty when nothing is left.
pub(super) fn project(points: &[DVec3], face: usize, n: usize) -> Result<Vec<DVec2>, ThroughEye> {
    let (axis, sign) = FACES[face];
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    let g = 1.0 + 4.0 / n as f64;
    let planes: [&dyn Fn(DVec3) -> f64; 4] = [
        &|p: DVec3| g * sign * p[axis] - p[b],
        &|p: DVec3| g * sign * p[axis] + p[b],
        &|p: DVec3| g * sign * p[axis] - p[c],
        &|p: DVec3| g * sign * p[axis] + p[c],
    ];
    let closed = points.len() > 2;
    let mut poly: Vec<DVec3> = points.to_vec();
    for f in planes {
        if poly.is_empty() {
            break;
        }
        poly = clip(&poly, closed, f);
    }
    let half = n as f64 / 2.0;
    let mut out = Vec::with_capacity(poly.len());
    for p in poly {
        let x = sign * p[axis];
        if x.is_nan() || x <= 1e-12 * p.abs().max_element() {
            return Err(ThroughEye);
        }
        out.push(DVec2::new((p[b] / x + 1.0) * half, (p[c] / x + 1.0) * half));
    }
    Ok(out)
}

/// Sutherland-Hodgman against `f >= 0`, for a closed polygon or an open
/// segment.
fn clip(poly: &[DVec3], closed: bool, f: &dyn Fn(DVec3) -> f64) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(poly.len() + 2);
    if !closed {
        let (p, q) = (poly[0], poly[1]);
        let (fp, fq) = (f(p), f(q));
        match (fp >= 0.0, fq >= 0.0) {
            (true, true) => return vec![p, q],
            (false, false) => return out,
            (true, false) => return vec![p, p + (q - p) * (fp / (fp - fq))],
            (false, true) => return vec![p + (q - p) * (fp / (fp - fq)), q],
        }
    }
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        let (fp, fq) = (f(p), f(q));
        if fp >= 0.0 {
            out.push(p);
        }
        if (fp >= 0.0) != (fq >= 0.0) {
            out.push(p + (q - p) * (fp / (fp - fq)));
        }
    }
    out
}

/// Calls `row_span(row, lo, hi)` for the pixels a convex polygon (or a
/// segment) touches, each row's span grown by [`MARGIN`].
fn touch(poly: &[DVec2], n: usize, row_span: &mut dyn FnMut(usize, usize, usize)) {
    let (ylo, yhi) = poly
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.y), b.max(p.y))
        });
    let last = n as f64 - 1.0;
    let r0 = (ylo - MARGIN).floor().max(0.0);
    let r1 = (yhi + MARGIN).floor().min(last);
    if r0.is_nan() || r1.is_nan() || r0 > r1 {
        return;
    }
    for row in r0 as usize..=r1 as usize {
        let (b0, b1) = (row as f64 - MARGIN, row as f64 + 1.0 + MARGIN);
        let (mut x0, mut x1) = (f64::INFINITY, f64::NEG_INFINITY);
        let k = poly.len();
        for i in 0..k {
            let p = poly[i];
            if p.y >= b0 && p.y <= b1 {
                x0 = x0.min(p.x);
                x1 = x1.max(p.x);
            }
            if k < 2 {
                continue;
            }
            let q = poly[(i + 1) % k];
            for y in [b0, b1] {
                if (p.y - y) * (q.y - y) < 0.0 {
                    let x = p.x + (y - p.y) * (q.x - p.x) / (q.y - p.y);
                    x0 = x0.min(x);
                    x1 = x1.max(x);
                }
            }
        }
        if x0.is_nan() || x1.is_nan() || x0 > x1 {
            continue;
        }
        let c0 = (x0 - MARGIN).floor().max(0.0);
        let c1 = (x1 + MARGIN).floor().min(last);
        if c0 <= c1 {
            row_span(row, c0 as usize, c1 as usize);
        }
    }
}

/// Calls `row_span(row, lo, hi)` for the pixels whose centres lie in a
/// convex polygon (inclusive; rounding either way is harmless, see the
/// module's doc).
fn centres_inside(poly: &[DVec2], n: usize, row_span: &mut dyn FnMut(usize, usize, usize)) {
    let (ylo, yhi) = poly
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.y), b.max(p.y))
        });
    let last = n as f64 - 1.0;
    let r0 = (ylo - 0.5).ceil().max(0.0);
    let r1 = (yhi - 0.5).floor().min(last);
    if r0.is_nan() || r1.is_nan() || r0 > r1 {
        return;
    }
    for row in r0 as usize..=r1 as usize {
        let y = row as f64 + 0.5;
        let (mut x0, mut x1) = (f64::INFINITY, f64::NEG_INFINITY);
        let k = poly.len();
        for i in 0..k {
            let (p, q) = (poly[i], poly[(i + 1) % k]);
            if p.y == y {
                x0 = x0.min(p.x);
                x1 = x1.max(p.x);
            }
            if (p.y - y) * (q.y - y) < 0.0 {
                let x = p.x + (y - p.y) * (q.x - p.x) / (q.y - p.y);
                x0 = x0.min(x);
                x1 = x1.max(x);
            }
        }
        if x0.is_nan() || x1.is_nan() || x0 > x1 {
            continue;
        }
        let c0 = (x0 - 0.5).ceil().max(0.0);
        let c1 = (x1 - 0.5).floor().min(last);
        if c0 <= c1 {
            row_span(row, c0 as usize, c1 as usize);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shrink::shrink_mesh::Solid;
    use crate::shrink::shrink_mesh::tests::box_triangles;

    fn shrunk_box(a: DVec3, b: DVec3) -> Shrunk {
        // Shrunk by nothing much: the box itself, nearly.
        Solid::new(&box_triangles(a, b), None)
            .unwrap()
            .shrink(1e-3, 1e-9)
            .0
    }

    #[test]
    fn a_box_covers_what_is_behind_it_and_not_beside_it() {
        let mut map = CubeMap::new(DVec3::ZERO, 64);
        map.draw(&shrunk_box(
            DVec3::new(5.0, -3.0, -3.0),
            DVec3::new(6.0, 3.0, 3.0),
        ));
        assert!(map.covered() > 0);
        // Behind it, small: hidden; beside it or in front: not.
        assert!(map.box_hidden(DVec3::new(8.0, -1.0, -1.0), DVec3::new(9.0, 1.0, 1.0), 8.0));
        assert!(!map.box_hidden(DVec3::new(8.0, 4.0, -1.0), DVec3::new(9.0, 6.0, 1.0), 8.0));
        assert!(!map.box_hidden(DVec3::new(3.0, -1.0, -1.0), DVec3::new(4.0, 1.0, 1.0), 3.0));
        // A box behind the eye is not behind the occluder.
        assert!(!map.box_hidden(
            DVec3::new(-9.0, -1.0, -1.0),
            DVec3::new(-8.0, 1.0, 1.0),
            8.0
        ));
    }

    #[test]
    fn covered_pixels_hold_only_rays_that_meet_the_faces_in_time() {
        use rand::{RngExt, SeedableRng};
        use rand_pcg::Pcg64;
        // A box across a cube map's seam (seen through several faces), and
        // random rays through covered pixels: each meets the box by D.
        let b = (DVec3::new(2.0, 1.0, -1.5), DVec3::new(3.5, 4.0, 2.0));
        let solid = shrunk_box(b.0, b.1);
        let n = 32;
        let mut map = CubeMap::new(DVec3::ZERO, n);
        map.draw(&solid);
        let mut rng = Pcg64::seed_from_u64(3);
        let mut tried = 0;
        for _ in 0..200_000 {
            let d = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            // Which face and pixel the direction falls in.
            let a = d.abs();
            let axis = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            let face = 2 * axis + usize::from(d[axis] < 0.0);
            let sign = FACES[face].1;
            let (bb, cc) = ((axis + 1) % 3, (axis + 2) % 3);
            let x = sign * d[axis];
            let (u, w) = (
                (d[bb] / x + 1.0) * n as f64 / 2.0,
                (d[cc] / x + 1.0) * n as f64 / 2.0,
            );
            let p = pixel(face, (w as usize).min(n - 1), (u as usize).min(n - 1), n);
            if !map.depth_floor[p].is_finite() {
                continue;
            }
            tried += 1;
            // The ray meets the shrunk box (a slab test), by D.
            let (lo, hi) = solid.bounds();
            let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
            for k in 0..3 {
                let (ta, tb) = ((lo[k]) / d[k], (hi[k]) / d[k]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
            assert!(t0 <= t1, "a ray of a covered pixel misses: {d:?}");
            assert!(t0 * d.length() <= map.depth_floor[p] + 1e-9);
        }
        assert!(tried > 1000, "{tried}");
    }
}
