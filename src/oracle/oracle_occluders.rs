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
//! - and, besides its polygons, a **convex shell**: an object whose
//!   polygons overlap to cover, with room to spare, the boundary of the
//!   convex polytope their planes bound (a crown of leaves tangent to an
//!   ellipsoid, each reaching past where its neighbours' planes cut it;
//!   a box of faces that overlap at its edges). No edge is shared, so it
//!   is no closed mesh, but a segment crossing the polytope crosses its
//!   boundary, which lies inside the polygons: see [`convex_shell`] for
//!   the margins that make this hold for the tracer's rays.
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
    /// For a convex shell, the largest tracer slack of a cell it may be
    /// used from (its margins were sized for it); `None` otherwise.
    pub shell_slack: Option<f64>,
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
            shell_slack: None,
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

    /// Whether it may be used from a cell whose tracer slack is `slack`
    /// (a convex shell only up to the slack its margins were sized for).
    pub fn usable(&self, slack: f64) -> bool {
        self.shell_slack.is_none_or(|s| slack <= s)
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
    /// Convex shells (objects whose polygons cover a convex polytope's
    /// boundary; their polygons are occluders too).
    pub shells: usize,
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
    extract_with(scene, true)
}

/// [`extract`], with the convex shells only when `shells` (the sliceable
/// solids alone need none).
pub fn extract_with(scene: &Scene, shells: bool) -> Extracted {
    let mut out = Extracted::default();
    // Shells are sized for the slack of the scene's box grown by a tenth
    // on each side: a cell whose own slack is larger (one farther out)
    // does not use them. (The margins grow with the slack, so with the
    // scene's scale: a box twice the scene's lost the shells of a grove
    // 80 m wide.)
    let b = scene.bounds();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let grown = 0.1 * (hi - lo);
    let shell_slack = super::tracer_slack(scene, lo - grown, hi + grown);
    for object in 0..scene.objects().len() {
        let o = &scene.objects()[object];
        if !o.flags.occludes() || o.is_empty() {
            continue;
        }
        extract_object(
            scene.object_triangles(object),
            object as u32,
            shells.then_some(shell_slack),
            &mut out,
        );
    }
    out
}

/// An object's welded mesh: vertex positions and triangles as indices.
pub(super) struct Mesh {
    pub(super) vertices: Vec<DVec3>,
    pub(super) triangles: Vec<[u32; 3]>,
}

/// Welds triangles by their corners' bits (0.0 and -0.0 alike), leaving
/// out those whose welded corners repeat.
pub(super) fn weld(triangles: &[[Vec3; 3]]) -> Mesh {
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

fn extract_object(
    triangles: &[[Vec3; 3]],
    object: u32,
    shell_slack: Option<f64>,
    extracted: &mut Extracted,
) {
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
    let first = out.len();
    let any_solid = used.iter().any(|&u| u);
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
    // A convex shell of those polygons (an object with a closed solid
    // already has its occluder).
    if let (false, Some(shell_slack)) = (any_solid, shell_slack) {
        let polygons: Vec<&[DVec3]> = out[first..].iter().map(|o| o.points.as_slice()).collect();
        if let Some(shell) = convex_shell(&polygons, object, shell_slack) {
            counts.shells += 1;
            out.push(shell);
        }
    }
}

/// The most polygons an object may have to be tried as a convex shell
/// (the test costs their number squared).
const SHELL_POLYGONS: usize = 2048;

/// How far, at most, a shell's planes are moved inwards for its margins,
/// as a share of its size (else it is not used).
const SHELL_INSET: f64 = 0.05;

/// An object's convex polygons as a **convex shell**, when they cover the
/// boundary of the convex polytope `P` bounded by their planes (each
/// oriented away from the mean of their corners, which must lie inside
/// every one): `P` shrunk by a margin `eta` is then a convex solid
/// occluder of the object, used from cells whose tracer slack is at most
/// `slack`.
///
/// **Why.** Each face of `P` (its part of one polygon's plane, the plane
/// clipped by all the others) must lie inside that polygon by `mu > 0` in
/// the plane; `mu` is the smallest such inset over all faces. A segment
/// from a point outside `P` (the solid's box is the object's, which holds
/// `P`, so the oracle's "apart from the solid's box" and "the cell
/// reaches into it" tests see `P`'s box) that reaches a point of `P_eta`
/// (every plane moved in by `eta`) crosses `P`'s boundary at a point `x`
/// of some face before it: `x` lies inside that face's polygon by `mu`,
/// and the segment, which goes from `x` to a point `eta` below the plane
/// within `P`'s diameter `D`, meets the plane at an angle whose sine is at
/// least `eta / D`. A ray that far from each edge of a polygon and that
/// steep to it passes its edges' lines by at least `mu eta / D` (the
/// distance between the ray's line and an edge's, across both), which
/// `eta` makes the tracer's slack (below): the
/// tracer hits the polygon. From inside `P_eta` the same holds for the
/// segment's way out. So what `P_eta` hides from a cell apart from `P` is
/// hidden, and a viewpoint inside `P_eta` sees only what lies in `P`'s
/// box. The polygons' triangles lie up to twice the planar tolerance
/// (`1e-7` of the size, below any slack) off the plane, which moves the
/// crossing along it by that over the sine, less than `mu / 2`: so `eta`
/// is taken as `2 slack D / mu`, for the slack (eight f32 roundings of
/// the scene's scale, [`super::tracer_slack`]) at `mu / 2`.
///
/// `None` for fewer than four polygons or more than [`SHELL_POLYGONS`],
/// a mean corner not inside every plane, a face not inside its polygon,
/// or an `eta` above [`SHELL_INSET`] of `D`.
fn convex_shell(polygons: &[&[DVec3]], object: u32, slack: f64) -> Option<Occluder> {
    if polygons.len() < 4 || polygons.len() > SHELL_POLYGONS {
        return None;
    }
    let corners = polygons.iter().flat_map(|p| p.iter().copied());
    let count = corners.clone().count() as f64;
    let centre = corners.clone().fold(DVec3::ZERO, |a, p| a + p) / count;
    let (min, max) = corners.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| {
        (a.min(p), b.max(p))
    });
    let size = (max - min).length();
    if size.is_nan() || size <= 0.0 || size.is_infinite() {
        return None;
    }
    let flatness = PLANAR_TOLERANCE * size;
    // Each polygon's plane (outward from the centre) and its edges'
    // inward half-planes `m . x >= e` within it.
    let mut planes: Vec<(DVec3, f64)> = Vec::with_capacity(polygons.len());
    let mut edges: Vec<Vec<(DVec3, f64)>> = Vec::with_capacity(polygons.len());
    for polygon in polygons {
        let k = polygon.len();
        if k < 3 {
            return None;
        }
        // Newell's normal: the polygon's area vector.
        let mut normal = DVec3::ZERO;
        for i in 0..k {
            let (a, b) = (polygon[i], polygon[(i + 1) % k]);
            normal += a.cross(b);
        }
        let n = normal.normalize_or_zero();
        if n == DVec3::ZERO {
            return None;
        }
        let d = polygon
            .iter()
            .map(|&p| n.dot(p))
            .fold(f64::NEG_INFINITY, f64::max);
        let below = d - n.dot(centre);
        let (n, d) = if below > 0.0 {
            (n, d)
        } else {
            let d = polygon
                .iter()
                .map(|&p| -n.dot(p))
                .fold(f64::NEG_INFINITY, f64::max);
            (-n, d)
        };
        if d - n.dot(centre) < 1e-6 * size {
            return None;
        }
        planes.push((n, d));
        // The winding's turn about `n` orients the edges' normals inwards.
        let turn = normal.dot(n).signum();
        edges.push(
            (0..k)
                .map(|i| {
                    let (a, b) = (polygon[i], polygon[(i + 1) % k]);
                    let m = (turn * n.cross(b - a)).normalize_or_zero();
                    (m, m.dot(a))
                })
                .collect(),
        );
    }
    // The faces of `P`, each inside its polygon: the smallest inset.
    let mut inset = f64::INFINITY;
    for (i, &(n, d)) in planes.iter().enumerate() {
        // The other planes relaxed outwards, far beyond the clipping's
        // rounding: the face found holds the exact face, whatever the
        // rounding (a review's counterexample: two coplanar polygons of
        // bit-identical planes, the only ones on the top of a box, each
        // clipped the other's face away by one ulp, and the open top was
        // never checked; now each must hold all of it).
        let face = face_of(&planes, i, (n, d), centre, size, RELAX * size);
        for &x in &face {
            for &(m, e) in &edges[i] {
                inset = inset.min(m.dot(x) - e);
            }
        }
        // (A NaN inset, from a degenerate face, is refused too.)
        if inset.is_nan() || inset <= 1e3 * flatness {
            return None;
        }
    }
    // (A plane that bounds no face of `P` is harmless: its polygon lies
    // outside `P`.)
    let eta = 2.0 * slack * size / inset;
    if eta.is_nan() || eta > SHELL_INSET * size {
        return None;
    }
    let moved: Vec<(DVec3, f64)> = planes.iter().map(|&(n, d)| (n, d - eta)).collect();
    let mut points = Vec::new();
    for (i, &plane) in moved.iter().enumerate() {
        points.extend(face_of(&moved, i, plane, centre, size, 0.0));
    }
    // Each corner comes once per face around it: one of each cluster of
    // corners within a millionth of the size is kept (each is the corner,
    // up to the clipping's rounding).
    points.sort_by(|a, b| a.x.total_cmp(&b.x));
    let near = 1e-6 * size;
    let mut kept: Vec<DVec3> = Vec::with_capacity(points.len() / 2);
    for &p in &points {
        let duplicate = kept
            .iter()
            .rev()
            .take_while(|q| p.x - q.x <= near)
            .any(|q| (p - *q).abs().max_element() <= near);
        if !duplicate {
            kept.push(p);
        }
    }
    let points = kept;
    if points.len() < 4 {
        return None;
    }
    let mut shell = Occluder::new(object, points, true);
    shell.planes = moved;
    // The box of the polygons, which holds `P`.
    (shell.min, shell.max) = (min, max);
    shell.shell_slack = Some(slack);
    Some(shell)
}

/// The cross-section of the convex polytope `n . x <= d` over `planes`
/// with the plane `n . x = d` of `plane` (not one of them): its corners,
/// in order around it (none where the plane misses it); `centre` and
/// `size` are a point near the polytope and a length beyond its width.
pub(crate) fn section(
    planes: &[(DVec3, f64)],
    plane: (DVec3, f64),
    centre: DVec3,
    size: f64,
) -> Vec<DVec3> {
    face_of(planes, usize::MAX, plane, centre, size, 0.0)
}

/// How far, relative to a shell's size, the other planes are moved out
/// when a face is found for the inset test (a million times the f64
/// rounding of a clip).
const RELAX: f64 = 1e-9;

/// The part of plane `i` (`n . x = d`) inside every other plane of
/// `planes` moved out by `relax`: a square around `centre`'s projection,
/// `4 size` wide (far beyond any bounded face), clipped by each; its
/// corners. With `relax` well above the rounding, the corners' polygon
/// holds the exact face: each clip keeps what the exact one keeps (a
/// point inside the exact plane is `relax` inside the moved one), and its
/// new corners lie on the edges it cuts, outside the exact plane.
fn face_of(
    planes: &[(DVec3, f64)],
    i: usize,
    (n, d): (DVec3, f64),
    centre: DVec3,
    size: f64,
    relax: f64,
) -> Vec<DVec3> {
    let origin = centre + n * (d - n.dot(centre));
    let u = n.any_orthonormal_vector();
    let v = n.cross(u);
    let h = 2.0 * size;
    let mut face = vec![
        origin - u * h - v * h,
        origin + u * h - v * h,
        origin + u * h + v * h,
        origin - u * h + v * h,
    ];
    let mut next = Vec::with_capacity(16);
    // The planes nearest in direction first, which cut the face down
    // soonest; then a ball around the face: a plane it lies wholly inside
    // leaves the face as it is.
    let mut order: Vec<(f64, usize)> = (0..planes.len())
        .filter(|&j| j != i)
        .map(|j| (-n.dot(planes[j].0), j))
        .collect();
    let by = |a: &(f64, usize), b: &(f64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
    const NEAREST: usize = 24;
    if order.len() > NEAREST {
        order.select_nth_unstable_by(NEAREST, by);
    }
    let head = order.len().min(NEAREST);
    order[..head].sort_unstable_by(by);
    let mut ball = (origin, 2.0 * h);
    for &(_, j) in &order {
        let (m, e) = planes[j];
        let e = e + relax;
        if m.dot(ball.0) + ball.1 <= e {
            continue;
        }
        next.clear();
        let k = face.len();
        for a in 0..k {
            let (p, q) = (face[a], face[(a + 1) % k]);
            let (sp, sq) = (m.dot(p) - e, m.dot(q) - e);
            if sp <= 0.0 {
                next.push(p);
            }
            if (sp < 0.0 && sq > 0.0) || (sp > 0.0 && sq < 0.0) {
                next.push(p + (q - p) * (sp / (sp - sq)));
            }
        }
        std::mem::swap(&mut face, &mut next);
        if face.is_empty() {
            break;
        }
        let mid = face.iter().fold(DVec3::ZERO, |a, &p| a + p) / face.len() as f64;
        let reach = face.iter().map(|&p| (p - mid).length()).fold(0.0, f64::max);
        ball = (mid, reach * (1.0 + 1e-9) + 1e-12 * size);
    }
    face
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

    /// The shells of a scene's objects, by object.
    fn shells(scene: &Scene) -> Vec<Occluder> {
        extract(scene)
            .occluders
            .into_iter()
            .filter(|o| o.shell_slack.is_some())
            .collect()
    }

    #[test]
    fn the_groves_crowns_are_convex_shells_and_the_thickets_are_not() {
        use crate::scene::procedural::{SceneKind, generate};
        let grove = generate(SceneKind::Grove, 1, 1);
        let crowns = (0..grove.objects().len())
            .filter(|&i| grove.objects()[i].name.ends_with("/crown"))
            .count();
        let found = shells(&grove);
        assert_eq!(found.len(), crowns);
        assert_eq!(extract(&grove).counts.shells, crowns);
        for shell in &found {
            let name = &grove.objects()[shell.object as usize].name;
            assert!(name.ends_with("/crown"), "{name}");
            assert_eq!(shell.planes.len(), 400, "{name}");
            // Its corners lie inside every plane, within the box given.
            for &p in &shell.points {
                assert!(shell.planes.iter().all(|&(n, d)| n.dot(p) <= d + 1e-9));
                assert!(p.cmpge(shell.min).all() && p.cmple(shell.max).all());
            }
        }
        let thicket = generate(SceneKind::Thicket, 1, 1);
        assert!(shells(&thicket).is_empty());
    }

    /// A crown with one leaf taken away has a hole where that leaf's face
    /// was: the neighbours' planes close the polytope beyond their leaves.
    /// A box of six faces reaching a tenth past its edges is a shell; one
    /// whose faces stop at the edges (unwelded: no room to spare) is not.
    #[test]
    fn a_leaf_missing_or_no_overlap_is_no_shell() {
        use crate::scene::procedural::{SceneKind, generate};
        let grove = generate(SceneKind::Grove, 1, 1);
        let crown = (0..grove.objects().len())
            .find(|&i| grove.objects()[i].name.ends_with("/crown"))
            .expect("a crown");
        let mut leaves = grove.object_triangles(crown).to_vec();
        assert_eq!(shells(&scene_of(vec![leaves.clone()])).len(), 1);
        leaves.remove(123);
        assert!(shells(&scene_of(vec![leaves])).is_empty());

        let quads = |reach: f32| {
            let (lo, hi) = (Vec3::splat(-reach), Vec3::splat(1.0 + reach));
            let mut tris = Vec::new();
            for axis in 0..3 {
                for side in [0.0f32, 1.0] {
                    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                    let corner = |a: f32, b: f32| {
                        let mut p = Vec3::ZERO;
                        p[axis] = side;
                        p[u] = a;
                        p[v] = b;
                        p
                    };
                    let [a, b, c, d] = [
                        corner(lo[u], lo[v]),
                        corner(hi[u], lo[v]),
                        corner(hi[u], hi[v]),
                        corner(lo[u], hi[v]),
                    ];
                    tris.push([a, b, c]);
                    tris.push([a, c, d]);
                }
            }
            shells(&scene_of(vec![tris]))
        };
        let found = quads(0.1);
        assert_eq!(found.len(), 1);
        // The unit box, moved in by a margin far below its size.
        let shell = &found[0];
        assert_eq!(shell.planes.len(), 6);
        for &p in &shell.points {
            assert!(
                p.cmpgt(DVec3::ZERO).all() && p.cmplt(DVec3::ONE).all(),
                "{p}"
            );
            assert!(p.cmplt(DVec3::splat(1e-3)).any() || p.cmpgt(DVec3::splat(1.0 - 1e-3)).any());
        }
        assert!(quads(0.0).is_empty());
    }

    /// A review's counterexample: a box of quads reaching past its edges,
    /// its top only two small coplanar quads. Their planes are
    /// bit-identical, and at some heights each clipped the other's face
    /// away by one ulp, so the open top was never checked: a shell. Each
    /// must now hold all of the top, so none is.
    #[test]
    fn an_open_top_on_two_coplanar_patches_is_no_shell() {
        let box_of = |top: f32| {
            let (e, bottom) = (0.125f32, -3.0f32);
            let (lo, hi) = (-e, 1.0 + e);
            let quads = [
                [
                    [lo, lo, bottom],
                    [hi, lo, bottom],
                    [hi, hi, bottom],
                    [lo, hi, bottom],
                ],
                [
                    [0.0, lo, bottom - e],
                    [0.0, hi, bottom - e],
                    [0.0, hi, top + e],
                    [0.0, lo, top + e],
                ],
                [
                    [1.0, lo, bottom - e],
                    [1.0, hi, bottom - e],
                    [1.0, hi, top + e],
                    [1.0, lo, top + e],
                ],
                [
                    [lo, 0.0, bottom - e],
                    [hi, 0.0, bottom - e],
                    [hi, 0.0, top + e],
                    [lo, 0.0, top + e],
                ],
                [
                    [lo, 1.0, bottom - e],
                    [hi, 1.0, bottom - e],
                    [hi, 1.0, top + e],
                    [lo, 1.0, top + e],
                ],
                [
                    [0.25, 0.25, top],
                    [0.375, 0.25, top],
                    [0.375, 0.375, top],
                    [0.25, 0.375, top],
                ],
                [
                    [0.5, 0.5, top],
                    [0.625, 0.5, top],
                    [0.625, 0.625, top],
                    [0.5, 0.625, top],
                ],
            ];
            let mut tris = Vec::new();
            for q in quads {
                let [a, b, c, d] = q.map(Vec3::from_array);
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
            tris
        };
        for top in [1.674f32, 1.5, 1.0 + 1.0 / 3.0] {
            assert!(shells(&scene_of(vec![box_of(top)])).is_empty(), "{top}");
        }
    }

    /// What a shell hides, rays find hidden: segments from outside the
    /// crown's box through the shrunk polytope all hit the crown's leaves.
    #[test]
    fn segments_through_a_shell_hit_its_leaves() {
        use crate::random::uniform_direction;
        use crate::scene::procedural::{SceneKind, generate};
        use crate::trace::{Ray, Tracer};
        use rand::{RngExt, SeedableRng};
        let grove = generate(SceneKind::Grove, 1, 1);
        let crown = (0..grove.objects().len())
            .find(|&i| grove.objects()[i].name.ends_with("/crown"))
            .expect("a crown");
        let scene = scene_of(vec![grove.object_triangles(crown).to_vec()]);
        let shell = &shells(&scene)[0];
        let tracer = Tracer::new(&scene);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(8);
        let (centre, size) = (
            0.5 * (shell.min + shell.max),
            (shell.max - shell.min).length(),
        );
        let mut through_shell = 0;
        for _ in 0..100_000 {
            // From a sphere around the box to a point past the crown, the
            // line aimed near a random point of the shell (often grazing).
            let a = centre + uniform_direction(&mut rng).as_dvec3() * size;
            let k = rng.random_range(0..shell.points.len());
            let aim = shell.points[k]
                + uniform_direction(&mut rng).as_dvec3() * (0.05 * size * rng.random::<f64>());
            let b = a + (aim - a) * 3.0;
            // Only segments reaching into the shrunk polytope count.
            let inside = |t: f64| {
                let x = a + (b - a) * t;
                shell.planes.iter().all(|&(n, d)| n.dot(x) < d)
            };
            if !(0..=64).any(|i| inside(i as f64 / 64.0)) {
                continue;
            }
            through_shell += 1;
            let ray = Ray::segment(a.as_vec3(), b.as_vec3());
            assert!(
                tracer.closest_hit(&ray).is_some(),
                "{a} -> {b} passes the leaves"
            );
        }
        assert!(through_shell > 20_000, "{through_shell}");
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
