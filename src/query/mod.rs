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
//! The loaded tree keeps its sets coded, as the file's third coding codes
//! them, and a query decodes the sets on its way down (`query_tree`): the
//! loaded file takes 1.15 to 1.8 times its size in memory on the scenes
//! measured ([`Pvs::memory_bytes`], notes/query.md).
//!
//! Queries allocate nothing: the answer goes into an [`ObjectSet`] made once
//! with [`Pvs::new_set`], and the sets on the walk's path into scratch that
//! each thread makes at its first query (two sets per level of the tree,
//! at most [`crate::tree::MAX_DEPTH`] levels).
//!
//! Conservative by construction where the tree is: positions outside the
//! view box the tree was built for get every object (nothing was sampled
//! there, so nothing may be culled; but an object of no triangles, an
//! empty group of the model, which is never visible).
//!
//! Positions are in the tree's frame ([`Pvs::frame`],
//! [`crate::geom::Frame`]): for a scene modelled around the origin (within
//! 4 of its diagonals of it) that is world coordinates, unchanged. A scene
//! far from the origin (a city in UTM coordinates) is built relative to an
//! origin near it, because f32 world coordinates cannot resolve it (at
//! 4.6e6 they step by 0.5); [`Pvs::query_view`] and [`Pvs::query_range`]
//! then take positions relative to [`Pvs::frame`]'s origin (what a
//! renderer drawing such a scene in f32 holds anyway), and
//! [`Pvs::query_view_world`] and [`Pvs::query_range_world`] take f64 world
//! positions and convert them, rounding the box of positions outwards.
//!
//! The frame also turns the axes when the tree was built for a scene whose
//! up axis is not +z (`vis5d build --up y`): local z is the scene's up.
//! The `_world` queries take world directions too and turn them; the
//! others take directions, like positions, in the tree's frame
//! ([`Frame::dir_to_local`]), and angle ranges are always about local z
//! (phi from the up axis).
//!
//! Views: [`View::look`] (eye, forward, up, vertical field of view and
//! aspect ratio, as engines give cameras), [`View::from_view_projection`]
//! (the matrix an engine draws with: OpenGL, Vulkan or Direct3D depth,
//! right- or left-handed) or [`View::square`].

use std::f32::consts::PI;
use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3, DVec4, Mat4, Vec3};

use crate::bitset::ObjectSet;
use crate::codec::{CodecError, Coding, ReadLimits, read_file};
use crate::geom::cell::{Cell, DIMS};
use crate::geom::{Aabb, Frame, trig};
use crate::slices::TreeSlices;

mod query_cull;
mod query_objects;
mod query_prefetch;
mod query_tree;
mod query_triangles;

pub use query_objects::ObjectInfo;
use query_objects::ObjectTable;
use query_tree::CodedTree;

pub use query_prefetch::Delta;
pub use query_triangles::ObjectTriangles;

/// Why a `.v5d` file cannot be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PvsError {
    /// The file cannot be read.
    // Note: the causes are in the messages, not `source()`s, so that a
    // chain printed whole (`anyhow`'s `{:#}`) says them once.
    #[error("{}: cannot read the .v5d file: {cause}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// The file is not a valid `.v5d` file.
    #[error("{}: {cause}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        cause: CodecError,
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

/// How a query was answered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[non_exhaustive]
pub enum Answer {
    /// From the tree: the union of the leaf sets the query meets.
    Tree,
    /// Every object (but those of no triangles, never visible; culled to
    /// the frustum, for a view): some position of
    /// the query lies outside the view box the tree was built for
    /// ([`Pvs::view_box`]), where nothing was sampled and nothing may be
    /// culled, or the query held a NaN. The conservative answer.
    Everything,
}

/// An answer set of another size than the file's object count: make sets
/// with [`Pvs::new_set`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "the answer set holds {got} objects but the .v5d file's answers {expected}: make it with Pvs::new_set"
)]
pub struct SetSizeError {
    /// The set's capacity (for raw words, 64 a word).
    pub got: usize,
    /// The file's object count (for raw words, 64 times
    /// [`Pvs::answer_words`]).
    pub expected: usize,
}

/// A camera: a position (or a small box around it) and a frustum.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
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
    /// A camera as engines give it: from `eye` looking along `forward`,
    /// `up` its up direction (need not be orthogonal to `forward`),
    /// `vfov` its vertical field of view in radians and `aspect` its
    /// width over its height (the horizontal field of view is `2
    /// atan(aspect tan(vfov / 2))`).
    pub fn look(eye: Vec3, forward: Vec3, up: Vec3, vfov: f32, aspect: f32) -> Self {
        let half = (0.5 * f64::from(vfov)).tan();
        Self {
            position: eye,
            radius: 0.0,
            dir: forward,
            up,
            fov_x: (2.0 * (f64::from(aspect) * half).atan()) as f32,
            fov_y: vfov,
        }
    }

    /// The view a perspective view-projection matrix draws (`clip = m *
    /// world`, column vectors, glam's column-major [`Mat4`]): any depth
    /// convention (OpenGL's -1..1, Vulkan's and Direct3D's 0..1, reversed
    /// or infinite), right- or left-handed, y up or down, and off-centre
    /// projections (VR, jittered): a symmetric frustum around the ray
    /// through the middle of the image, just wide enough to hold the four
    /// edge rays of the matrix's (whatever its near and far planes:
    /// objects beyond the far plane are kept).
    /// `None` for a matrix that is not a perspective projection (no eye,
    /// an orthographic one, not finite) or whose frustum no symmetric one
    /// under 180 degrees holds.
    pub fn from_view_projection(m: Mat4) -> Option<Self> {
        let m = m.as_dmat4();
        let (r0, r1, r3) = (m.row(0), m.row(1), m.row(3));
        // The eye: where clip x, y and w are all 0.
        let a = DMat3::from_cols(r0.truncate(), r1.truncate(), r3.truncate()).transpose();
        let b = -DVec3::new(r0.w, r1.w, r3.w);
        let det = a.determinant().abs();
        let scale: f64 = a.to_cols_array().iter().map(|v| v.abs()).sum();
        if det.is_nan() || det <= 1e-12 * scale.powi(3) {
            return None;
        }
        let eye = a.inverse() * b;
        let inv = m.inverse();
        // The four edge rays: through clip (+-1, +-1) at a depth inside
        // every convention's range, unprojected.
        let mut corners = [DVec3::ZERO; 4];
        let mut centre = DVec3::ZERO;
        for (k, (x, y)) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .into_iter()
            .enumerate()
        {
            let q = inv * DVec4::new(x, y, 0.5, 1.0);
            if q.w == 0.0 || q.w.is_nan() {
                return None;
            }
            let d = q.truncate() / q.w - eye;
            // In front of the eye: w = r3 . (p, 1) grows along it.
            let ahead = r3.truncate().dot(d);
            if ahead.is_nan() || ahead <= 0.0 {
                return None;
            }
            corners[k] = d.normalize();
            centre += 0.25 * d;
        }
        if !(eye.is_finite() && corners.iter().all(|c| c.is_finite())) {
            return None;
        }
        // The axis: through the middle of the image rectangle (the corners
        // lie on a plane of constant depth), which an off-centre frustum's
        // principal ray is not.
        let f = centre.normalize();
        let up0 = (corners[2] + corners[3]) - (corners[0] + corners[1]);
        let u = (up0 - f * up0.dot(f)).normalize();
        let r = f.cross(u);
        if !(u.is_finite() && r.is_finite()) {
            return None;
        }
        let (mut tx, mut ty) = (0.0f64, 0.0f64);
        for c in corners {
            let z = c.dot(f);
            if z.is_nan() || z <= 0.0 {
                return None;
            }
            tx = tx.max(c.dot(r).abs() / z);
            ty = ty.max(c.dot(u).abs() / z);
        }
        // Rounded up: the f32 angles still hold every edge ray.
        let fov = |t: f64| ((2.0 * t.atan()) * (1.0 + 1e-6) + 1e-6) as f32;
        let (fov_x, fov_y) = (fov(tx), fov(ty));
        if !(fov_x < PI && fov_y < PI) {
            return None;
        }
        Some(Self {
            position: eye.as_vec3(),
            radius: 0.0,
            dir: f.as_vec3(),
            up: u.as_vec3(),
            fov_x,
            fov_y,
        })
    }

    /// The box of eyes: `position`, `radius` around it (in the view's
    /// own coordinates).
    pub(crate) fn eyes(&self) -> Aabb {
        let r = Vec3::splat(self.radius.max(0.0));
        Aabb::new(self.position - r, self.position + r)
    }

    /// The same view with its position, direction and up turned from world
    /// coordinates into `frame`'s (the eye at the nearest local point).
    pub fn to_local(&self, frame: &Frame, eye: DVec3) -> Self {
        Self {
            position: frame.to_local(eye),
            dir: frame.dir_to_local(self.dir),
            up: frame.dir_to_local(self.up),
            ..*self
        }
    }

    /// A view with a square field of view of `fov_degrees`, up = +z (+y
    /// when `dir` is vertical), from the point `position`. Its roll is
    /// that of a +z-up camera: an engine whose up is another axis, or
    /// whose viewport is not square, gives its own up with [`View::look`]
    /// (a square frustum rolled by another angle than a right one is
    /// another frustum).
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

/// A view's frustum as inward planes, to cull an answer to what the view
/// can show: an object whose bounding box lies wholly outside one plane is
/// not drawn by the view whatever the tree says.
///
/// Built for a box of eye positions, it is the union of the frusta of
/// every eye in the box (each plane moved back to the box's corner
/// furthest behind it), so culling with it is conservative for all of
/// them. A box is kept unless it is outside a plane by more than
/// [`Frustum::ANGLE_SLACK`] times its distance from the eye (plus f32
/// rounding): a renderer's own f32 frame may be rolled or tilted by that
/// much. When the view's roll is ill-conditioned (`up` within
/// [`Frustum::MIN_UP_ANGLE`] of `dir`, where a renderer's f32 cross
/// product rolls its frame by up to 1e-5) only the eye's plane culls; a
/// field of view above 170 degrees culls nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// `(n, d)`: a point `p` may be seen only where `n . p >= d`.
    planes: [(Vec3, f32); 5],
    /// Per plane, the eye of the box it was moved back to.
    eyes: [Vec3; 5],
    /// How many of `planes` are used.
    count: usize,
}

impl Frustum {
    /// The angle (radians) by which a plane may be off without an object
    /// near it being culled. A review found `render::Camera` rolled by
    /// 6e-5 against the exact frame with `up` 1e-3 rad from `dir`.
    pub const ANGLE_SLACK: f32 = 1e-4;

    /// Below this angle (radians) between `up` and `dir`, the side planes
    /// are not used.
    pub const MIN_UP_ANGLE: f64 = 1e-2;

    /// The frustum of `view` from every eye in `eyes` (in the coordinates
    /// of the boxes it will test).
    pub fn new(view: &View, eyes: &Aabb) -> Frustum {
        Frustum::in_frame(
            &ViewFrame::new(view.dir, view.up, view.fov_x, view.fov_y),
            eyes,
        )
    }

    /// [`Frustum::new`] with the view's frame made already.
    fn in_frame(frame: &ViewFrame, eyes: &Aabb) -> Frustum {
        let none = Frustum {
            planes: [(Vec3::ZERO, 0.0); 5],
            eyes: [Vec3::ZERO; 5],
            count: 0,
        };
        let fovs_ok = frame.fov_x >= 0.0
            && frame.fov_y >= 0.0
            && frame.fov_x.max(frame.fov_y) <= 170f32.to_radians();
        if !(frame.dir_ok && fovs_ok && eyes.min.is_finite() && eyes.max.is_finite()) {
            return none;
        }
        let f = frame.f;
        let mut normals = [f; 5];
        let mut used = 1;
        let r0 = frame.r0;
        if r0.length() > Self::MIN_UP_ANGLE.sin() * frame.up.length() && r0.length().is_finite() {
            let (r, u, tx, ty) = (frame.r, frame.u, frame.tx, frame.ty);
            normals[1..].copy_from_slice(&[
                (f - r * tx).cross(u),
                u.cross(f + r * tx),
                (f + u * ty).cross(r),
                r.cross(f - u * ty),
            ]);
            used = 5;
        }
        let mut out = none;
        for n in &normals[..used] {
            let n = n.normalize().as_vec3();
            // The eye of the box furthest behind the plane.
            let e = Vec3::select(n.cmpge(Vec3::ZERO), eyes.min, eyes.max);
            out.planes[out.count] = (n, n.dot(e));
            out.eyes[out.count] = e;
            out.count += 1;
        }
        out
    }

    /// Whether some point of the box `b` may be in the frustum: false only
    /// when all of it is outside one plane by more than the slack.
    /// (Queries cull with a faster form of the same test that keeps every
    /// box this keeps: `query_cull`.)
    pub fn may_see(&self, b: &Aabb) -> bool {
        if b.is_empty() {
            // The box of no triangles: nothing to see.
            return false;
        }
        self.planes[..self.count]
            .iter()
            .zip(&self.eyes)
            .all(|(&(n, d), &e)| {
                let p = Vec3::select(n.cmpge(Vec3::ZERO), b.max, b.min);
                let along = n.dot(p);
                if along >= d {
                    return true;
                }
                // Outside, but maybe by less than the slack: the box's
                // farthest point from the eye moves most when the plane
                // turns.
                let far = (b.min - e).abs().max((b.max - e).abs()).length();
                let slack = Self::ANGLE_SLACK * far + 1e-6 * (1.0 + d.abs() + along.abs());
                along >= d - slack
            })
    }
}

/// Angular boxes that contain every direction of the frustum looking along
/// `dir` with `up`, `fov_x` by `fov_y` radians: one box, or two when the
/// theta range crosses +-pi. A frustum containing (or passing within 0.01
/// rad of) a pole covers every theta. Bounds are padded by 1e-4 rad (theta's
/// by 1.02e-4, phi's by 1.00001e-4: see the code).
///
/// The frustum's directions are a spherical quadrilateral. Theta is
/// monotone along any great-circle arc that misses the poles, so the theta
/// range is found by walking the four edges and unwrapping; phi's extremes
/// are at the corners, at the highest or lowest point of an edge's great
/// circle when it falls on the edge, or at a pole inside. Computed in f64.
/// When the frame is ill-defined (`up` within 1e-3 rad of `dir`) or the
/// frustum nearly flat (a field of view above 170 degrees), the answer is
/// the cone around `dir` that holds the frustum whatever its roll.
pub fn frustum_angles(dir: Vec3, up: Vec3, fov_x: f32, fov_y: f32) -> AngularRanges {
    frustum_angles_in(&ViewFrame::new(dir, up, fov_x, fov_y))
}

/// A view's frame in f64, made once for [`frustum_angles`] and
/// [`Frustum::new`]: the unit forward axis `f`, `r0 = f x up`, the right
/// and up axes `r` and `u` (meaningful only where `r0` is not too short:
/// each user checks it), and the tangents of the half fields of view.
struct ViewFrame {
    /// Whether `dir` has a finite, non-zero length.
    dir_ok: bool,
    f: DVec3,
    up: DVec3,
    r0: DVec3,
    r: DVec3,
    u: DVec3,
    fov_x: f32,
    fov_y: f32,
    tx: f64,
    ty: f64,
}

impl ViewFrame {
    fn new(dir: Vec3, up: Vec3, fov_x: f32, fov_y: f32) -> ViewFrame {
        let f = dir.as_dvec3();
        let len = f.length();
        let f = f / len;
        let up = up.as_dvec3();
        let r0 = f.cross(up);
        let r = (r0 - f * r0.dot(f)).normalize();
        ViewFrame {
            dir_ok: len > 0.0 && len.is_finite(),
            f,
            up,
            r0,
            r,
            u: r.cross(f),
            fov_x,
            fov_y,
            tx: (f64::from(fov_x) * 0.5).tan(),
            ty: (f64::from(fov_y) * 0.5).tan(),
        }
    }
}

/// [`frustum_angles`] of a view's frame.
fn frustum_angles_in(frame: &ViewFrame) -> AngularRanges {
    let full = AngularRanges::one((-PI, PI, 0.0, PI));
    let (fov_x, fov_y) = (frame.fov_x, frame.fov_y);
    if !(frame.dir_ok && fov_x >= 0.0 && fov_y >= 0.0) || fov_x >= PI || fov_y >= PI {
        return full;
    }
    let (f, tx, ty, r0) = (frame.f, frame.tx, frame.ty, frame.r0);
    let flat = fov_x.max(fov_y) as f64 > 170f64.to_radians();
    let degenerate = r0.length() <= 1e-3 * frame.up.length() || r0.length().is_nan();
    if degenerate || flat {
        return cone_angles(f, tx.hypot(ty).atan());
    }
    let (r, u) = (frame.r, frame.u);
    // The corners' directions, all of length sqrt(1 + tx^2 + ty^2) in the
    // orthonormal frame: their unit z is their z over it.
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(sx, sy)| f + r * (sx * tx) + u * (sy * ty));
    let inv_len = 1.0 / (1.0 + tx * tx + ty * ty).sqrt();
    // A pole inside, or on the boundary to within the padding.
    let inside = |v: DVec3| {
        let z = v.dot(f);
        z > 0.0
            && v.dot(r).abs() <= (tx + PAD * (1.0 + tx * tx)) * z
            && v.dot(u).abs() <= (ty + PAD * (1.0 + ty * ty)) * z
    };
    let (north, south) = (inside(DVec3::Z), inside(-DVec3::Z));
    // The z range of the unit directions (phi = acos z is monotone; acos is
    // accurate to ~1e-8 rad in f64 even next to the poles).
    let mut zmin = corners
        .iter()
        .map(|c| c.z * inv_len)
        .fold(f64::INFINITY, f64::min);
    let mut zmax = corners
        .iter()
        .map(|c| c.z * inv_len)
        .fold(f64::NEG_INFINITY, f64::max);
    // The edges' great circles, their planes from the frame (not from the
    // corners, which lose precision for wide views): x = +-tx (vertical
    // edges, spanned by f + r x and u, normal (f + r x) x u = r - x f) and
    // y = +-ty (spanned by f + u y and r, normal (f + u y) x r = y f - u),
    // of lengths sqrt(1 + x^2) and sqrt(1 + y^2); a circle's highest and
    // lowest points, +-m / |m| with m = Z - n n.z (n the unit normal),
    // count if they lie on the edge: in front (p . f > 0, so only one of
    // the two) and within its half-width (both tests free of |m|).
    let (len_x, len_y) = ((1.0 + tx * tx).sqrt(), (1.0 + ty * ty).sqrt());
    for s in [-1.0, 1.0] {
        let edges = [
            (r - f * (s * tx), len_x, u, ty),
            (f * (s * ty) - u, len_y, r, tx),
        ];
        for (n, len, along, half) in edges {
            let m = DVec3::Z - n * (n.z / (len * len));
            let m_len = m.length();
            let front = m.dot(f);
            if m_len < 1e-12 || front == 0.0 || m.dot(along).abs() > half * front.abs() {
                continue;
            }
            let z = if front > 0.0 { m.z } else { -m.z } / m_len;
            zmin = zmin.min(z);
            zmax = zmax.max(z);
        }
    }
    if north {
        zmax = 1.0;
    }
    if south {
        zmin = -1.0;
    }
    // PHI_PAD more: the closed forms above round otherwise than the
    // normalisations they replace (by 3e-11 rad at most, in a review's
    // 300,000 frames), and no answer may lack an object theirs had.
    let (p0, p1) = (
        zmax.clamp(-1.0, 1.0).acos() - PAD - PHI_PAD,
        zmin.clamp(-1.0, 1.0).acos() + PAD + PHI_PAD,
    );
    if north || south || p0 < POLE_GUARD || p1 > std::f64::consts::PI - POLE_GUARD {
        return AngularRanges::one((-PI, PI, (p0.max(0.0)) as f32, (p1 as f32).min(PI)));
    }
    // Theta: unwrap along the edges. The corners' angles in f32 (the
    // project's atan2, within 3e-7 rad, on coordinates rounded by 6e-8 of
    // themselves; near a pole, where theta is ill-conditioned, the answer
    // above took every theta), padded by THETA_PAD more: the bounds hold
    // those of libm's f64 atan2 (rounding to f32 is monotone), so no
    // answer lacks an object that answer had.
    let th = trig::atan2(corners.map(|c| c.y as f32), corners.map(|c| c.x as f32)).map(f64::from);
    let mut t = th[0];
    let (mut tmin, mut tmax) = (t, t);
    for k in 1..4 {
        t += wrap(th[k] - th[k - 1]);
        tmin = tmin.min(t);
        tmax = tmax.max(t);
    }
    theta_boxes(tmin - PAD - THETA_PAD, tmax + PAD + THETA_PAD, p0, p1)
}

/// Padding of the angular bounds, radians.
const PAD: f64 = 1e-4;

/// More padding of a frustum's theta bounds, radians: four times what its
/// f32 `atan2` may be off by ([`frustum_angles`]).
const THETA_PAD: f64 = 2e-6;

/// More padding of a frustum's phi bounds, radians ([`frustum_angles`]).
const PHI_PAD: f64 = 1e-9;

/// How close to a pole a view may come before its theta range is taken as
/// all of it (theta is ill-conditioned there).
const POLE_GUARD: f64 = 0.01;

/// `d` wrapped into (-pi, pi].
fn wrap(d: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if d > PI {
        d - TAU
    } else if d <= -PI {
        d + TAU
    } else {
        d
    }
}

/// The boxes of the unwrapped theta range `[t0, t1]` (any span under 2 pi)
/// times `[p0, p1]`.
fn theta_boxes(t0: f64, t1: f64, p0: f64, p1: f64) -> AngularRanges {
    use std::f64::consts::{PI, TAU};
    let (p0, p1) = (p0.max(0.0) as f32, (p1 as f32).min(std::f32::consts::PI));
    let c = |t: f64| t as f32;
    if t1 - t0 >= TAU {
        AngularRanges::one((-std::f32::consts::PI, std::f32::consts::PI, p0, p1))
    } else if t0 < -PI {
        AngularRanges {
            boxes: [
                (c(t0 + TAU), std::f32::consts::PI, p0, p1),
                (-std::f32::consts::PI, c(t1), p0, p1),
            ],
            count: 2,
        }
    } else if t1 > PI {
        AngularRanges {
            boxes: [
                (-std::f32::consts::PI, c(t1 - TAU), p0, p1),
                (c(t0), std::f32::consts::PI, p0, p1),
            ],
            count: 2,
        }
    } else {
        AngularRanges::one((c(t0), c(t1), p0, p1))
    }
}

/// The boxes around the cone of directions within `half` radians of the
/// unit vector `f`: phi within `half` of f's, theta within
/// `asin(sin half / sin phi)` of f's (the widest a spherical cap reaches in
/// longitude), every theta when the cap reaches a pole.
fn cone_angles(f: DVec3, half: f64) -> AngularRanges {
    let phi_f = f.x.hypot(f.y).atan2(f.z);
    let (p0, p1) = (phi_f - half - PAD, phi_f + half + PAD);
    if p0 < POLE_GUARD || p1 > std::f64::consts::PI - POLE_GUARD {
        return AngularRanges::one((-PI, PI, p0.max(0.0) as f32, (p1 as f32).min(PI)));
    }
    let w = (half.sin() / phi_f.sin()).min(1.0).asin();
    let t = f.y.atan2(f.x);
    theta_boxes(t - w - PAD, t + w + PAD, p0, p1)
}

/// A loaded `.v5d` file, ready for queries.
///
/// # What an engine uses
///
/// - [`Pvs::load`] or [`Pvs::from_bytes`], once;
/// - [`Pvs::new_set`] (and [`Pvs::new_delta`]), once: the answers it
///   writes into, reused every frame;
/// - [`Pvs::query_view_world`] (or [`Pvs::query_view`] with positions in
///   the tree's frame) for each camera ([`View::look`] or
///   [`View::from_view_projection`]): no allocation, under a microsecond
///   on scenes of a few hundred objects, a few on a city of thousands
///   (notes/query.md);
/// - [`Pvs::delta`]: the objects entering and leaving since last frame;
///   [`Pvs::query_positions_world`]: what to stream in for a region;
/// - [`Pvs::object`]: an object's id, name, triangle count and flags.
///
/// These are re-exported at the crate's root ([`crate::Pvs`],
/// [`crate::View`], ...). The rest serves tools and bindings: range
/// queries over angles, raw-word answers (the C API), slices' triangle
/// ranges, the file's parameters, coding and size.
///
/// Memory: the sets stay coded (`query_tree`), 1.15 to 1.8 times the
/// file's size in all on the scenes measured ([`Pvs::memory_bytes`],
/// notes/query.md); each thread that
/// queries keeps scratch for the sets on one path of the tree, made by
/// its first query.
#[derive(Clone, Debug)]
pub struct Pvs {
    coding: Coding,
    fingerprint: u64,
    frame: Frame,
    params: String,
    objects: ObjectTable,
    root: Cell,
    /// The splits and the coded sets (`query_tree`).
    tree: CodedTree,
    /// The leaves' hidden slices, when the file has them (version 4).
    slices: Option<TreeSlices>,
    /// Every object's bit: the answer outside the view box.
    all: Vec<u64>,
}

impl Pvs {
    /// Loads and checks the `.v5d` file at `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<Pvs, PvsError> {
        let path = path.as_ref();
        let limit = ReadLimits::default().max_file_bytes;
        let bytes = crate::input::read_regular(path, limit).map_err(|cause| PvsError::Io {
            path: path.to_owned(),
            cause,
        })?;
        Pvs::from_bytes(&bytes).map_err(|cause| PvsError::File {
            path: path.to_owned(),
            cause,
        })
    }

    /// Decodes and checks a `.v5d` file held in memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<Pvs, CodecError> {
        // The decoded tree and the coded copy made of it below coexist for
        // a while: each gets half of the documented budget, so that a
        // crafted file cannot make a load cost twice the budget.
        let budget = ReadLimits::default();
        let limits = ReadLimits {
            max_decoded_bytes: budget.max_decoded_bytes / 2,
            ..budget
        };
        let file = read_file(bytes, limits)?;
        let slices = file.slices;
        let tree = file.tree;
        let (root, grid_bits) = (tree.root_cell(), tree.grid_bits());
        let n_objects = tree.object_count();
        let objects = ObjectTable::new(&file.objects)
            .ok_or_else(|| CodecError::TooLarge("the names and ids pass 4 GiB".into()))?;
        // The leaf records stay in the file: they tell how sure a leaf's
        // set is (`vis5d stat`, `VisTree::leaf_records`), which no query
        // needs.
        let (tree_nodes, _records) = tree.into_parts();
        let coded = CodedTree::new(root, grid_bits, n_objects, &tree_nodes)?;
        drop(tree_nodes);
        // Every object that has triangles: one without (an empty group of
        // the model) is never visible.
        let mut all = ObjectSet::full(n_objects);
        for (i, o) in file.objects.iter().enumerate() {
            if o.triangles == 0 {
                all.remove(i);
            }
        }
        let all = all.words().to_vec();
        Ok(Pvs {
            coding: file.coding,
            fingerprint: file.fingerprint,
            frame: file.frame,
            params: file.params,
            objects,
            root,
            tree: coded,
            slices,
            all,
        })
    }

    /// The objects, in scene order (bit i of an answer is the i-th):
    /// names, ids, triangle counts, bounds, flags.
    pub fn objects(&self) -> impl ExactSizeIterator<Item = ObjectInfo<'_>> + '_ {
        (0..self.objects.len()).map(|i| self.objects.at(i))
    }

    /// Object `object` (bit `object` of an answer); `None` past the last.
    pub fn object(&self, object: usize) -> Option<ObjectInfo<'_>> {
        self.objects.get(object)
    }

    /// The object whose id is `id` ([`ObjectInfo::id`]: its name, or
    /// `name#k` where names repeat, or the id given at build time), by
    /// binary search; `None` when no object has it.
    pub fn object_index(&self, id: &str) -> Option<usize> {
        self.objects.index(id)
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

    /// Whether the tree is conservative (`vis5d build --conservative`:
    /// every set holds every object some ray of its cell can see, by the
    /// extended-projection oracle) rather than sampled (`vis5d build`: each
    /// object tested by rays, an object seen from a small part of a cell
    /// may be missed). Read from the file's parameters
    /// ([`crate::codec::METHOD_KEY`]).
    pub fn is_conservative(&self) -> bool {
        crate::codec::params_say_conservative(&self.params)
    }

    /// The coding the file used.
    pub fn coding(&self) -> Coding {
        self.coding
    }

    /// Where the tree's local coordinates sit in the world (the identity
    /// for a scene built near the origin).
    pub fn frame(&self) -> Frame {
        self.frame
    }

    /// The root cell: the view box times all directions, in local
    /// coordinates ([`Pvs::frame`]).
    pub fn root_cell(&self) -> Cell {
        self.root
    }

    /// The number of tree nodes.
    pub fn node_count(&self) -> usize {
        self.tree.node_count()
    }

    /// The bytes the loaded file takes in memory: the struct and every
    /// vector it holds (by capacity), names included. What an engine
    /// budgets for; notes/query.md compares it with the files' sizes.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        size_of::<Self>()
            + self.params.capacity()
            + self.objects.memory_bytes()
            + self.tree.memory_bytes()
            + self.slices.as_ref().map_or(0, TreeSlices::memory_bytes)
            + self.all.capacity() * 8
    }

    /// An empty answer set of the right size, to reuse across queries.
    pub fn new_set(&self) -> ObjectSet {
        ObjectSet::new(self.objects.len())
    }

    /// The set of the leaf holding the ray point `p` = (x, y, z, theta,
    /// phi), local coordinates, into `out` (bit i = object i), and
    /// [`Answer::Tree`]; every object with triangles and
    /// [`Answer::Everything`] for a
    /// point outside the view box ([`Pvs::view_box`]), a direction's
    /// angles outside their ranges or a NaN. An error, `out` untouched,
    /// when `out` is not of the file's size.
    pub fn leaf_set(&self, p: [f32; DIMS], out: &mut ObjectSet) -> Result<Answer, SetSizeError> {
        self.check_set(out)?;
        Ok(self.leaf_into(p, out.words_mut()))
    }

    /// The leaf holding the ray point `p` = (x, y, z, theta, phi), local
    /// coordinates (a point on a split value goes above, as queries do):
    /// its rank in the tree's preorder (a stable id for this file) and its
    /// cell. `None` outside the view box or for a NaN, where no leaf
    /// answers ([`Answer::Everything`]).
    pub fn leaf_at(&self, p: [f32; DIMS]) -> Option<(u32, Cell)> {
        self.holds(p).then(|| self.tree.leaf_cell(p, None))
    }

    /// [`Pvs::leaf_set`] into words of the file's size.
    fn leaf_into(&self, p: [f32; DIMS], out: &mut [u64]) -> Answer {
        if self.holds(p) {
            self.tree.leaf(p, Some(out));
            Answer::Tree
        } else {
            out.copy_from_slice(&self.all);
            Answer::Everything
        }
    }

    /// The box of eye positions the tree was built for (local
    /// coordinates): queries from outside it answer every object.
    pub fn view_box(&self) -> Aabb {
        self.root.space()
    }

    /// Whether the ray point `p` lies in the root cell (NaN: no).
    fn holds(&self, p: [f32; DIMS]) -> bool {
        (0..DIMS).all(|d| p[d] >= self.root.lo[d] && p[d] <= self.root.hi[d])
    }

    /// `Ok` when `out` has one bit per object of the file.
    fn check_set(&self, out: &ObjectSet) -> Result<(), SetSizeError> {
        if out.capacity() == self.objects.len() {
            Ok(())
        } else {
            Err(SetSizeError {
                got: out.capacity(),
                expected: self.objects.len(),
            })
        }
    }

    /// As [`Pvs::query_range`], with the box of positions `[min, max]` in
    /// f64 world coordinates (rounded outwards into the tree's frame).
    ///
    /// The angles are about the tree's up axis ([`Frame::up`]: phi from
    /// it, theta about it from the axis after it, cyclically: from world x
    /// for a Z-up tree, from world z for a Y-up one).
    pub fn query_range_world(
        &self,
        min: DVec3,
        max: DVec3,
        theta: (f32, f32),
        phi: (f32, f32),
        out: &mut ObjectSet,
    ) -> Result<Answer, SetSizeError> {
        let local = self.frame.box_to_local(min, max);
        self.query_range(&local, theta, phi, out)
    }

    /// The objects visible from some ray with origin in `positions` (the
    /// tree's frame: see the module docs) and direction angles in `theta`
    /// x `phi` (closed ranges, radians; theta may wrap: `theta.0 >
    /// theta.1` means `[theta.0, pi] u [-pi, theta.1]`), written into
    /// `out` (cleared first). [`Answer::Everything`] when `positions`
    /// reach outside the view box or the range holds a NaN; an error,
    /// `out` untouched, when `out` is not of the file's size.
    pub fn query_range(
        &self,
        positions: &Aabb,
        theta: (f32, f32),
        phi: (f32, f32),
        out: &mut ObjectSet,
    ) -> Result<Answer, SetSizeError> {
        self.check_set(out)?;
        Ok(self.range_into(positions, theta, phi, out.words_mut()))
    }

    /// As [`Pvs::query_range`], into the raw words of a bitset of
    /// [`Pvs::answer_words`] words (bit `i % 64` of word `i / 64` is
    /// object `i`): for bindings that own their memory (the C API). An
    /// error, `out` untouched, for another length.
    pub fn query_range_words(
        &self,
        positions: &Aabb,
        theta: (f32, f32),
        phi: (f32, f32),
        out: &mut [u64],
    ) -> Result<Answer, SetSizeError> {
        self.check_words(out)?;
        Ok(self.range_into(positions, theta, phi, out))
    }

    /// The range query into `out` (of the file's size, checked by the
    /// caller).
    fn range_into(
        &self,
        positions: &Aabb,
        theta: (f32, f32),
        phi: (f32, f32),
        out: &mut [u64],
    ) -> Answer {
        out.fill(0);
        if theta.0 <= theta.1 {
            self.accumulate(positions, theta, phi, out)
        } else {
            let a = self.accumulate(positions, (theta.0, PI), phi, out);
            let b = self.accumulate(positions, (-PI, theta.1), phi, out);
            a.max(b)
        }
    }

    /// The number of 64-bit words of an answer's bitset.
    pub fn answer_words(&self) -> usize {
        self.tree.words()
    }

    /// `Ok` when `out` has the words of an answer.
    fn check_words(&self, out: &[u64]) -> Result<(), SetSizeError> {
        if out.len() == self.tree.words() {
            Ok(())
        } else {
            Err(SetSizeError {
                got: out.len() * 64,
                expected: self.tree.words() * 64,
            })
        }
    }

    /// The objects visible from `view` (its position in the tree's frame:
    /// see the module docs), written into `out` (cleared first): the
    /// tree's answer for the view's directions, culled to its frustum with
    /// the objects' bounds ([`Frustum`], each plane's slack taken for the
    /// scene's farthest point from the eye, not the box's: a box outside
    /// a plane by less than 1e-4 times that distance is kept; a version 1
    /// file has no bounds and is not culled). [`Answer::Everything`] (every object in the frustum)
    /// from outside the view box; an error, `out` untouched, when `out` is
    /// not of the file's size.
    pub fn query_view(&self, view: &View, out: &mut ObjectSet) -> Result<Answer, SetSizeError> {
        self.query_view_from(&view.eyes(), view, out)
    }

    /// As [`Pvs::query_view`], with the eye at `eye` in f64 world
    /// coordinates (`view.position` is not used) and the view's directions
    /// in world axes: the box of eyes (`view.radius` around it) is rounded
    /// outwards into the tree's frame, the directions turned into it.
    pub fn query_view_world(
        &self,
        eye: DVec3,
        view: &View,
        out: &mut ObjectSet,
    ) -> Result<Answer, SetSizeError> {
        let (positions, local) = self.local_view(eye, view);
        self.query_view_from(&positions, &local, out)
    }

    /// A world view's box of eyes and the view, in the tree's frame.
    fn local_view(&self, eye: DVec3, view: &View) -> (Aabb, View) {
        let r = DVec3::splat(f64::from(view.radius.max(0.0)));
        let positions = self.frame.box_to_local(eye - r, eye + r);
        (positions, view.to_local(&self.frame, eye))
    }

    /// The objects visible from some eye in the box `positions` looking
    /// into `view`'s frustum (`view.position` and `view.radius` are not
    /// used), both in the tree's frame, written into `out` (cleared
    /// first): as [`Pvs::query_view`] for a box of eyes of any shape.
    pub fn query_view_from(
        &self,
        positions: &Aabb,
        view: &View,
        out: &mut ObjectSet,
    ) -> Result<Answer, SetSizeError> {
        self.check_set(out)?;
        Ok(self.view_into(positions, view, out.words_mut()))
    }

    /// As [`Pvs::query_view_from`], into the raw words of a bitset of
    /// [`Pvs::answer_words`] words (see [`Pvs::query_range_words`]).
    pub fn query_view_from_words(
        &self,
        positions: &Aabb,
        view: &View,
        out: &mut [u64],
    ) -> Result<Answer, SetSizeError> {
        self.check_words(out)?;
        Ok(self.view_into(positions, view, out))
    }

    /// The view query into `out` (of the file's size, checked by the
    /// caller): the leaf sets met, culled to the frustum.
    fn view_into(&self, positions: &Aabb, view: &View, out: &mut [u64]) -> Answer {
        let frame = ViewFrame::new(view.dir, view.up, view.fov_x, view.fov_y);
        let answer = self.ranges_into(positions, &frustum_angles_in(&frame), out);
        self.cull(&Frustum::in_frame(&frame, positions), out);
        answer
    }

    /// Removes from `out` the objects whose bounds `frustum` cannot see.
    fn cull(&self, frustum: &Frustum, out: &mut [u64]) {
        self.objects.cull(frustum, out);
    }

    /// The union of the leaf sets the positions and the angular boxes
    /// meet, into `out` (cleared first).
    fn ranges_into(&self, positions: &Aabb, ranges: &AngularRanges, out: &mut [u64]) -> Answer {
        out.fill(0);
        let mut answer = Answer::Tree;
        for &(t0, t1, p0, p1) in ranges.boxes() {
            answer = answer.max(self.accumulate(positions, (t0, t1), (p0, p1), out));
        }
        answer
    }

    /// The range of `positions` x `theta` x `phi`, its angles clipped to
    /// the root (every direction's angles lie there): empty, everything
    /// (a NaN, or positions reaching outside the view box, where nothing
    /// was sampled and nothing may be culled), or a cell to descend with.
    fn clip_range(&self, positions: &Aabb, theta: (f32, f32), phi: (f32, f32)) -> Clipped {
        let nan = [theta.0, theta.1, phi.0, phi.1].iter().any(|a| a.is_nan())
            || positions.min.is_nan()
            || positions.max.is_nan();
        let theta = (theta.0.max(-PI), theta.1.min(PI));
        let phi = (phi.0.max(0.0), phi.1.min(PI));
        let empty = theta.0 > theta.1 || phi.0 > phi.1 || !positions.min.cmple(positions.max).all();
        if empty && !nan {
            return Clipped::Empty;
        }
        let space = self.root.space();
        let inside = positions.min.cmpge(space.min).all() && positions.max.cmple(space.max).all();
        if nan || !inside || !positions.min.is_finite() || !positions.max.is_finite() {
            return Clipped::Everything;
        }
        let (a, b) = (positions.min, positions.max);
        Clipped::Range(Cell {
            lo: [a.x, a.y, a.z, theta.0, phi.0],
            hi: [b.x, b.y, b.z, theta.1, phi.1],
        })
    }

    /// Adds the objects of the range to `out` (of the file's size).
    /// Angles are clipped to the root; an empty range adds nothing; a
    /// range with a NaN or reaching outside the view box adds everything
    /// ([`Pvs::clip_range`]).
    fn accumulate(
        &self,
        positions: &Aabb,
        theta: (f32, f32),
        phi: (f32, f32),
        out: &mut [u64],
    ) -> Answer {
        let range = match self.clip_range(positions, theta, phi) {
            Clipped::Empty => return Answer::Tree,
            Clipped::Everything => {
                for (a, b) in out.iter_mut().zip(&self.all) {
                    *a |= b;
                }
                return Answer::Everything;
            }
            Clipped::Range(range) => range,
        };
        // The node sets are ObjectSet words over the same objects (bits past
        // the capacity 0), so the walk ORs raw words.
        self.tree.union(&range, out);
        Answer::Tree
    }
}

/// A range as a query descends it ([`Pvs::clip_range`]).
enum Clipped {
    /// Meets nothing.
    Empty,
    /// Culls nothing.
    Everything,
    /// The cell to descend with.
    Range(Cell),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::cell::angles_to_direction;
    use std::f32::consts::FRAC_PI_2;

    #[test]
    fn a_frustum_of_many_eyes_sees_what_each_eye_sees() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let eyes = Aabb::new(Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
        let mut point = |scale: f32| {
            Vec3::new(rng.random(), rng.random(), rng.random()) * (2.0 * scale) - Vec3::splat(scale)
        };
        let (mut seen, mut culled) = (0, 0);
        for _ in 0..200 {
            let view = View::square(Vec3::ZERO, point(1.0), 70.0);
            let union = Frustum::new(&view, &eyes);
            let b = {
                let c = point(6.0);
                Aabb::new(c, c + point(0.5).abs())
            };
            let by_union = union.may_see(&b);
            culled += usize::from(!by_union);
            for _ in 0..50 {
                let e = eyes.lerp(point(0.5) + Vec3::splat(0.5));
                let one = Frustum::new(
                    &View {
                        position: e,
                        ..view
                    },
                    &Aabb::new(e, e),
                );
                if one.may_see(&b) {
                    seen += 1;
                    assert!(by_union, "{b:?} seen from {e} but culled for the box");
                }
            }
        }
        assert!(seen > 0 && culled > 20, "seen {seen}, culled {culled}");
    }

    /// Every direction of the frustum (a dense grid over it, the edges
    /// included) lies in one of the boxes; angles in f64.
    fn check_frustum(dir: Vec3, up: Vec3, fx: f32, fy: f32) {
        let ranges = frustum_angles(dir, up, fx, fy);
        let f = dir.as_dvec3().normalize();
        let mut r = f.cross(up.as_dvec3());
        if r.length() < 1e-9 {
            r = f.any_orthonormal_vector();
        }
        let r = (r - f * r.dot(f)).normalize();
        let u = r.cross(f);
        let (tx, ty) = ((fx as f64 * 0.5).tan(), (fy as f64 * 0.5).tan());
        let n = 48;
        for i in 0..=n {
            for j in 0..=n {
                let x = (i as f64 / n as f64 * 2.0 - 1.0) * tx;
                let y = (j as f64 / n as f64 * 2.0 - 1.0) * ty;
                let d = f + r * x + u * y;
                let (t, p) = (d.y.atan2(d.x), d.x.hypot(d.y).atan2(d.z));
                let hit = ranges.boxes().iter().any(|&(t0, t1, p0, p1)| {
                    let pole = !(1e-9..=std::f64::consts::PI - 1e-9).contains(&p);
                    (pole || (t >= t0 as f64 && t <= t1 as f64)) && p >= p0 as f64 && p <= p1 as f64
                });
                assert!(
                    hit,
                    "dir {dir} up {up} fov {fx} {fy}: ({t}, {p}) outside {:?}",
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
            let t = -PI + (k as f32 * 0.618_034).fract() * 2.0 * PI;
            let p = (k as f32 * 0.414_213_6).fract() * PI;
            check_frustum(angles_to_direction(t, p), Vec3::Z, 1.2, 0.9);
        }
    }

    /// The counterexamples of the review (2026-11-26): up parallel to dir,
    /// fields of view next to 180 degrees, a pole on the frustum's edge, a
    /// tiny frustum next to a pole.
    #[test]
    fn frustum_boxes_hold_in_degenerate_cases() {
        let d = Vec3::new(0.00504, 0.26157, 0.26164);
        check_frustum(d, d * 3.0, 0.5, 0.5);
        let tilt = d.normalize() + d.normalize().any_orthonormal_vector() * 1e-5;
        check_frustum(d, tilt, 0.5, 0.5);
        for eps in [1e-3f32, 1e-4, 1e-5, 1e-6] {
            check_frustum(Vec3::new(-0.1427, 0.2206, 0.9649), Vec3::Z, PI - eps, 0.1);
            check_frustum(Vec3::X, Vec3::Z, PI - eps, PI - eps);
        }
        let (e, t) = (0.77275f32, 0.77966f32);
        let dir = Vec3::new(e.cos() * t.cos(), e.cos() * t.sin(), e.sin());
        check_frustum(dir, Vec3::Z, 0.8, 2.0 * (PI / 2.0 - e));
        check_frustum(Vec3::new(-4.75e-5, -2.08e-4, 1.0), Vec3::Z, 2.7e-4, 3.3e-4);
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

    /// A matrix from its rows.
    fn rows(r: [[f32; 4]; 4]) -> Mat4 {
        Mat4::from_cols_array_2d(&r).transpose()
    }

    /// Right-handed (OpenGL, Vulkan) or left-handed (Direct3D) view
    /// matrices.
    fn look_at(eye: Vec3, forward: Vec3, up: Vec3, right_handed: bool) -> Mat4 {
        let f = forward.normalize();
        let (s, u, back) = if right_handed {
            let s = f.cross(up).normalize();
            (s, s.cross(f), -f)
        } else {
            let s = up.cross(f).normalize();
            (s, f.cross(s), f)
        };
        let row = |a: Vec3| [a.x, a.y, a.z, -a.dot(eye)];
        rows([row(s), row(u), row(back), [0.0, 0.0, 0.0, 1.0]])
    }

    /// Projections: (depth row, w row) over the x and y scales and shifts.
    fn projection(sx: f32, sy: f32, cx: f32, cy: f32, depth: [f32; 4], w: [f32; 4]) -> Mat4 {
        rows([[sx, 0.0, cx, 0.0], [0.0, sy, cy, 0.0], depth, w])
    }

    /// Whether direction `d` lies in `view`'s frustum (the frame of
    /// [`frustum_angles`]), with a relative tolerance.
    fn in_view(view: &View, d: DVec3) -> bool {
        let f = view.dir.as_dvec3().normalize();
        let r0 = f.cross(view.up.as_dvec3());
        let r = (r0 - f * r0.dot(f)).normalize();
        let u = r.cross(f);
        let z = d.dot(f);
        let tx = (0.5 * f64::from(view.fov_x)).tan();
        let ty = (0.5 * f64::from(view.fov_y)).tan();
        z > 0.0 && d.dot(r).abs() <= tx * z && d.dot(u).abs() <= ty * z
    }

    #[test]
    fn a_view_projection_matrix_gives_a_view_holding_its_frustum() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(15);
        let unit = |rng: &mut rand_pcg::Pcg64| {
            Vec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - Vec3::ONE
        };
        for k in 0..300 {
            let eye = unit(&mut rng) * 50.0;
            let forward = unit(&mut rng).normalize();
            let up = (unit(&mut rng) + forward.any_orthonormal_vector()).normalize();
            let (mut vfov, mut aspect): (f32, f32) =
                (rng.random_range(0.2..2.0), rng.random_range(0.4..2.5));
            if k % 6 == 5 {
                // Off centre, as a headset's eye: up to about 110 degrees.
                (vfov, aspect) = (vfov.min(1.4), aspect.min(1.6));
            }
            let t = 1.0 / (0.5 * vfov).tan();
            let (n, far) = (0.1f32, 100.0f32);
            let rh = look_at(eye, forward, up, true);
            let lh = look_at(eye, forward, up, false);
            let back = [0.0, 0.0, -1.0, 0.0];
            let ahead = [0.0, 0.0, 1.0, 0.0];
            let gl = [0.0, 0.0, (far + n) / (n - far), 2.0 * far * n / (n - far)];
            let zero_one_rh = [0.0, 0.0, far / (n - far), n * far / (n - far)];
            let zero_one_lh = [0.0, 0.0, far / (far - n), -n * far / (far - n)];
            let reversed_infinite = [0.0, 0.0, 0.0, n];
            let p = |depth, w| projection(t / aspect, t, 0.0, 0.0, depth, w);
            // (matrix, a clip depth some 10 to 17 units away, symmetric):
            // the f32 matrix holds its eye to about 1e-5 units.
            let (m, depth, symmetric) = match k % 6 {
                0 => (p(gl, back) * rh, 0.99, true),
                1 => (p(zero_one_rh, back) * rh, 0.99, true),
                2 => (p(zero_one_lh, ahead) * lh, 0.99, true),
                3 => (p(reversed_infinite, back) * rh, 0.01, true),
                // Vulkan's y points down the image.
                4 => (
                    Mat4::from_scale(Vec3::new(1.0, -1.0, 1.0)) * p(zero_one_rh, back) * rh,
                    0.99,
                    true,
                ),
                // Off centre (VR): the eye sees more to one side and up.
                _ => (
                    projection(t / aspect, t, 0.4, -0.25, gl, back) * rh,
                    0.99,
                    false,
                ),
            };
            let v = View::from_view_projection(m).unwrap_or_else(|| panic!("{k}: {m:?}"));
            assert!(
                (v.position - eye).length() < 1e-3 * (1.0 + eye.length()),
                "{k}: {v:?}"
            );
            if symmetric {
                let fov_x = 2.0 * (aspect * (0.5 * vfov).tan()).atan();
                assert!((v.fov_y - vfov).abs() < 1e-3, "{k}: {v:?} {vfov}");
                assert!((v.fov_x - fov_x).abs() < 1e-3, "{k}: {v:?} {fov_x}");
                assert!(v.dir.dot(forward) > 0.9999, "{k}");
            }
            // Every direction the matrix draws is in the view.
            let inv = m.as_dmat4().inverse();
            for _ in 0..300 {
                let (x, y): (f64, f64) =
                    (rng.random_range(-1.0..=1.0), rng.random_range(-1.0..=1.0));
                let q = inv * DVec4::new(x, y, depth, 1.0);
                let d = q.truncate() / q.w - eye.as_dvec3();
                assert!(in_view(&v, d), "{k}: clip ({x}, {y}) outside {v:?}");
            }
        }
        let ortho = rows([
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, -0.1, -0.01],
            [0.0, 0.0, 0.0, 1.0],
        ]);
        assert!(View::from_view_projection(ortho).is_none());
        assert!(View::from_view_projection(Mat4::ZERO).is_none());
        assert!(View::from_view_projection(Mat4::from_cols_array(&[f32::NAN; 16])).is_none());
    }

    #[test]
    fn look_sets_both_fields_of_view_and_turns_with_the_frame() {
        let v = View::look(Vec3::ZERO, Vec3::X, Vec3::Z, 1.0, 2.0);
        assert_eq!(v.fov_y, 1.0);
        assert!((v.fov_x - 2.0 * (2.0 * 0.5f32.tan()).atan()).abs() < 1e-6);
        let y = Frame {
            origin: DVec3::new(10.0, 0.0, 0.0),
            up: crate::geom::Up::Y,
        };
        let w = View::look(Vec3::ZERO, Vec3::X, Vec3::Y, 1.0, 2.0);
        let l = w.to_local(&y, DVec3::new(11.0, 2.0, 3.0));
        assert_eq!(
            (l.position, l.dir, l.up),
            (Vec3::new(3.0, 1.0, 2.0), Vec3::Y, Vec3::Z)
        );
        assert_eq!((l.fov_x, l.fov_y), (w.fov_x, w.fov_y));
    }
}
