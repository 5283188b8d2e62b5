//! The occlusion buffer of one view (papers/002 sec. 3, with depths; see
//! the module docs): one depth per pixel, and the conservative drawing of
//! an object's triangles into it (a pixel is marked only where its whole
//! square lies inside a triangle, or inside a pair of triangles sharing an
//! edge).

use glam::DVec3;

use crate::render::Camera;

/// How far inside a triangle's projection a pixel square must lie to be
/// marked occluded, in pixels.
const COVER_MARGIN: f64 = 1e-3;

/// The occlusion buffer of one view, and the camera frame in f64 to draw
/// into it.
pub(super) struct OcclusionBuffer {
    pub(super) w: u32,
    pub(super) h: u32,
    /// Per pixel, row by row from the top: the smallest farthest depth of
    /// the triangles covering it (`+inf`: free).
    pub(super) depth: Vec<f32>,
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_x: f64,
    tan_y: f64,
}

impl OcclusionBuffer {
    /// An empty buffer (every pixel free) for `cam`'s image.
    pub(super) fn new(cam: &Camera) -> Self {
        let (w, h) = (cam.width, cam.height);
        Self {
            w,
            h,
            depth: vec![f32::INFINITY; w as usize * h as usize],
            eye: cam.eye.as_dvec3(),
            forward: cam.forward.as_dvec3(),
            right: cam.right.as_dvec3(),
            up: cam.up.as_dvec3(),
            tan_x: cam.tan_x as f64,
            tan_y: cam.tan_y as f64,
        }
    }

    /// The depths of row `y`, pixels `x0..=x1`.
    pub(super) fn row(&self, y: u32, x0: u32, x1: u32) -> &[f32] {
        let row = (y * self.w) as usize;
        &self.depth[row + x0 as usize..=row + x1 as usize]
    }

    /// Draws one primitive: a triangle, or a pair of triangles sharing an
    /// edge, whose union covers more (the pixels across the shared edge)
    /// when the two lie on opposite sides of that edge in the image. Each
    /// triangle is first clipped to the near plane.
    pub(super) fn draw_prim(&mut self, p: &Prim, near: f32, slack: f32) {
        let clip_z = 2.0 * near as f64;
        match *p {
            Prim::Tri(t) => {
                let poly = Poly::clip(t.map(|q| q.as_dvec3() - self.eye), self.forward, clip_z);
                if let Some(half) = self.half_planes(&poly) {
                    self.fill(
                        &half.lines[..half.len],
                        &[half.plane],
                        half.zmax,
                        half.bbox,
                        slack,
                    );
                }
            }
            Prim::Pair([a, b, c, d]) => {
                let [a, b, c, d] = [a, b, c, d].map(|q| q.as_dvec3() - self.eye);
                let p1 = Poly::clip([a, b, c], self.forward, clip_z);
                let p2 = Poly::clip([a, b, d], self.forward, clip_z);
                let h1 = self.half_planes(&p1);
                let h2 = self.half_planes(&p2);
                // Opposite sides of the shared edge a-b (the in-front part
                // of a triangle lies on its third corner's side of the
                // plane through the eye and a-b): the union holds every
                // square inside the outer edges of both clipped triangles
                // (a point of it on c's side of a-b is in the first, one on
                // d's side in the second).
                let opposite = |n: DVec3, p: DVec3, q: DVec3| {
                    let (sp, sq) = (n.dot(p), n.dot(q));
                    sp != 0.0 && sq != 0.0 && (sp > 0.0) != (sq > 0.0)
                };
                let fused = match (&h1, &h2) {
                    (Some(h1), Some(h2)) => {
                        opposite(a.cross(b), c, d) && h1.shared.is_some() && h2.shared.is_some()
                    }
                    _ => false,
                };
                // Unclipped, and a, b on opposite sides of c-d too: the
                // image of the pair is a convex quadrilateral, which the
                // fused region is (up to the margin): no need for the
                // triangles one by one.
                let convex = fused && p1.len == 3 && p2.len == 3 && opposite(c.cross(d), a, b);
                if !convex {
                    for h in [&h1, &h2].into_iter().flatten() {
                        self.fill(&h.lines[..h.len], &[h.plane], h.zmax, h.bbox, slack);
                    }
                }
                if let (true, Some(h1), Some(h2)) = (fused, h1, h2) {
                    let mut lines = [(0.0, 0.0, 0.0); 8];
                    let mut len = 0;
                    for h in [&h1, &h2] {
                        for (k, &l) in h.lines[..h.len].iter().enumerate() {
                            if Some(k) != h.shared {
                                lines[len] = l;
                                len += 1;
                            }
                        }
                    }
                    let bbox = [
                        h1.bbox[0].min(h2.bbox[0]),
                        h1.bbox[1].max(h2.bbox[1]),
                        h1.bbox[2].min(h2.bbox[2]),
                        h1.bbox[3].max(h2.bbox[3]),
                    ];
                    let z = h1.zmax.max(h2.zmax);
                    self.fill(&lines[..len], &[h1.plane, h2.plane], z, bbox, slack);
                }
            }
        }
    }

    /// The image half-planes of a clipped (convex, planar, in front)
    /// polygon, its depth plane and farthest depth; `None` when it is
    /// empty or seen edge-on.
    fn half_planes(&self, poly: &Poly) -> Option<HalfPlanes> {
        if poly.len < 3 {
            return None;
        }
        let verts = &poly.verts[..poly.len];
        let centre = verts.iter().copied().sum::<DVec3>() / poly.len as f64;
        let (w, h) = (self.w as f64, self.h as f64);
        // Along the pixel ray through image point (x, y), whose direction
        // is D(x, y) = forward + right tan_x (2x/w - 1) + up tan_y (1 - 2y/h),
        // the sign of n . D is that of E(x, y) = a x + b y + c.
        let linear = |n: DVec3| {
            let (nf, nr, nu) = (n.dot(self.forward), n.dot(self.right), n.dot(self.up));
            let a = 2.0 * self.tan_x * nr / w;
            let b = -2.0 * self.tan_y * nu / h;
            (a, b, nf - self.tan_x * nr + self.tan_y * nu)
        };
        let mut out = HalfPlanes {
            lines: [(0.0, 0.0, 0.0); 4],
            len: poly.len,
            shared: None,
            plane: (0.0, 0.0, 0.0, 0.0),
            zmax: verts
                .iter()
                .map(|v| v.dot(self.forward))
                .fold(0.0, f64::max),
            bbox: [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ],
        };
        for v in verts {
            // The image point (as Camera::to_image; every corner is in
            // front of the near plane).
            let z = v.dot(self.forward);
            let x = (v.dot(self.right) / (z * self.tan_x) + 1.0) * 0.5 * w;
            let y = (1.0 - v.dot(self.up) / (z * self.tan_y)) * 0.5 * h;
            out.bbox = [
                out.bbox[0].min(x),
                out.bbox[1].max(x),
                out.bbox[2].min(y),
                out.bbox[3].max(y),
            ];
        }
        for k in 0..poly.len {
            // The plane through the eye and edge k, positive inside; over
            // the square [i, i+1] x [j, j+1] the least E is at the corner
            // picked by the signs of a and b.
            let mut n = verts[k].cross(verts[(k + 1) % poly.len]);
            let side = n.dot(centre);
            if side == 0.0 || !side.is_finite() {
                return None;
            }
            if side < 0.0 {
                n = -n;
            }
            let (a, b, c) = linear(n);
            let margin = COVER_MARGIN * (a * a + b * b).sqrt();
            out.lines[k] = (a, b, c + a.min(0.0) + b.min(0.0) - margin);
            if poly.labels[k] == 0 {
                out.shared = Some(k);
            }
        }
        // The depth plane n . p = k > 0: at (x, y) the depth is
        // k / (n . D(x, y)), and n . D is linear, so the farthest depth over
        // a square is k over the least n . D there (at a corner).
        let mut n = (verts[1] - verts[0]).cross(verts[2] - verts[0]);
        let mut k = n.dot(verts[0]);
        if k == 0.0 || !k.is_finite() {
            return None;
        }
        if k < 0.0 {
            n = -n;
            k = -k;
        }
        let (a, b, c) = linear(n);
        out.plane = (a, b, c + a.min(0.0) + b.min(0.0), k);
        Some(out)
    }

    /// Marks the pixels whose squares lie inside every half-plane `lines`
    /// (among those of the image box `bbox`: x from, x to, y from, y to)
    /// with the farthest depth of the `planes` over the square (at most
    /// `zmax`, the region's farthest depth).
    fn fill(
        &mut self,
        lines: &[(f64, f64, f64)],
        planes: &[(f64, f64, f64, f64)],
        zmax: f64,
        bbox: [f64; 4],
        slack: f32,
    ) {
        // The pixel rows and columns of the bounding box, a pixel wider.
        let span = |lo: f64, hi: f64, n: u32| {
            let a = (lo.floor() - 1.0).max(0.0);
            let b = (hi.floor() + 1.0).min(n as f64 - 1.0);
            (a, b)
        };
        let (bx0, bx1) = span(bbox[0], bbox[1], self.w);
        let (by0, by1) = span(bbox[2], bbox[3], self.h);
        if bx0 > bx1 || by0 > by1 {
            return;
        }
        let inside = |i: f64, j: f64| lines.iter().all(|&(a, b, c)| a * i + b * j + c > 0.0);
        for j in by0 as u32..=by1 as u32 {
            let jf = j as f64;
            let (mut lo, mut hi) = (bx0, bx1);
            for &(a, b, c) in lines {
                let rest = b * jf + c;
                if a > 0.0 {
                    lo = lo.max((-rest / a).floor());
                } else if a < 0.0 {
                    hi = hi.min((-rest / a).ceil());
                } else if rest <= 0.0 {
                    hi = lo - 1.0;
                }
            }
            // Rounding may put a span end one off: shrink it until both
            // ends pass. Each line's value is monotone along the row (in
            // floating point too), so every square between passes as well.
            while lo <= hi && !inside(lo, jf) {
                lo += 1.0;
            }
            while hi >= lo && !inside(hi, jf) {
                hi -= 1.0;
            }
            if lo > hi {
                continue;
            }
            let row = (j * self.w) as usize;
            let depths = &mut self.depth[row + lo as usize..=row + hi as usize];
            // The depth over each square (branch-free, for the
            // vectoriser): the farthest over the planes.
            let plane_row = |(a, b, c, k): (f64, f64, f64, f64)| (a, a * lo + b * jf + c, k);
            let p1 = plane_row(planes[0]);
            let p2 = plane_row(*planes.last().expect("one plane at least"));
            let depth_at = |(a, l0, k): (f64, f64, f64), i: f64| {
                let l = l0 + a * i;
                if l > 0.0 { (k / l).min(zmax) } else { zmax }
            };
            // Rounding: a relative margin besides the absolute slack.
            let store = |d: &mut f32, z: f64| *d = d.min((z * (1.0 + 1e-6)) as f32 + slack);
            if planes.len() == 1 {
                for (d, i) in depths.iter_mut().zip(0u32..) {
                    store(d, depth_at(p1, i as f64));
                }
            } else {
                for (d, i) in depths.iter_mut().zip(0u32..) {
                    store(d, depth_at(p1, i as f64).max(depth_at(p2, i as f64)));
                }
            }
        }
    }
}

/// A triangle clipped to the near plane: a convex polygon of up to four
/// corners (eye-relative), with for each edge (from corner k to k + 1) the
/// triangle edge it lies on (0: a-b, 1: b-c, 2: c-a; 3: the near plane).
struct Poly {
    verts: [DVec3; 4],
    labels: [u8; 4],
    len: usize,
}

impl Poly {
    /// Sutherland-Hodgman against `p . forward >= clip_z`.
    fn clip(t: [DVec3; 3], forward: DVec3, clip_z: f64) -> Poly {
        let mut out = Poly {
            verts: [DVec3::ZERO; 4],
            labels: [0; 4],
            len: 0,
        };
        let z = t.map(|v| v.dot(forward));
        let mut push = |v: DVec3, l: u8| {
            out.verts[out.len] = v;
            out.labels[out.len] = l;
            out.len += 1;
        };
        for k in 0..3 {
            let (s, e) = (k, (k + 1) % 3);
            let (s_in, e_in) = (z[s] >= clip_z, z[e] >= clip_z);
            let cut = || {
                let f = (clip_z - z[s]) / (z[e] - z[s]);
                let p = t[s] + (t[e] - t[s]) * f;
                // On the plane exactly (in front by construction).
                p + forward * (clip_z - p.dot(forward)).max(0.0)
            };
            match (s_in, e_in) {
                (true, true) => push(t[s], k as u8),
                (true, false) => {
                    push(t[s], k as u8);
                    push(cut(), 3);
                }
                (false, true) => push(cut(), k as u8),
                (false, false) => {}
            }
        }
        out
    }
}

/// A clipped triangle ready to fill.
#[derive(Clone, Copy, Debug)]
struct HalfPlanes {
    /// Per edge `(a, b, c)`: the square at `(i, j)` is inside the edge
    /// when `a i + b j + c > 0`.
    lines: [(f64, f64, f64); 4],
    len: usize,
    /// Which line lies on the triangle's edge a-b, if it survived clipping.
    shared: Option<usize>,
    /// The depth plane `(a, b, c, k)`: the farthest depth over the square
    /// at `(i, j)` is `k / (a i + b j + c)` when that is positive.
    plane: (f64, f64, f64, f64),
    /// The farthest corner's depth.
    zmax: f64,
    /// The image box of the corners: x from, x to, y from, y to.
    bbox: [f64; 4],
}

/// What drawing rasterises: a triangle, or two triangles `(a, b, c)` and
/// `(a, b, d)` of one object sharing the edge `a-b`.
#[derive(Clone, Copy, Debug)]
pub(super) enum Prim {
    Tri([glam::Vec3; 3]),
    Pair([glam::Vec3; 4]),
}

/// Pairs an object's triangles that share an edge (same corner
/// coordinates), coplanar neighbours first (the two halves of a quad),
/// then any neighbour; the rest stay single.
pub(super) fn pair_triangles(tris: &[[glam::Vec3; 3]], out: &mut Vec<Prim>) {
    use std::collections::HashMap;
    let key = |p: glam::Vec3| p.to_array().map(f32::to_bits);
    // The corners of an edge, as bits, in order: the triangles on it.
    type EdgeKey = ([u32; 3], [u32; 3]);
    let mut edges: HashMap<EdgeKey, Vec<u32>> = HashMap::new();
    for (t, tri) in tris.iter().enumerate() {
        for e in 0..3u8 {
            let (p, q) = (key(tri[e as usize]), key(tri[(e as usize + 1) % 3]));
            edges
                .entry((p.min(q), p.max(q)))
                .or_default()
                .push(t as u32);
        }
    }
    let normal = |t: &[glam::Vec3; 3]| {
        let [a, b, c] = t.map(|p| p.as_dvec3());
        (b - a).cross(c - a).normalize_or_zero()
    };
    let mut partner: Vec<Option<(u32, u8)>> = vec![None; tris.len()];
    for coplanar in [true, false] {
        for t in 0..tris.len() {
            if partner[t].is_some() {
                continue;
            }
            let nt = normal(&tris[t]);
            let mut best: Option<(f64, u32, u8)> = None;
            for e in 0..3u8 {
                let (p, q) = (key(tris[t][e as usize]), key(tris[t][(e as usize + 1) % 3]));
                for &u in &edges[&(p.min(q), p.max(q))] {
                    if u as usize == t || partner[u as usize].is_some() {
                        continue;
                    }
                    let cos = nt.dot(normal(&tris[u as usize])).abs();
                    if (!coplanar || cos > 0.9999) && best.is_none_or(|(b, _, _)| cos > b) {
                        best = Some((cos, u, e));
                    }
                }
            }
            if let Some((_, u, e)) = best {
                partner[t] = Some((u, e));
                partner[u as usize] = Some((t as u32, u8::MAX));
            }
        }
    }
    for (t, tri) in tris.iter().enumerate() {
        match partner[t] {
            None => out.push(Prim::Tri(*tri)),
            Some((_, u8::MAX)) => {} // emitted with its partner
            Some((u, e)) => {
                let e = e as usize;
                let (a, b, c) = (tri[e], tri[(e + 1) % 3], tri[(e + 2) % 3]);
                let other = &tris[u as usize];
                let d = *other
                    .iter()
                    .find(|&&p| key(p) != key(a) && key(p) != key(b))
                    .expect("a triangle sharing an edge has a third corner");
                out.push(Prim::Pair([a, b, c, d]));
            }
        }
    }
}
