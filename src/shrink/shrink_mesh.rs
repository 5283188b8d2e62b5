//! Shrinking one closed solid by a distance `e` (papers/004 sec. 4.1.2 to
//! 4.1.4), with a check of our own that makes the result provably safe.
//!
//! The paper's steps:
//! 1. **Offsets** (sec. 4.1.3). Each vertex moves against its normal `Nv`
//!    (the sum of its faces' outward normals weighted by their angles at
//!    the vertex, normalised) by
//!    `d = e / sin(alpha/2)`, where `alpha/2 = min_i (90 deg - angle(Nv,
//!    Ni))` over its faces, so `sin(alpha/2) = min_i Nv . Ni`: every face's
//!    plane then moves inward by at least `e`.
//! 2. **Degenerate faces** (sec. 4.1.4): a shrunk face with no area, or
//!    turned over (its normal against the original's), is removed; so are
//!    the faces of a vertex too sharp to move (`min_i Nv . Ni` below
//!    [`MIN_SINE`]).
//! 3. **Swept volumes** (sec. 4.1.4): the volume a face sweeps as it
//!    shrinks is the hull of its old and new corners; two faces that share
//!    no vertex and whose swept volumes meet (bounding boxes, then a search
//!    for a separating plane) are both removed. Done last, among the faces
//!    the check below kept (it removes only more, and the pairs are far
//!    fewer: on curved meshes of small faces, comparing every face's swept
//!    volume with its neighbours' first took tens of seconds).
//!
//! The paper's steps do not by themselves keep a shrunk face inside the
//! solid's erosion by a ball of radius `e` (a face moved past a thin part
//! of the solid, or past a notch whose faces it does not sweep into, is
//! not caught). What Theorem 1 needs is exactly that erosion, so each
//! face that survives is **checked**: it must be at least `e` plus a
//! margin from every face of the solid, and inside the solid (one point, by the
//! parity of crossings along a ray; a face at distance `> 0` from the
//! surface lies wholly on one side of it). A face that fails is removed.
//! For a solid on a floor (see [`Solid`]) the floor is left out of the
//! distances and no point may lie below it.
//! Then every point `s` of a kept face has the open ball of radius `e`
//! around it inside the solid, which is what the proof in `mod.rs` uses.

use std::collections::HashMap;

use glam::{DVec3, Vec3};

use super::shrink_geom::{hulls_may_intersect, triangle_distance};
use crate::geom::{Aabb, BoxTree};

/// The smallest `Nv . Ni` (the sine of the paper's `alpha/2`) a vertex may
/// have to be moved; sharper vertices would move more than 20 times `e`,
/// and their faces are dropped instead.
pub const MIN_SINE: f64 = 0.05;

/// A closed solid to shrink: a closed, consistently oriented welded mesh,
/// or a solid **on a floor**: open only at its bottom, where every open
/// edge lies in the plane `z = floor` (an extruded footprint without a
/// floor, or a closed solid with its flat bottom faces taken off).
///
/// A solid `X` on a floor is shrunk as `X u H`, `H` the half-space below
/// the floor (papers/004 Fig. 16: "the vertices touching the ground are
/// not moved vertically"): its floor vertices move only across the floor,
/// and the check asks for distance from every face but not from the
/// floor, and no point below it. That is sound for viewpoints and
/// occludee points above the floor (a point on it will do for the
/// occludee): a segment between two such points that passes within `e` of
/// a shrunk face passes through `X u H` above the floor, so through `X`,
/// and crosses one of its faces (mod.rs). `H` need not be opaque: the
/// segment never reaches it. Were the bottom shrunk up by `e` instead, a
/// building would float `e` above the street and hide nothing from a
/// viewpoint lower than that.
#[derive(Clone, Debug)]
pub struct Solid {
    /// Its welded vertices.
    pub vertices: Vec<DVec3>,
    /// Its triangles, wound so that their normals point out of the solid.
    pub triangles: Vec<[u32; 3]>,
    /// The height of the floor of a solid on one.
    pub floor: Option<f64>,
    /// Vertices on the open bottom edges.
    pub on_floor: Vec<bool>,
    /// Its bounding box.
    pub min: DVec3,
    /// Its bounding box.
    pub max: DVec3,
    /// The boxes of its triangles, for nearness queries.
    tree: BoxTree,
}

/// How a solid's triangles fared in one shrinking.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShrinkCounts {
    /// Triangles before shrinking.
    pub input: usize,
    /// Removed as degenerate, turned over, or at a vertex too sharp.
    pub degenerate: usize,
    /// Removed because their swept volumes met another's (the paper's
    /// test, among the faces the erosion check kept).
    pub swept: usize,
    /// Removed by the erosion check (ours).
    pub unsafe_: usize,
    /// Kept.
    pub kept: usize,
}

impl std::ops::AddAssign for ShrinkCounts {
    fn add_assign(&mut self, o: Self) {
        self.input += o.input;
        self.degenerate += o.degenerate;
        self.swept += o.swept;
        self.unsafe_ += o.unsafe_;
        self.kept += o.kept;
    }
}

/// A solid shrunk by `e`: its kept faces, and their edges with what lies
/// on each side (for the silhouettes from a point).
#[derive(Clone, Debug)]
pub struct Shrunk {
    /// The original solid's floor, if open at the bottom.
    pub floor: Option<f64>,
    /// The original solid's box (viewpoints must be outside it).
    pub solid_min: DVec3,
    /// The original solid's box.
    pub solid_max: DVec3,
    /// The moved vertices.
    pub vertices: Vec<DVec3>,
    /// The kept faces, outward.
    pub triangles: Vec<[u32; 3]>,
    /// Each edge of the kept faces: its two vertices and the third vertex
    /// of each face on it (one face: an edge of a hole, always part of the
    /// outline).
    pub edges: Vec<Edge>,
}

impl Shrunk {
    /// The box of the kept faces.
    #[cfg(test)]
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.triangles.iter().flat_map(|t| t.iter()).fold(
            (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(a, b), &i| {
                let p = self.vertices[i as usize];
                (a.min(p), b.max(p))
            },
        )
    }
}

/// An edge of a shrunk solid's kept faces.
#[derive(Clone, Copy, Debug)]
pub struct Edge {
    /// Its vertices.
    pub a: u32,
    /// Its vertices.
    pub b: u32,
    /// The third vertex of the faces on it (one or two).
    pub third: [Option<u32>; 2],
}

impl Solid {
    /// The solid of a closed (or open-at-the-bottom) welded mesh given as
    /// triangles of bit-identical shared corners, wound consistently either
    /// way; `None` when it is not closed (every edge once each way, but
    /// for a floor's edges in its plane) or encloses no volume.
    pub fn new(triangles: &[[DVec3; 3]], floor: Option<f64>) -> Option<Self> {
        let mut index: HashMap<[u64; 3], u32> = HashMap::new();
        let mut vertices = Vec::new();
        let mut tris: Vec<[u32; 3]> = Vec::with_capacity(triangles.len());
        for t in triangles {
            tris.push(t.map(|v| {
                let key = v.to_array().map(|c| if c == 0.0 { 0 } else { c.to_bits() });
                *index.entry(key).or_insert_with(|| {
                    vertices.push(v);
                    (vertices.len() - 1) as u32
                })
            }));
        }
        let (min, max) = vertices
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        // Closed: every edge has one twin in the other direction (the
        // winding consistent), but for the edges of a floor in its plane.
        // Keep this check: the oracle's solids to slice are only closed
        // modulo two (any winding, edges of four triangles), and moving
        // vertices against their normals needs a consistent winding.
        let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * tris.len());
        for t in &tris {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &count) in &directed {
            let twin = directed.get(&(b, a)).copied().unwrap_or(0);
            let on_floor =
                floor.is_some_and(|f| vertices[a as usize].z == f && vertices[b as usize].z == f);
            if count != 1 || (twin != 1 && !(twin == 0 && on_floor)) {
                return None;
            }
        }
        // Signed volume about a point of the floor plane (a floor's
        // triangles would add nothing there), or the box's centre.
        let o = match floor {
            Some(f) => DVec3::new((min.x + max.x) / 2.0, (min.y + max.y) / 2.0, f),
            None => (min + max) / 2.0,
        };
        let volume: f64 = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i as usize] - o);
                a.dot(b.cross(c))
            })
            .sum();
        let scale = (max - min).max_element().max(f64::MIN_POSITIVE);
        if volume.is_nan() || volume.abs() <= 1e-9 * scale * scale * scale {
            return None;
        }
        if volume < 0.0 {
            for t in &mut tris {
                t.swap(1, 2);
            }
        }
        let mut on_floor = vec![false; vertices.len()];
        if floor.is_some() {
            let mut directed: HashMap<(u32, u32), ()> = HashMap::new();
            for t in &tris {
                for k in 0..3 {
                    directed.insert((t[k], t[(k + 1) % 3]), ());
                }
            }
            for t in &tris {
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    if !directed.contains_key(&(b, a)) {
                        on_floor[a as usize] = true;
                        on_floor[b as usize] = true;
                    }
                }
            }
        }
        let boxes: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                let p = t.map(|i| vertices[i as usize]);
                let lo = p[0].min(p[1]).min(p[2]).as_vec3();
                let hi = p[0].max(p[1]).max(p[2]).as_vec3();
                // f32 boxes, widened past their rounding.
                Aabb::new(
                    lo - lo.abs() * 1e-6 - Vec3::splat(1e-30),
                    hi + hi.abs() * 1e-6 + Vec3::splat(1e-30),
                )
            })
            .collect();
        Some(Self {
            tree: BoxTree::new(&boxes),
            vertices,
            triangles: tris,
            floor,
            on_floor,
            min,
            max,
        })
    }

    /// A closed solid with a flat bottom (faces facing down in the plane of
    /// its lowest point) as a solid on that floor: the same without those
    /// faces. `None` for a solid already on a floor or without such faces.
    pub fn on_its_floor(&self) -> Option<Solid> {
        if self.floor.is_some() {
            return None;
        }
        let g = self.min.z;
        let mut rest = Vec::with_capacity(self.triangles.len());
        let mut dropped = 0;
        for t in 0..self.triangles.len() {
            let c = self.corners(t);
            if c.iter().all(|p| p.z == g) && self.normal(t).z < 0.0 {
                dropped += 1;
            } else {
                rest.push(c);
            }
        }
        if dropped == 0 || rest.is_empty() {
            return None;
        }
        Solid::new(&rest, Some(g))
    }

    fn corners(&self, t: usize) -> [DVec3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// The unit outward normal of face `t` (zero when it has no area).
    fn normal(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// Shrinks the solid by `e` (> 0): the paper's offsets, degenerate
    /// faces (moving faces by `e + 2 margin`), the erosion check (every
    /// kept face at least `e + margin` from the surface), then the swept
    /// volumes.
    pub fn shrink(&self, e: f64, margin: f64) -> (Shrunk, ShrinkCounts) {
        let n = self.triangles.len();
        let mut counts = ShrinkCounts {
            input: n,
            ..ShrinkCounts::default()
        };
        let normals: Vec<DVec3> = (0..n).map(|t| self.normal(t)).collect();
        // Vertex normals and the smallest sine over their faces.
        // Weighted by each face's angle at the vertex, so that a face cut
        // into several triangles counts once.
        let mut sum = vec![DVec3::ZERO; self.vertices.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let v = tri[k] as usize;
                let p = self.vertices[v];
                let (a, b) = (
                    self.vertices[tri[(k + 1) % 3] as usize] - p,
                    self.vertices[tri[(k + 2) % 3] as usize] - p,
                );
                sum[v] += normals[t] * a.angle_between(b);
            }
        }
        // Vertices on the floor move only across it (papers/004 Fig. 16):
        // the solid stays on its floor, see [`Solid`].
        for (v, s) in sum.iter_mut().enumerate() {
            if self.on_floor[v] {
                s.z = 0.0;
            }
        }
        let nv: Vec<DVec3> = sum.iter().map(|s| s.normalize_or_zero()).collect();
        let mut sine = vec![f64::INFINITY; self.vertices.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            for &v in tri {
                let s = &mut sine[v as usize];
                *s = s.min(nv[v as usize].dot(normals[t]));
            }
        }
        // Moved by twice the margin more than the check asks for, so that
        // faces moved exactly as the paper says pass it.
        let offset = e + 2.0 * margin;
        let moved: Vec<DVec3> = (0..self.vertices.len())
            .map(|v| {
                if sine[v] >= MIN_SINE {
                    self.vertices[v] - nv[v] * (offset / sine[v])
                } else {
                    self.vertices[v]
                }
            })
            .collect();
        // Degenerate and turned-over faces.
        let mut keep = vec![true; n];
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|i| moved[i as usize]);
            let m = (b - a).cross(c - a);
            let sharp = tri.iter().any(|&v| sine[v as usize] < MIN_SINE);
            let [oa, ob, oc] = self.corners(t);
            let area0 = (ob - oa).cross(oc - oa).length();
            let facing = m.dot(normals[t]);
            if sharp || normals[t] == DVec3::ZERO || facing.is_nan() || facing <= 1e-9 * area0 {
                keep[t] = false;
                counts.degenerate += 1;
            }
        }
        // The erosion check first: it is what makes the faces safe, and
        // the swept volumes are then compared among fewer faces.
        let need = e + margin;
        for (k, tri) in keep.iter_mut().zip(&self.triangles) {
            if *k && !self.eroded(tri.map(|i| moved[i as usize]), need) {
                *k = false;
                counts.unsafe_ += 1;
            }
        }
        // Swept volumes.
        let swept: Vec<[DVec3; 6]> = self
            .triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| self.vertices[i as usize]);
                let [d, f, g] = tri.map(|i| moved[i as usize]);
                [a, b, c, d, f, g]
            })
            .collect();
        let boxes: Vec<Aabb> = swept
            .iter()
            .map(|s| {
                let (lo, hi) = s
                    .iter()
                    .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), &p| {
                        (a.min(p), b.max(p))
                    });
                let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
                Aabb::new(
                    lo - lo.abs() * 1e-6 - Vec3::splat(1e-30),
                    hi + hi.abs() * 1e-6 + Vec3::splat(1e-30),
                )
            })
            .collect();
        let sweep_tree = BoxTree::new(&boxes);
        let mut hit = vec![false; n];
        let mut near = Vec::new();
        for t in 0..n {
            if !keep[t] {
                continue;
            }
            near.clear();
            sweep_tree.overlapping(&boxes[t], &mut near);
            for &u in &near {
                let u = u as usize;
                if u <= t || !keep[u] {
                    continue;
                }
                let shares = self.triangles[t]
                    .iter()
                    .any(|v| self.triangles[u].contains(v));
                if !shares && hulls_may_intersect(&swept[t], &swept[u]) {
                    hit[t] = true;
                    hit[u] = true;
                }
            }
        }
        for t in 0..n {
            if keep[t] && hit[t] {
                keep[t] = false;
                counts.swept += 1;
            }
        }
        counts.kept = keep.iter().filter(|k| **k).count();
        (self.shrunk(&moved, &keep), counts)
    }

    /// Whether the triangle `s` lies inside the solid, at least `need`
    /// from its surface (but for the floor, for a solid on one: then not
    /// below it).
    fn eroded(&self, s: [DVec3; 3], need: f64) -> bool {
        if let Some(f) = self.floor
            && s.iter().any(|p| p.z.is_nan() || p.z < f)
        {
            return false;
        }
        let lo = s[0].min(s[1]).min(s[2]) - DVec3::splat(need);
        let hi = s[0].max(s[1]).max(s[2]) + DVec3::splat(need);
        let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
        let query = Aabb::new(lo - lo.abs() * 1e-6, hi + hi.abs() * 1e-6);
        let mut near = Vec::new();
        self.tree.overlapping(&query, &mut near);
        for &t in &near {
            let d = triangle_distance(&s, &self.corners(t as usize));
            if d.is_nan() || d < need {
                return false;
            }
        }
        self.inside((s[0] + s[1] + s[2]) / 3.0)
    }

    /// Whether `p` (not on the surface) is inside the solid: the parity of
    /// the faces crossed by a ray going up from it (up: it never meets a
    /// virtual floor below `p`). Rays that pass near an edge are retried in
    /// another direction; `false` when every one does.
    fn inside(&self, p: DVec3) -> bool {
        const DIRECTIONS: [[f64; 3]; 4] = [
            [0.1234, 0.2345, 1.0],
            [-0.3123, 0.1711, 1.0],
            [0.2718, -0.3141, 1.0],
            [-0.1618, -0.2236, 1.0],
        ];
        let mut near = Vec::new();
        'directions: for d in DIRECTIONS {
            let d = DVec3::from_array(d).normalize();
            // The faces whose boxes the ray's box (up to the solid's top)
            // meets.
            let end = p + d * ((self.max.z - p.z).max(0.0) / d.z);
            let (lo, hi) = (p.min(end).as_vec3(), p.max(end).as_vec3());
            let query = Aabb::new(lo - lo.abs() * 1e-6 - 1e-6, hi + hi.abs() * 1e-6 + 1e-6);
            near.clear();
            self.tree.overlapping(&query, &mut near);
            let mut crossings = 0usize;
            for &t in &near {
                let [a, b, c] = self.corners(t as usize);
                match ray_crosses(p, d, [a, b, c]) {
                    Crossing::No => {}
                    Crossing::Yes => crossings += 1,
                    Crossing::Unsure => continue 'directions,
                }
            }
            return crossings % 2 == 1;
        }
        false
    }

    fn shrunk(&self, moved: &[DVec3], keep: &[bool]) -> Shrunk {
        let triangles: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .zip(keep)
            .filter(|(_, k)| **k)
            .map(|(t, _)| *t)
            .collect();
        let mut by_edge: HashMap<(u32, u32), Edge> = HashMap::new();
        for t in &triangles {
            for k in 0..3 {
                let (a, b, third) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                let key = (a.min(b), a.max(b));
                let e = by_edge.entry(key).or_insert(Edge {
                    a: key.0,
                    b: key.1,
                    third: [None, None],
                });
                if e.third[0].is_none() {
                    e.third[0] = Some(third);
                } else {
                    // A closed manifold mesh has at most two faces an edge.
                    e.third[1] = Some(third);
                }
            }
        }
        let mut edges: Vec<Edge> = by_edge.into_values().collect();
        edges.sort_by_key(|e| (e.a, e.b));
        Shrunk {
            floor: self.floor,
            solid_min: self.min,
            solid_max: self.max,
            vertices: moved.to_vec(),
            triangles,
            edges,
        }
    }
}

enum Crossing {
    No,
    Yes,
    Unsure,
}

/// Whether the ray `p + t d` (t > 0) crosses the triangle, clearly away
/// from its edges and plane-parallel cases (else unsure).
fn ray_crosses(p: DVec3, d: DVec3, [a, b, c]: [DVec3; 3]) -> Crossing {
    let (e1, e2) = (b - a, c - a);
    let h = d.cross(e2);
    let det = e1.dot(h);
    let scale = e1.length() * e2.length();
    if det.abs() <= 1e-9 * scale {
        // Parallel to the plane: it crosses nothing unless it lies in it.
        let n = e1.cross(e2).normalize_or_zero();
        return if n.dot(p - a).abs() <= 1e-9 * (e1.length() + e2.length()) {
            Crossing::Unsure
        } else {
            Crossing::No
        };
    }
    let inv = 1.0 / det;
    let s = p - a;
    let u = s.dot(h) * inv;
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    let t = e2.dot(q) * inv;
    let tol = 1e-9;
    if u < -tol || v < -tol || u + v > 1.0 + tol || t < -tol * (e1.length() + e2.length()) {
        return Crossing::No;
    }
    if u <= tol || v <= tol || u + v >= 1.0 - tol || t <= tol * (e1.length() + e2.length()) {
        return Crossing::Unsure;
    }
    Crossing::Yes
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The 12 triangles of the box `[a, b]`, outward.
    pub(crate) fn box_triangles(a: DVec3, b: DVec3) -> Vec<[DVec3; 3]> {
        let c = crate::oracle::corners(a, b);
        let mut out = Vec::new();
        for q in crate::shrink::shrink_cube::BOX_QUADS {
            out.push([c[q[0]], c[q[1]], c[q[2]]]);
            out.push([c[q[0]], c[q[2]], c[q[3]]]);
        }
        out
    }

    #[test]
    fn a_box_shrinks_by_e_on_every_side() {
        let s = Solid::new(&box_triangles(DVec3::ZERO, DVec3::new(4.0, 6.0, 8.0)), None).unwrap();
        let (shrunk, counts) = s.shrink(1.0, 1e-6);
        assert_eq!(counts.kept, 12, "{counts:?}");
        let (min, max) = shrunk.bounds();
        // Moved by e plus twice the margin.
        assert!((min - DVec3::ONE).abs().max_element() < 1e-5, "{min:?}");
        assert!((max - DVec3::new(3.0, 5.0, 7.0)).abs().max_element() < 1e-5);
        // Every edge has its two faces.
        assert!(shrunk.edges.iter().all(|e| e.third[1].is_some()));
        // Inward winding of the input is turned out.
        let inward: Vec<_> = box_triangles(DVec3::ZERO, DVec3::ONE * 4.0)
            .into_iter()
            .map(|[a, b, c]| [a, c, b])
            .collect();
        let (shrunk, counts) = Solid::new(&inward, None).unwrap().shrink(1.0, 1e-6);
        assert_eq!(counts.kept, 12);
        assert!((shrunk.bounds().1 - DVec3::splat(3.0)).abs().max_element() < 1e-5);
    }

    #[test]
    fn open_meshes_are_not_solids() {
        let mut tris = box_triangles(DVec3::ZERO, DVec3::ONE);
        // A hole in the top (faces 2 and 3 are z = 1).
        tris.remove(2);
        assert!(Solid::new(&tris, None).is_none());
        // Open at the top is no floor either.
        assert!(Solid::new(&tris, Some(0.0)).is_none());
        // Two faces wound against their neighbours.
        let mut flipped = box_triangles(DVec3::ZERO, DVec3::ONE);
        flipped[0].swap(1, 2);
        assert!(Solid::new(&flipped, None).is_none());
    }

    #[test]
    fn a_thin_wall_vanishes_and_the_check_stands_behind_the_paper() {
        // 0.2 thick, shrunk by 0.5: the faces cross; all are removed.
        let s = Solid::new(
            &box_triangles(DVec3::ZERO, DVec3::new(10.0, 0.2, 3.0)),
            None,
        )
        .unwrap();
        let (shrunk, counts) = s.shrink(0.5, 1e-6);
        assert!(shrunk.triangles.is_empty(), "{counts:?}");
        // Whatever survives any shrinking is deep enough inside.
        let s = Solid::new(
            &box_triangles(DVec3::ZERO, DVec3::new(10.0, 2.0, 3.0)),
            None,
        )
        .unwrap();
        for e in [0.1, 0.5, 0.9, 0.99, 1.01, 2.0] {
            let (shrunk, _) = s.shrink(e, 1e-6);
            for t in &shrunk.triangles {
                for &v in t {
                    let p = shrunk.vertices[v as usize];
                    let depth = (p - DVec3::ZERO)
                        .min(DVec3::new(10.0, 2.0, 3.0) - p)
                        .min_element();
                    assert!(depth >= e, "e {e}: a vertex {depth} deep");
                }
            }
        }
    }

    #[test]
    fn a_block_on_a_floor_shrinks_across_it_and_stays_on_it() {
        let mut tris = box_triangles(DVec3::ZERO, DVec3::new(6.0, 6.0, 10.0));
        // Drop the two floor triangles (z = 0 faces come first in quads[0]).
        tris.drain(0..2);
        let s = Solid::new(&tris, Some(0.0)).unwrap();
        let (shrunk, counts) = s.shrink(1.0, 1e-6);
        assert_eq!(counts.kept, 10, "{counts:?}");
        let (min, max) = shrunk.bounds();
        assert!(
            (min - DVec3::new(1.0, 1.0, 0.0)).abs().max_element() < 1e-5,
            "{min:?}"
        );
        assert!(
            (max - DVec3::new(5.0, 5.0, 9.0)).abs().max_element() < 1e-5,
            "{max:?}"
        );
        // The hole where the floor was is an outline.
        assert_eq!(
            shrunk.edges.iter().filter(|e| e.third[1].is_none()).count(),
            4
        );
    }

    #[test]
    fn an_l_shaped_solid_keeps_only_faces_deep_inside() {
        // An L prism: the inner corner's faces move towards each other.
        let pts2 = [
            (0.0, 0.0),
            (6.0, 0.0),
            (6.0, 2.0),
            (2.0, 2.0),
            (2.0, 6.0),
            (0.0, 6.0),
        ];
        let mut tris = Vec::new();
        let h = 3.0;
        let p = |i: usize, z: f64| DVec3::new(pts2[i % 6].0, pts2[i % 6].1, z);
        for i in 0..6 {
            tris.push([p(i, 0.0), p(i + 1, 0.0), p(i + 1, h)]);
            tris.push([p(i, 0.0), p(i + 1, h), p(i, h)]);
        }
        // Caps (a fan from corner 0 would not be convex: split by hand).
        for (a, b, c) in [(0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 5)] {
            tris.push([p(a, h), p(b, h), p(c, h)]);
            tris.push([p(a, 0.0), p(c, 0.0), p(b, 0.0)]);
        }
        let s = Solid::new(&tris, None).unwrap();
        let inside = |q: DVec3| {
            let in2 = (q.x >= 0.0 && q.x <= 6.0 && q.y >= 0.0 && q.y <= 2.0)
                || (q.x >= 0.0 && q.x <= 2.0 && q.y >= 0.0 && q.y <= 6.0);
            in2 && q.z >= 0.0 && q.z <= h
        };
        for e in [0.2, 0.5, 0.8, 0.95] {
            let (shrunk, counts) = s.shrink(e, 1e-6);
            assert!(counts.kept > 0, "e {e}: {counts:?}");
            // Sample each kept face; each point has the ball of radius e
            // inside the L (checked on 26 directions).
            for t in &shrunk.triangles {
                let [a, b, c] = t.map(|v| shrunk.vertices[v as usize]);
                for (u, v) in [
                    (0.2, 0.2),
                    (0.6, 0.2),
                    (0.2, 0.6),
                    (0.0, 0.0),
                    (1.0, 0.0),
                    (0.0, 1.0),
                ] {
                    let q = a + (b - a) * u + (c - a) * v;
                    for dx in [-1.0, 0.0, 1.0] {
                        for dy in [-1.0, 0.0, 1.0] {
                            for dz in [-1.0, 0.0, 1.0] {
                                let d = DVec3::new(dx, dy, dz).normalize_or_zero();
                                assert!(inside(q + d * e * 0.999), "e {e}: {q:?} + {d:?}");
                            }
                        }
                    }
                }
            }
        }
    }
}
