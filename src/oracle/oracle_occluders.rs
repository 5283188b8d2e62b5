//! Convex occluders from a scene (papers/001 sec. 3.2-3.3).
//!
//! The extended projection of an occluder is the intersection of its views
//! from the cell's corners, which is only right for *convex* occluders
//! (the set of viewpoints that see a point of the plane through a convex
//! occluder is convex, so the corners stand for the whole cell). Each
//! object therefore becomes a list of convex pieces, each of which is a
//! real surface that a segment crossing it must hit:
//!
//! - a **convex solid**: an edge-connected component of the object's welded
//!   mesh that is closed (every edge shared by exactly two triangles, in
//!   opposite directions) and convex (every vertex on the inner side of
//!   every face's plane). A segment that crosses its hull crosses its
//!   surface.
//! - else **planar convex polygons**: triangles grown greedily across
//!   shared edges into coplanar neighbours while the union stays convex
//!   (the neighbour lies across the shared edge, so the union is exactly
//!   the polygon; the turns at the two ends of the edge are checked).
//!   Single triangles are the fallback.
//!
//! Vertices are welded by exact position (bit-equal f32 coordinates);
//! tolerances are relative to the piece's size and only ever refuse a
//! merge or a solid, never widen one.

use std::collections::HashMap;

use glam::{DVec2, DVec3, Vec3};

use crate::geom::polygon::{convex_hull, signed_area};
use crate::scene::Scene;

/// Relative tolerance for "on the plane" (times the piece's size).
const PLANAR_TOLERANCE: f64 = 1e-7;

/// One convex occluder: the convex hull of `points` is a surface or a solid
/// of object `object`.
#[derive(Clone, Debug)]
pub struct Occluder {
    /// The object it belongs to.
    pub object: u32,
    /// Its corners (a planar polygon's vertices, or a solid's vertices).
    pub points: Vec<DVec3>,
    /// Its bounding box.
    pub min: DVec3,
    /// Its bounding box.
    pub max: DVec3,
    /// Whether it is a closed convex solid (else a planar polygon whose
    /// `points` are in order around it).
    pub solid: bool,
    /// A solid's face planes `(n, d)`, `n` a unit outward normal: its
    /// inside is where `n . p <= d` for every plane (within
    /// [`Occluder::tolerance`]). Empty for a polygon.
    pub planes: Vec<(DVec3, f64)>,
}

impl Occluder {
    fn new(object: u32, points: Vec<DVec3>, solid: bool) -> Self {
        let (min, max) = points
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        Self {
            object,
            points,
            min,
            max,
            solid,
            planes: Vec::new(),
        }
    }

    /// The box `[a, b]` as a closed convex solid of `object` (tests).
    #[cfg(test)]
    pub(crate) fn test_box(object: u32, a: DVec3, b: DVec3) -> Self {
        let points = super::oracle_project::corners(a, b).to_vec();
        let mut o = Self::new(object, points, true);
        for axis in 0..3 {
            let mut n = DVec3::ZERO;
            n[axis] = 1.0;
            o.planes.push((n, b[axis]));
            o.planes.push((-n, -a[axis]));
        }
        o
    }

    /// How far a solid's vertices may lie outside its face planes (the
    /// convexity test's tolerance): a point is surely inside the solid
    /// when it is inside every plane by more than this.
    pub fn tolerance(&self) -> f64 {
        PLANAR_TOLERANCE * (self.max - self.min).length()
    }
}

/// How a scene's objects became occluders.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OccluderCounts {
    /// Convex solids.
    pub solids: usize,
    /// Planar polygons of more than one triangle.
    pub polygons: usize,
    /// Single triangles.
    pub triangles: usize,
    /// Triangles fused into solids or polygons.
    pub fused_triangles: usize,
}

/// An object whose surface encloses a volume, for slicing (papers/001
/// sec. 3.3): where a projection plane cuts it, the cut is an occluder
/// lying in the plane, since a segment from outside to a point inside
/// crosses the surface.
///
/// Closed means closed modulo two: every edge of the welded mesh is
/// shared by an even number of triangles, whatever their winding (its
/// inside is then where the even-odd rule says). Extruded
/// footprints without a floor (common in city models) are accepted too,
/// as *open at the bottom*: every edge shared by an odd number lies in the plane
/// `z = open_bottom`, the object's lowest; they count as closed by a
/// virtual floor for viewpoints strictly above that plane (a segment
/// between two points above it cannot reach the floor).
#[derive(Clone, Debug)]
pub struct SlicedSolid {
    /// The object.
    pub object: u32,
    /// Its triangles (welded: shared corners are bit-identical).
    pub triangles: Vec<[DVec3; 3]>,
    /// Its edges without a twin (all on the floor plane), as corner pairs.
    pub open_edges: Vec<[DVec3; 2]>,
    /// Its bounding box.
    pub min: DVec3,
    /// Its bounding box.
    pub max: DVec3,
    /// The floor plane's height when open at the bottom.
    pub open_bottom: Option<f64>,
}

/// Everything the oracle uses of a scene's geometry.
#[derive(Clone, Debug, Default)]
pub struct Extracted {
    /// Convex occluders.
    pub occluders: Vec<Occluder>,
    /// Objects that can be sliced.
    pub solids: Vec<SlicedSolid>,
    /// How objects became convex occluders.
    pub counts: OccluderCounts,
}

/// Extracts the convex occluders and the sliceable solids of every object
/// of a scene that occludes (none of an object flagged
/// [`crate::scene::ObjectFlags::NEVER_OCCLUDER`]).
pub fn extract(scene: &Scene) -> Extracted {
    let mut out = Extracted::default();
    for object in 0..scene.objects().len() {
        let o = &scene.objects()[object];
        if !o.flags.occludes() || o.is_empty() {
            continue;
        }
        extract_object(scene.object_triangles(object), object as u32, &mut out);
    }
    out
}

/// An object's welded mesh: vertex positions and triangles as indices.
struct Mesh {
    vertices: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
}

fn weld(triangles: &[[Vec3; 3]]) -> Mesh {
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut vertices = Vec::new();
    let mut tris = Vec::with_capacity(triangles.len());
    for t in triangles {
        let ids = t.map(|v| {
            let key = v.to_array().map(|c| if c == 0.0 { 0 } else { c.to_bits() });
            *index.entry(key).or_insert_with(|| {
                vertices.push(v.as_dvec3());
                (vertices.len() - 1) as u32
            })
        });
        // Triangles whose welded corners repeat are degenerate: skip them
        // as occluders (they are still objects' surfaces for tracing).
        if ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2] {
            tris.push(ids);
        }
    }
    Mesh {
        vertices,
        triangles: tris,
    }
}

fn extract_object(triangles: &[[Vec3; 3]], object: u32, extracted: &mut Extracted) {
    let Extracted {
        occluders: out,
        solids,
        counts,
    } = extracted;
    let mesh = weld(triangles);
    // Directed edge -> triangle.
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.triangles.len() * 3);
    let mut manifold = true;
    for (i, t) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            if edges.insert((t[k], t[(k + 1) % 3]), i as u32).is_some() {
                manifold = false;
            }
        }
    }
    if let Some(solid) = sliced_solid(&mesh, object) {
        solids.push(solid);
    }
    let mut used = vec![false; mesh.triangles.len()];
    // Convex solids, per edge-connected component.
    if manifold {
        for component in components(&mesh, &edges) {
            if let Some((points, planes)) = convex_solid(&mesh, &component, &edges) {
                for &t in &component {
                    used[t as usize] = true;
                }
                counts.solids += 1;
                counts.fused_triangles += component.len();
                let mut solid = Occluder::new(object, points, true);
                solid.planes = planes;
                out.push(solid);
            }
        }
    }
    // Planar polygons from what is left.
    for start in 0..mesh.triangles.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let polygon = grow_polygon(&mesh, start, &edges, &mut used);
        let n = polygon.fused;
        if n > 1 {
            counts.polygons += 1;
            counts.fused_triangles += n;
        } else {
            counts.triangles += 1;
        }
        out.push(Occluder::new(object, polygon.points, false));
    }
}

/// The mesh as a solid to slice, if it is closed or open only at its
/// bottom, *modulo two*: every edge (either direction) is shared by an
/// even number of triangles, but for edges in the plane of its lowest
/// point. Neither a consistent winding nor a manifold is needed (exports
/// of BIM models flip some triangles of a wall, or give a window's frame
/// and pane one shared edge): such a surface still bounds its inside by
/// the even-odd rule, a segment from a point outside to a point inside
/// crosses it an odd number of times, and both the cuts (closed loops,
/// filled by the even-odd rule) and the shafts only use that.
fn sliced_solid(mesh: &Mesh, object: u32) -> Option<SlicedSolid> {
    if mesh.triangles.is_empty() {
        return None;
    }
    let (min, max) = mesh
        .vertices
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    // Undirected edge -> how many triangles share it; in first-seen order
    // so that the open edges come out the same on every run.
    let mut count: HashMap<(u32, u32), (u32, usize)> = HashMap::new();
    let mut order: Vec<(u32, u32)> = Vec::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            let n = order.len();
            let entry = count.entry(key).or_insert((0, n));
            if entry.1 == n {
                order.push((a, b));
            }
            entry.0 += 1;
        }
    }
    let mut open_edges = Vec::new();
    for &(a, b) in &order {
        if count[&(a.min(b), a.max(b))].0 % 2 == 1 {
            let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
            if pa.z != min.z || pb.z != min.z {
                return None;
            }
            open_edges.push([pa, pb]);
        }
    }
    let open_bottom = (!open_edges.is_empty()).then_some(min.z);
    Some(SlicedSolid {
        object,
        triangles: mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| mesh.vertices[i as usize]))
            .collect(),
        open_edges,
        min,
        max,
        open_bottom,
    })
}

/// Edge-connected components of a mesh, as triangle lists.
fn components(mesh: &Mesh, edges: &HashMap<(u32, u32), u32>) -> Vec<Vec<u32>> {
    let mut seen = vec![false; mesh.triangles.len()];
    let mut out = Vec::new();
    for start in 0..mesh.triangles.len() {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        let mut stack = vec![start as u32];
        let mut component = Vec::new();
        while let Some(t) = stack.pop() {
            component.push(t);
            let tri = mesh.triangles[t as usize];
            for k in 0..3 {
                if let Some(&n) = edges.get(&(tri[(k + 1) % 3], tri[k]))
                    && !seen[n as usize]
                {
                    seen[n as usize] = true;
                    stack.push(n);
                }
            }
        }
        out.push(component);
    }
    out
}

/// The vertices of a component and its face planes (outward), if it is a
/// closed convex solid.
#[allow(clippy::type_complexity)]
fn convex_solid(
    mesh: &Mesh,
    component: &[u32],
    edges: &HashMap<(u32, u32), u32>,
) -> Option<(Vec<DVec3>, Vec<(DVec3, f64)>)> {
    if component.len() < 4 {
        return None;
    }
    // Closed: every directed edge has its twin.
    for &t in component {
        let tri = mesh.triangles[t as usize];
        for k in 0..3 {
            edges.get(&(tri[(k + 1) % 3], tri[k]))?;
        }
    }
    let mut ids: Vec<u32> = component
        .iter()
        .flat_map(|&t| mesh.triangles[t as usize])
        .collect();
    ids.sort_unstable();
    ids.dedup();
    let points: Vec<DVec3> = ids.iter().map(|&i| mesh.vertices[i as usize]).collect();
    let (min, max) = points
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let size = (max - min).length();
    let tolerance = PLANAR_TOLERANCE * size;
    // Convex: all vertices on one side of every face plane, the same side
    // for all faces (outward or inward winding), and a real volume.
    let mut sign = 0.0;
    let mut volume = 0.0;
    let mut planes = Vec::with_capacity(component.len());
    for &t in component {
        let [a, b, c] = mesh.triangles[t as usize].map(|i| mesh.vertices[i as usize]);
        let normal = (b - a).cross(c - a);
        let length = normal.length();
        if length == 0.0 {
            return None;
        }
        let n = normal / length;
        volume += a.dot(b.cross(c));
        let (mut lo, mut hi) = (0.0f64, 0.0f64);
        for &p in &points {
            let d = n.dot(p - a);
            lo = lo.min(d);
            hi = hi.max(d);
        }
        let side = if hi <= tolerance {
            -1.0
        } else if lo >= -tolerance {
            1.0
        } else {
            return None;
        };
        if hi <= tolerance && lo >= -tolerance {
            return None; // flat: every vertex on this face's plane
        }
        if sign == 0.0 {
            sign = side;
        } else if sign != side {
            return None;
        }
        // Outward: the vertices on the plane's lower side.
        let outward = -side * n;
        planes.push((outward, outward.dot(a)));
    }
    (volume.abs() / 6.0 > 1e-9 * size * size * size).then_some((points, planes))
}

struct Polygon {
    points: Vec<DVec3>,
    fused: usize,
}

/// Grows a convex planar polygon from triangle `start` across shared
/// edges into unused coplanar triangles.
fn grow_polygon(
    mesh: &Mesh,
    start: usize,
    edges: &HashMap<(u32, u32), u32>,
    used: &mut [bool],
) -> Polygon {
    let tri = mesh.triangles[start];
    let [a, b, c] = tri.map(|i| mesh.vertices[i as usize]);
    let normal = (b - a).cross(c - a).normalize();
    let ex = (b - a).normalize();
    let ey = normal.cross(ex);
    let flat = |p: DVec3| DVec2::new((p - a).dot(ex), (p - a).dot(ey));
    let size = (b - a).length().max((c - a).length());
    let mut ring: Vec<u32> = tri.to_vec();
    let mut fused = 1;
    let mut grown = true;
    while grown && ring.len() < 64 {
        grown = false;
        for k in 0..ring.len() {
            let (p, q) = (ring[k], ring[(k + 1) % ring.len()]);
            let Some(&t) = edges.get(&(q, p)) else {
                continue;
            };
            if used[t as usize] {
                continue;
            }
            let other = mesh.triangles[t as usize];
            let r = other
                .into_iter()
                .find(|&v| v != p && v != q)
                .expect("a triangle has three corners");
            let (pa, pb, pc) = (
                mesh.vertices[p as usize],
                mesh.vertices[q as usize],
                mesh.vertices[r as usize],
            );
            let n = (pa - pb).cross(pc - pb);
            let scale = size.max((pc - pa).length());
            let tolerance = PLANAR_TOLERANCE * scale;
            if n.length() == 0.0
                || n.normalize().dot(normal) < 1.0 - 1e-9
                || normal.dot(pc - a).abs() > tolerance
            {
                continue;
            }
            let before = ring[(k + ring.len() - 1) % ring.len()];
            let after = ring[(k + 2) % ring.len()];
            let (f_before, f_p, f_q, f_r, f_after) = (
                flat(mesh.vertices[before as usize]),
                flat(pa),
                flat(pb),
                flat(pc),
                flat(mesh.vertices[after as usize]),
            );
            let turn = |o: DVec2, x: DVec2, y: DVec2| (x - o).perp_dot(y - x);
            let slack = -1e-12 * scale * scale;
            // Across the edge (strictly outside), and convex at both ends.
            if turn(f_p, f_q, f_r) >= 0.0
                || turn(f_before, f_p, f_r) < slack
                || turn(f_r, f_q, f_after) < slack
            {
                continue;
            }
            used[t as usize] = true;
            ring.insert(k + 1, r);
            fused += 1;
            grown = true;
            break;
        }
    }
    let points: Vec<DVec3> = ring.iter().map(|&i| mesh.vertices[i as usize]).collect();
    debug_assert!({
        let mut flat_points: Vec<DVec2> = points.iter().map(|&p| flat(p)).collect();
        signed_area(&convex_hull(&mut flat_points)) > 0.0
    });
    Polygon { points, fused }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::procedural::shapes::{push_box, push_cylinder};
    use crate::scene::{SceneBuilder, SceneFormat};

    fn scene_of(objects: Vec<Vec<[Vec3; 3]>>) -> Scene {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        for (i, tris) in objects.into_iter().enumerate() {
            b.begin_object(format!("o{i}"));
            for t in tris {
                b.push_triangle(t).expect("finite");
            }
        }
        b.finish(std::path::Path::new("test"))
            .expect("a valid scene")
    }

    #[test]
    fn boxes_and_tetrahedra_are_solids_but_unwelded_cylinders_are_not() {
        let mut a = Vec::new();
        push_box(&mut a, Vec3::ZERO, Vec3::ONE);
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let tet = vec![
            [p[0], p[2], p[1]],
            [p[0], p[1], p[3]],
            [p[1], p[2], p[3]],
            [p[0], p[3], p[2]],
        ];
        // The procedural cylinder's seam is not bit-exact (cos and sin of
        // 2 pi in f32): not closed, so its faces are used instead.
        let mut c = Vec::new();
        push_cylinder(&mut c, Vec3::ZERO, Vec3::Z, 1.0, 12);
        let Extracted {
            occluders: occ,
            counts,
            ..
        } = extract(&scene_of(vec![a, tet, c]));
        assert_eq!(counts.solids, 2, "{counts:?}");
        assert_eq!(occ[0].points.len(), 8);
        assert_eq!(occ[1].points.len(), 4);
        assert!(occ[2..].iter().all(|o| !o.solid && o.object == 2));
    }

    #[test]
    fn separate_boxes_are_solids_and_open_ones_merge_into_faces() {
        let mut a = Vec::new();
        push_box(&mut a, Vec3::ZERO, Vec3::ONE);
        push_box(&mut a, Vec3::splat(2.0), Vec3::splat(3.0));
        let Extracted {
            occluders: occ,
            counts,
            ..
        } = extract(&scene_of(vec![a]));
        // One object of two boxes: each is a closed convex component.
        assert_eq!(counts.solids, 2, "{counts:?}");
        assert_eq!(occ.len(), 2);
        // Two boxes sharing an edge: not manifold, so no convex solids;
        // faces (and one solid to slice, closed mod 2).
        let mut b = Vec::new();
        push_box(&mut b, Vec3::ZERO, Vec3::ONE);
        push_box(&mut b, Vec3::new(-1.0, -1.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
        let counts = extract(&scene_of(vec![b])).counts;
        assert_eq!(
            (counts.solids, counts.polygons, counts.triangles),
            (0, 12, 0),
            "{counts:?}"
        );
        // An open box (five faces): no solid, five quads.
        let mut open = Vec::new();
        push_box(&mut open, Vec3::ZERO, Vec3::ONE);
        open.truncate(10);
        let Extracted {
            occluders: occ,
            counts,
            solids,
        } = extract(&scene_of(vec![open.clone()]));
        assert_eq!(counts.solids, 0);
        assert_eq!(counts.polygons, 5, "{counts:?}");
        assert!(occ.iter().all(|o| o.points.len() == 4));
        // Open at a side: not a solid to slice; open at the bottom: one.
        assert!(solids.is_empty());
        let floorless: Vec<[Vec3; 3]> = {
            let mut b = Vec::new();
            push_box(&mut b, Vec3::ZERO, Vec3::ONE);
            b.split_off(2)
        };
        let solids = extract(&scene_of(vec![floorless])).solids;
        assert_eq!(solids.len(), 1);
        assert_eq!(solids[0].open_bottom, Some(0.0));
        assert_eq!(solids[0].open_edges.len(), 4);
        let mut closed = Vec::new();
        push_box(&mut closed, Vec3::ZERO, Vec3::ONE);
        let solids = extract(&scene_of(vec![closed])).solids;
        assert_eq!((solids.len(), solids[0].open_bottom), (1, None));
    }

    #[test]
    fn surfaces_closed_modulo_two_are_solids_to_slice_whatever_their_winding() {
        // A box with two triangles wound the other way (as BIM exports
        // give): not manifold, so no convex solid, but closed mod 2.
        let mut flipped = Vec::new();
        push_box(&mut flipped, Vec3::ZERO, Vec3::ONE);
        flipped[0].swap(1, 2);
        flipped[7].swap(1, 2);
        let found = extract(&scene_of(vec![flipped]));
        assert_eq!(found.counts.solids, 0);
        assert_eq!(found.solids.len(), 1);
        assert_eq!(found.solids[0].open_bottom, None);
        // Two boxes sharing an edge (four triangles on it): one solid.
        let mut b = Vec::new();
        push_box(&mut b, Vec3::ZERO, Vec3::ONE);
        push_box(&mut b, Vec3::new(-1.0, -1.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(extract(&scene_of(vec![b])).solids.len(), 1);
        // Flipped and floorless: open at the bottom, each open edge once.
        let mut floorless = Vec::new();
        push_box(&mut floorless, Vec3::ZERO, Vec3::ONE);
        let mut floorless = floorless.split_off(2);
        floorless[3].swap(0, 1);
        let solids = extract(&scene_of(vec![floorless])).solids;
        assert_eq!(solids.len(), 1);
        assert_eq!(solids[0].open_bottom, Some(0.0));
        assert_eq!(solids[0].open_edges.len(), 4);
        // An edge shared by three triangles off the floor: not closed.
        let mut odd = Vec::new();
        push_box(&mut odd, Vec3::ZERO, Vec3::ONE);
        let [a, b, _] = odd[2];
        odd.push([a, b, Vec3::new(0.5, 0.5, 3.0)]);
        assert!(extract(&scene_of(vec![odd])).solids.is_empty());
    }

    #[test]
    fn a_fan_fuses_into_one_polygon_and_a_concave_one_does_not() {
        // A regular octagon as a fan of 6 triangles: one polygon.
        let ring: Vec<Vec3> = (0..8)
            .map(|i| {
                let a = i as f32 * std::f32::consts::TAU / 8.0;
                Vec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let fan: Vec<[Vec3; 3]> = (1..7).map(|i| [ring[0], ring[i], ring[i + 1]]).collect();
        let Extracted {
            occluders: occ,
            counts,
            ..
        } = extract(&scene_of(vec![fan]));
        assert_eq!((counts.polygons, counts.triangles), (1, 0), "{counts:?}");
        assert_eq!(occ[0].points.len(), 8);
        // An L of three unit squares (6 triangles): not convex as a whole.
        let sq = |x: f32, y: f32| {
            let p = |dx: f32, dy: f32| Vec3::new(x + dx, y + dy, 0.0);
            vec![
                [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)],
                [p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)],
            ]
        };
        let l: Vec<[Vec3; 3]> = [sq(0.0, 0.0), sq(1.0, 0.0), sq(0.0, 1.0)].concat();
        let occ = extract(&scene_of(vec![l])).occluders;
        let area: f64 = occ
            .iter()
            .map(|o| {
                let mut f: Vec<DVec2> = o.points.iter().map(|p| p.truncate()).collect();
                signed_area(&convex_hull(&mut f))
            })
            .sum();
        // The pieces tile the L exactly: no piece covers the missing square.
        assert!((area - 3.0).abs() < 1e-9, "{area}");
    }
}
