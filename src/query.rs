//! The runtime query (papers/003 sec. 7): load a `.v5d` file once, then
//! answer "which objects can be seen from this box of positions, looking
//! into this range of directions?" with a bitset the caller owns.
//!
//! A range query descends from the root into every child whose cell the
//! range meets (the below child `[lo, v)` when `range.lo < v`, the above
//! child `[v, hi)` when `range.hi >= v`) and unites the sets of the leaves
//! reached; a node whose whole cell lies inside the range contributes its
//! own set (the union of its leaves') without descending. A view query
//! turns a camera frustum into one or two (theta, phi) boxes that contain
//! every direction of the frustum ([`frustum_angles`]) and runs range
//! queries with a small box around the position.
//!
//! Queries allocate nothing: the answer goes into an [`ObjectSet`] made once
//! with [`Pvs::new_set`], and the descent is a recursion bounded by
//! [`crate::tree::MAX_DEPTH`].
//!
//! Conservative by construction where the tree is: positions outside the
//! view box the tree was built for get every object (nothing was sampled
//! there, so nothing may be culled).

use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::bitset::ObjectSet;
use crate::codec::{CodecError, Coding, FileObject, ReadLimits, read_file};
use crate::geom::Aabb;
use crate::geom::cell::{Cell, DIMS};

/// Why a `.v5d` file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum PvsError {
    /// The file cannot be read.
    #[error("{}: cannot read the .v5d file: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a valid `.v5d` file.
    #[error("{}: {source}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        source: CodecError,
    },
}

/// The tree was built for other geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "the .v5d file was built for another version of the scene (its fingerprint is {file:016x}, \
     the scene's is {scene:016x}): rebuild it with `vis5d build`"
)]
pub struct FingerprintMismatch {
    /// The fingerprint stored in the file.
    pub file: u64,
    /// The fingerprint of the scene at hand.
    pub scene: u64,
}

/// A node as queries need it: the split value is precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
struct QueryNode {
    /// The split dimension, or [`LEAF`].
    dim: u8,
    /// The split value.
    value: f32,
    /// The second child.
    above: u32,
}

const LEAF: u8 = u8::MAX;

/// A camera: a position (or a small box around it) and a frustum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// The eye.
    pub position: Vec3,
    /// Half the size of the box of positions around the eye (0: the point
    /// itself).
    pub radius: f32,
    /// The viewing direction (need not be unit length).
    pub dir: Vec3,
    /// The up direction (need not be unit or orthogonal to `dir`).
    pub up: Vec3,
    /// The horizontal field of view, radians.
    pub fov_x: f32,
    /// The vertical field of view, radians.
    pub fov_y: f32,
}

impl View {
    /// A view with a square field of view of `fov_degrees`, up = +z (+y
    /// when `dir` is vertical), from the point `position`.
    pub fn square(position: Vec3, dir: Vec3, fov_degrees: f32) -> Self {
        let n = dir.normalize_or_zero();
        let up = if n.z.abs() > 0.999 { Vec3::Y } else { Vec3::Z };
        let fov = fov_degrees.to_radians();
        Self {
            position,
            radius: 0.0,
            dir,
            up,
            fov_x: fov,
            fov_y: fov,
        }
    }
}

/// Up to two (theta, phi) boxes, as `(theta0, theta1, phi0, phi1)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AngularRanges {
    boxes: [(f32, f32, f32, f32); 2],
    count: usize,
}

impl AngularRanges {
    /// The boxes.
    pub fn boxes(&self) -> &[(f32, f32, f32, f32)] {
        &self.boxes[..self.count]
    }

    fn one(b: (f32, f32, f32, f32)) -> Self {
        Self {
            boxes: [b, b],
            count: 1,
        }
    }
}

/// Angular boxes that contain every direction of the frustum looking along
/// `dir` with `up`, `fov_x` by `fov_y` radians: one box, or two when the
/// theta range crosses +-pi. A frustum containing a pole covers every
/// theta. Bounds are padded by 1e-4 rad.
///
/// The frustum's directions are a spherical quadrilateral. Theta is
/// monotone along any great-circle arc that misses the poles, so the theta
/// range is found by walking the four edges and unwrapping; phi's extremes
/// are at the corners, at the highest or lowest point of an edge's great
/// circle when it falls on the edge, or at a pole inside.
pub fn frustum_angles(dir: Vec3, up: Vec3, fov_x: f32, fov_y: f32) -> AngularRanges {
    const PAD: f32 = 1e-4;
    let full = AngularRanges::one((-PI, PI, 0.0, PI));
    let f = dir.normalize_or_zero();
    if f == Vec3::ZERO || !(fov_x < PI && fov_y < PI) || !f.is_finite() {
        return full;
    }
    let mut r = f.cross(up).normalize_or_zero();
    if r == Vec3::ZERO {
        r = f.any_orthonormal_vector();
    }
    let u = r.cross(f);
    let (tx, ty) = ((fov_x * 0.5).max(0.0).tan(), (fov_y * 0.5).max(0.0).tan());
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(sx, sy)| (f + r * (sx * tx) + u * (sy * ty)).normalize());
    let inside = |v: Vec3| {
        let z = v.dot(f);
        z > 0.0 && v.dot(r).abs() <= tx * z && v.dot(u).abs() <= ty * z
    };
    let (north, south) = (inside(Vec3::Z), inside(-Vec3::Z));
    // The z range.
    let mut zmin = corners.iter().map(|c| c.z).fold(f32::INFINITY, f32::min);
    let mut zmax = corners
        .iter()
        .map(|c| c.z)
        .fold(f32::NEG_INFINITY, f32::max);
    for k in 0..4 {
        let (a, b) = (corners[k], corners[(k + 1) % 4]);
        let n = a.cross(b).normalize_or_zero();
        let m = (Vec3::Z - n * n.z).normalize_or_zero();
        for p in [m, -m] {
            if p != Vec3::ZERO && a.cross(p).dot(n) >= 0.0 && p.cross(b).dot(n) >= 0.0 {
                zmin = zmin.min(p.z);
                zmax = zmax.max(p.z);
            }
        }
    }
    if north {
        zmax = 1.0;
    }
    if south {
        zmin = -1.0;
    }
    let phi0 = (zmax.clamp(-1.0, 1.0).acos() - PAD).max(0.0);
    let phi1 = (zmin.clamp(-1.0, 1.0).acos() + PAD).min(PI);
    if north || south {
        return AngularRanges::one((-PI, PI, phi0, phi1));
    }
    // Theta: unwrap along the edges.
    let theta = |v: Vec3| v.y.atan2(v.x);
    let wrap = |d: f32| {
        if d > PI {
            d - TAU
        } else if d < -PI {
            d + TAU
        } else {
            d
        }
    };
    let mut t = theta(corners[0]);
    let (mut tmin, mut tmax) = (t, t);
    for k in 1..4 {
        t += wrap(theta(corners[k]) - theta(corners[k - 1]));
        tmin = tmin.min(t);
        tmax = tmax.max(t);
    }
    let (t0, t1) = (tmin - PAD, tmax + PAD);
    if t1 - t0 >= TAU {
        AngularRanges::one((-PI, PI, phi0, phi1))
    } else if t0 < -PI {
        AngularRanges {
            boxes: [(t0 + TAU, PI, phi0, phi1), (-PI, t1, phi0, phi1)],
            count: 2,
        }
    } else if t1 > PI {
        AngularRanges {
            boxes: [(-PI, t1 - TAU, phi0, phi1), (t0, PI, phi0, phi1)],
            count: 2,
        }
    } else {
        AngularRanges::one((t0, t1, phi0, phi1))
    }
}

/// A loaded `.v5d` file, ready for queries.
#[derive(Clone, Debug)]
pub struct Pvs {
    coding: Coding,
    fingerprint: u64,
    params: String,
    objects: Vec<FileObject>,
    root: Cell,
    nodes: Vec<QueryNode>,
    /// `words` words per node, in node order.
    sets: Vec<u64>,
    words: usize,
}

impl Pvs {
    /// Loads and checks the `.v5d` file at `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<Pvs, PvsError> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|source| PvsError::Io {
            path: path.to_owned(),
            source,
        })?;
        Pvs::from_bytes(&bytes).map_err(|source| PvsError::File {
            path: path.to_owned(),
            source,
        })
    }

    /// Decodes and checks a `.v5d` file held in memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<Pvs, CodecError> {
        let file = read_file(bytes, ReadLimits::default())?;
        let tree = &file.tree;
        let words = tree.object_count().div_ceil(64);
        let mut nodes = Vec::with_capacity(tree.nodes().len());
        let mut sets = Vec::with_capacity(tree.nodes().len() * words);
        // Replay the cells in preorder to precompute split values.
        let mut stack = vec![tree.root_cell()];
        for node in tree.nodes() {
            let cell = stack.pop().expect("preorder: one cell per node");
            sets.extend_from_slice(node.set.words());
            match node.split {
                None => nodes.push(QueryNode {
                    dim: LEAF,
                    value: 0.0,
                    above: 0,
                }),
                Some(s) => {
                    let value = tree.split_value(&cell, &s);
                    let (below, above) = cell.split(s.dim as usize, value);
                    stack.push(above);
                    stack.push(below);
                    nodes.push(QueryNode {
                        dim: s.dim,
                        value,
                        above: s.above,
                    });
                }
            }
        }
        Ok(Pvs {
            coding: file.coding,
            fingerprint: file.fingerprint,
            params: file.params,
            objects: file.objects,
            root: tree.root_cell(),
            nodes,
            sets,
            words,
        })
    }

    /// The objects, in scene order: names and triangle counts.
    pub fn objects(&self) -> &[FileObject] {
        &self.objects
    }

    /// The number of objects (the capacity of every answer).
    pub fn object_count(&self) -> usize {
        self.objects.len()
    }

    /// The scene fingerprint the file was built for.
    pub fn fingerprint(&self) -> u64 {
        self.fingerprint
    }

    /// Checks that the file was built for the scene whose geometry has
    /// `fingerprint` ([`crate::codec::geometry_fingerprint`]).
    pub fn check_fingerprint(&self, fingerprint: u64) -> Result<(), FingerprintMismatch> {
        if fingerprint == self.fingerprint {
            Ok(())
        } else {
            Err(FingerprintMismatch {
                file: self.fingerprint,
                scene: fingerprint,
            })
        }
    }

    /// The build parameters stored in the file, `key=value` lines.
    pub fn params(&self) -> &str {
        &self.params
    }

    /// The coding the file used.
    pub fn coding(&self) -> Coding {
        self.coding
    }

    /// The root cell: the view box times all directions.
    pub fn root_cell(&self) -> Cell {
        self.root
    }

    /// The number of tree nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// An empty answer set of the right size, to reuse across queries.
    pub fn new_set(&self) -> ObjectSet {
        ObjectSet::new(self.objects.len())
    }

    fn set_words(&self, node: usize) -> &[u64] {
        &self.sets[node * self.words..(node + 1) * self.words]
    }

    /// The set of the leaf holding the ray point `p` = (x, y, z, theta,
    /// phi), as words of bits (bit i = object i).
    pub fn leaf_set(&self, p: [f32; DIMS]) -> &[u64] {
        let mut i = 0;
        while self.nodes[i].dim != LEAF {
            let n = self.nodes[i];
            i = if p[n.dim as usize] < n.value {
                i + 1
            } else {
                n.above as usize
            };
        }
        self.set_words(i)
    }

    /// The objects visible from some ray with origin in `positions` and
    /// direction angles in `theta` x `phi` (closed ranges, radians; theta
    /// may wrap: `theta.0 > theta.1` means `[theta.0, pi] u [-pi,
    /// theta.1]`), written into `out` (cleared first).
    pub fn query_range(
        &self,
        positions: &Aabb,
        theta: (f32, f32),
        phi: (f32, f32),
        out: &mut ObjectSet,
    ) {
        out.clear();
        if theta.0 <= theta.1 {
            self.accumulate(positions, theta, phi, out);
        } else {
            self.accumulate(positions, (theta.0, PI), phi, out);
            self.accumulate(positions, (-PI, theta.1), phi, out);
        }
    }

    /// The objects visible from `view`, written into `out` (cleared first).
    pub fn query_view(&self, view: &View, out: &mut ObjectSet) {
        out.clear();
        let r = view.radius.max(0.0);
        let positions = Aabb::new(
            view.position - Vec3::splat(r),
            view.position + Vec3::splat(r),
        );
        let ranges = frustum_angles(view.dir, view.up, view.fov_x, view.fov_y);
        for &(t0, t1, p0, p1) in ranges.boxes() {
            self.accumulate(&positions, (t0, t1), (p0, p1), out);
        }
    }

    /// Adds the objects of the range to `out`.
    fn accumulate(
        &self,
        positions: &Aabb,
        theta: (f32, f32),
        phi: (f32, f32),
        out: &mut ObjectSet,
    ) {
        let space = self.root.space();
        let inside = positions.min.cmpge(space.min).all() && positions.max.cmple(space.max).all();
        if !inside || !positions.min.is_finite() || !positions.max.is_finite() {
            // Outside the view box: nothing was sampled, cull nothing.
            for o in 0..self.objects.len() {
                out.insert(o);
            }
            return;
        }
        let range = Cell {
            lo: [
                positions.min.x,
                positions.min.y,
                positions.min.z,
                theta.0,
                phi.0,
            ],
            hi: [
                positions.max.x,
                positions.max.y,
                positions.max.z,
                theta.1,
                phi.1,
            ],
        };
        self.visit(0, self.root, &range, out);
    }

    fn visit(&self, i: usize, cell: Cell, range: &Cell, out: &mut ObjectSet) {
        let n = self.nodes[i];
        let covered = (0..DIMS).all(|d| range.lo[d] <= cell.lo[d] && range.hi[d] >= cell.hi[d]);
        if n.dim == LEAF || covered {
            out.union_words(self.set_words(i));
            return;
        }
        let d = n.dim as usize;
        let (below, above) = cell.split(d, n.value);
        if range.lo[d] < n.value {
            self.visit(i + 1, below, range, out);
        }
        if range.hi[d] >= n.value {
            self.visit(n.above as usize, above, range, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::cell::{angles_to_direction, direction_to_angles};
    use std::f32::consts::FRAC_PI_2;

    /// Every direction of the frustum (a dense grid over it) lies in one
    /// of the boxes.
    fn check_frustum(dir: Vec3, up: Vec3, fx: f32, fy: f32) {
        let ranges = frustum_angles(dir, up, fx, fy);
        let f = dir.normalize();
        let mut r = f.cross(up).normalize_or_zero();
        if r == Vec3::ZERO {
            r = f.any_orthonormal_vector();
        }
        let u = r.cross(f);
        let n = 40;
        for i in 0..=n {
            for j in 0..=n {
                let x = (i as f32 / n as f32 * 2.0 - 1.0) * (fx * 0.5).tan();
                let y = (j as f32 / n as f32 * 2.0 - 1.0) * (fy * 0.5).tan();
                let d = f + r * x + u * y;
                let (t, p) = direction_to_angles(d);
                let hit = ranges
                    .boxes()
                    .iter()
                    .any(|&(t0, t1, p0, p1)| t >= t0 && t <= t1 && p >= p0 && p <= p1);
                assert!(
                    hit,
                    "dir {dir} fov {fx} {fy}: ({t}, {p}) outside {:?}",
                    ranges.boxes()
                );
            }
        }
    }

    #[test]
    fn frustum_boxes_contain_the_frustum() {
        let fov = 90f32.to_radians();
        for (dir, up) in [
            (Vec3::X, Vec3::Z),
            (-Vec3::X, Vec3::Z), // theta wraps at +-pi
            (Vec3::new(-1.0, 0.01, 0.2), Vec3::Z),
            (Vec3::Z, Vec3::Y),                  // the north pole inside
            (-Vec3::Z, Vec3::Y),                 // the south pole inside
            (Vec3::new(1.0, 0.0, 1.2), Vec3::Z), // near the pole, outside
            (Vec3::new(0.3, -0.8, -0.5), Vec3::Z),
        ] {
            check_frustum(dir, up, fov, fov);
            check_frustum(dir, up, 120f32.to_radians(), 30f32.to_radians());
            check_frustum(dir, up, 1f32.to_radians(), 1f32.to_radians());
        }
        for k in 0..200 {
            let t = -PI + (k as f32 * 0.618_034).fract() * TAU;
            let p = (k as f32 * 0.414_213_6).fract() * PI;
            check_frustum(angles_to_direction(t, p), Vec3::Z, 1.2, 0.9);
        }
    }

    #[test]
    fn frustum_boxes_are_tight_where_easy() {
        let r = frustum_angles(Vec3::X, Vec3::Z, FRAC_PI_2, FRAC_PI_2);
        assert_eq!(r.boxes().len(), 1);
        let (t0, t1, p0, p1) = r.boxes()[0];
        assert!(
            (t0 + PI / 4.0).abs() < 1e-3 && (t1 - PI / 4.0).abs() < 1e-3,
            "{t0} {t1}"
        );
        assert!(
            (p0 - PI / 4.0).abs() < 1e-3 && (p1 - 3.0 * PI / 4.0).abs() < 1e-3,
            "{p0} {p1}"
        );
        let r = frustum_angles(-Vec3::X, Vec3::Z, FRAC_PI_2, FRAC_PI_2);
        assert_eq!(r.boxes().len(), 2, "looking along -x crosses theta = pi");
        let r = frustum_angles(Vec3::Z, Vec3::Y, FRAC_PI_2, FRAC_PI_2);
        assert_eq!(r.boxes()[0].0, -PI);
        assert_eq!(r.boxes()[0].2, 0.0);
        assert_eq!(
            frustum_angles(Vec3::ZERO, Vec3::Z, 1.0, 1.0).boxes()[0],
            (-PI, PI, 0.0, PI)
        );
        assert_eq!(
            frustum_angles(Vec3::X, Vec3::Z, 4.0, 1.0).boxes()[0],
            (-PI, PI, 0.0, PI)
        );
    }
}
