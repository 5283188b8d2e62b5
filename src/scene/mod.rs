//! Scenes: named objects made of triangles, loaded from OBJ or glTF files or
//! generated procedurally.
//!
//! An *object* is the unit of visibility: the builder decides for each view
//! cell which objects can be seen, and the runtime answers with a bitset over
//! objects. Objects are identified by their index, in file order; their
//! names are for people and may repeat (repeats are kept and reported).
//!
//! Every group of the model is an object, so that indices follow the
//! model's groups (issue 15: "empty groups are listed, not dropped"): a
//! group with no triangle of non-zero area (an OBJ `o` without faces, a
//! glTF node whose mesh is points or lines, faces all of zero area) is an
//! *empty* object ([`Object::is_empty`]), with its name, id and flags, no
//! triangles, the empty box ([`Aabb::EMPTY`]) and no area. It has no
//! surface, so it is never visible: never in a set of a tree, hidden by
//! both oracles, occluding nothing ([`Scene::surface_objects`] are the
//! others; [`LoadReport::empty_objects`] lists them).
//!
//! Each object owns a contiguous range of the scene's triangle array, its
//! bounding box, and a cumulative area table for uniform surface sampling
//! (papers/003 sec. 5 casts rays "to random points on the object"): a
//! triangle is picked with probability proportional to its area, then a
//! point uniform in it (barycentric square-root warp).
//!
//! Invariants kept by [`SceneBuilder::finish`] and checked by
//! [`Scene::validate`]: every coordinate is finite, every triangle has
//! non-zero area, object ranges tile the triangle array in order (an
//! empty object's range is empty, its box [`Aabb::EMPTY`]), the scene has
//! at least one triangle, and the objects' ids ([`Scene::ids`]) are valid
//! and unique.

mod load_gltf;
mod load_obj;
pub mod procedural;
mod scene_builder;
mod write_glb;
mod write_obj;

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use rand::{Rng, RngExt};

pub use crate::codec::ObjectFlags;
use crate::geom::{Aabb, Frame, Up};
use crate::invariant::InvariantError;

pub use scene_builder::SceneBuilder;
pub use write_glb::{glb_bytes, write_glb};
pub use write_obj::{write_obj, write_obj_file};

/// A triangle: three corners, in the scene's local coordinates
/// ([`Scene::frame`]).
pub type Triangle = [Vec3; 3];

/// One object of a scene: a named, contiguous range of triangles.
#[derive(Clone, Debug)]
pub struct Object {
    /// The name from the file (OBJ `o`/`g` name, glTF node or mesh name).
    pub name: String,
    /// The model's own id for the object (a glTF node's
    /// `extras.vis5d.id`), which replaces its default id in a `.v5d`
    /// ([`Scene::ids`]); `None` for most objects, and for every object of
    /// an OBJ file.
    pub id: Option<String>,
    /// The object's triangles, as a range of [`Scene::triangles`] (empty
    /// for an empty object).
    pub triangles: Range<u32>,
    /// The bounding box of the object's triangles ([`Aabb::EMPTY`] for an
    /// empty object: check [`Object::is_empty`] before using its centre).
    pub bounds: Aabb,
    /// The total surface area (one side), in squared scene units (0 for an
    /// empty object).
    pub area: f64,
    /// What the object is to visibility beyond its triangles (always
    /// visible, never an occluder): the model's (a glTF node's
    /// `extras.vis5d.flags`) when loaded, set by [`Scene::with_flags`]
    /// (`vis5d build --flags` adds a sidecar's to the model's).
    pub flags: ObjectFlags,
}

impl Object {
    /// The number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the object has no triangle (a group of the model with no
    /// triangle of non-zero area): it has no surface and is never visible.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }
}

/// The file format a scene came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFormat {
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// glTF 2.0 with JSON (`.gltf`), buffers embedded or beside it.
    Gltf,
    /// Binary glTF 2.0 (`.glb`).
    Glb,
    /// Generated in memory (see [`procedural`]).
    Procedural,
}

impl fmt::Display for SceneFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SceneFormat::Obj => "obj",
            SceneFormat::Gltf => "gltf",
            SceneFormat::Glb => "glb",
            SceneFormat::Procedural => "procedural",
        })
    }
}

impl SceneFormat {
    /// The format a file name's extension stands for (case-insensitive).
    pub fn from_path(path: &Path) -> Option<SceneFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(SceneFormat::Obj),
            "gltf" => Some(SceneFormat::Gltf),
            "glb" => Some(SceneFormat::Glb),
            _ => None,
        }
    }
}

/// What loading noticed and repaired: facts for the summary, never errors.
#[derive(Clone, Debug, Default)]
pub struct LoadReport {
    /// Triangles dropped because their area is zero (collinear or repeated
    /// corners); see [`is_degenerate`].
    pub dropped_degenerate: usize,
    /// The empty objects ([`Object::is_empty`]), by index, in order:
    /// groups (OBJ `o`/`g`, glTF nodes) with no triangle of non-zero area.
    /// They are listed with the others, so that indices follow the model,
    /// but have no surface and are never visible.
    pub empty_objects: Vec<usize>,
    /// Primitives that are not surfaces and were skipped: OBJ `l`/`p`
    /// lines, glTF points and lines.
    pub skipped_non_triangles: usize,
    /// Names used by more than one object, with how many objects use each,
    /// sorted by name.
    pub duplicate_names: Vec<(String, usize)>,
}

/// Errors of scene loading. Each names the file and says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be opened or read.
    // Note: `cause` is in the message, not a `source()`, so that a chain
    // printed whole (`anyhow`'s `{:#}`) says it once.
    #[error("{}: cannot read the scene file: {cause}", path.display())]
    Io {
        /// The scene file.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// The extension names no format vis5d reads.
    #[error(
        "{}: unknown scene format {ext:?}: vis5d reads .obj, .gltf and .glb files",
        path.display()
    )]
    UnknownFormat {
        /// The scene file.
        path: PathBuf,
        /// The extension found (empty when there is none).
        ext: String,
    },
    /// The file does not parse: `line` is 1-based (0 when unknown).
    #[error("{}{}: {message}", path.display(), line_suffix(*line))]
    Syntax {
        /// The scene file.
        path: PathBuf,
        /// The 1-based line of an OBJ file, 0 when the format has no lines.
        line: usize,
        /// What is wrong there.
        message: String,
    },
    /// A face or index refers to a vertex that does not exist.
    #[error("{}{}: {message}", path.display(), line_suffix(*line))]
    IndexOutOfRange {
        /// The scene file.
        path: PathBuf,
        /// The 1-based line of an OBJ file, 0 when the format has no lines.
        line: usize,
        /// Which index, and the valid range.
        message: String,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error(
        "{}{}: object {object:?} has a vertex with a non-finite coordinate ({value}): \
         fix or remove that vertex",
        path.display(), line_suffix(*line)
    )]
    NonFinite {
        /// The scene file.
        path: PathBuf,
        /// The 1-based line of an OBJ file where the value was seen, 0 when
        /// unknown.
        line: usize,
        /// The object the vertex belongs to.
        object: String,
        /// The offending coordinate, as text.
        value: String,
    },
    /// Nothing to see: no triangle of non-zero area.
    #[error(
        "{}: the scene has no triangles of non-zero area ({dropped} degenerate dropped): \
         nothing can be visible",
        path.display()
    )]
    Empty {
        /// The scene file.
        path: PathBuf,
        /// How many degenerate triangles were dropped on the way.
        dropped: usize,
    },
    /// The scene has more than [`MAX_TRIANGLES`] triangles.
    #[error(
        "{}: the scene has more than 2^30 triangles, the most the tracer indexes",
        path.display()
    )]
    TooLarge {
        /// The scene file.
        path: PathBuf,
    },
    /// An object's id from the model is not valid, or two objects would
    /// have one id ([`Scene::ids`]).
    #[error("{}: {message}", path.display())]
    Id {
        /// The scene file.
        path: PathBuf,
        /// Which objects (glTF: which nodes), and what is wrong.
        message: String,
    },
    /// The scene's size is outside what vis5d's f32 pipeline resolves.
    #[error(
        "{}: the scene's bounding box has a diagonal of {diagonal:e} units, outside the {MIN_EXTENT:e} \
         to {MAX_EXTENT:e} that vis5d resolves (it works in f32): rescale the model (for \
         example to metres) and try again",
        path.display()
    )]
    Extent {
        /// The scene file.
        path: PathBuf,
        /// The diagonal of its bounding box (infinite when it overflows).
        diagonal: f64,
    },
    /// The scene lies so far from the origin, for its size, that its own
    /// (f64) coordinates do not resolve it
    /// ([`crate::geom::frame::MAX_DIAGONALS`]).
    #[error(
        "{}: the scene lies {distance:e} units from the origin but is only {diagonal:e} across: \
         at that distance its coordinates cannot resolve it (the limit is {:e} diagonals): \
         move the model nearer the origin and try again",
        path.display(), crate::geom::frame::MAX_DIAGONALS
    )]
    FarFromOrigin {
        /// The scene file.
        path: PathBuf,
        /// The distance of its bounding box's centre from the origin.
        distance: f64,
        /// The diagonal of its bounding box.
        diagonal: f64,
    },
    /// A glTF names a buffer file outside its own folder.
    #[error(
        "{}: buffer {buffer} names {uri:?}, outside the model's folder: a model may name only \
         files inside its own folder, as relative paths (to allow it, set \
         LoadOptions::allow_outside_paths; `vis5d --allow-outside-paths`)",
        path.display()
    )]
    OutsidePath {
        /// The scene file.
        path: PathBuf,
        /// The buffer's index.
        buffer: usize,
        /// Its URI, as written.
        uri: String,
    },
}

/// The smallest scene diagonal vis5d accepts. Below it the tracer's rays
/// escape closed rooms (the apartment scaled to 1e-15 lost 8% of its
/// pixels; at 1e-12 it was exact; notes/reliability.md).
pub const MIN_EXTENT: f32 = 1e-10;

/// The most triangles a scene may have (2^30, over a billion): the
/// tracer's BVH addresses its leaves' triangles with 30 bits.
pub const MAX_TRIANGLES: u32 = 1 << 30;

/// The largest scene diagonal vis5d accepts. Above it f32 arithmetic
/// loses the scene (the apartment scaled to 1e16 lost 4% of its pixels,
/// 1e30 made obvhs's BVH build panic; 1e15 was exact).
pub const MAX_EXTENT: f32 = 1e14;

/// How scene files are read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadOptions {
    /// Let a glTF name buffer files outside its own folder (absolute
    /// paths, `..`, links leading out). Off by default: a model read from
    /// somewhere else must not make vis5d read `/etc/passwd` as geometry.
    pub allow_outside_paths: bool,
    /// The most bytes the scene file may hold (default: no limit but the
    /// file's own size; buffer files are read only as far as the glTF
    /// declares).
    pub max_file_bytes: u64,
    /// The scene's up axis in its file's coordinates (default +z): local
    /// z follows it ([`Scene::with_up`]).
    pub up: Up,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            allow_outside_paths: false,
            max_file_bytes: u64::MAX,
            up: Up::Z,
        }
    }
}

fn line_suffix(line: usize) -> String {
    if line == 0 {
        String::new()
    } else {
        format!(":{line}")
    }
}

/// Whether a triangle has (numerically) zero area and is dropped on load:
/// the cross product of two edges, computed in f64, is at most `1e-12`
/// times the squared longest edge (the corners are collinear to within
/// rounding), or the corners coincide.
pub fn is_degenerate(t: &Triangle) -> bool {
    crate::geom::zero_area(&t.map(|v| v.as_dvec3()))
}

/// The area of a triangle (f64, one side).
pub fn triangle_area(t: &Triangle) -> f64 {
    let [a, b, c] = t.map(|v| v.as_dvec3());
    0.5 * (b - a).cross(c - a).length()
}

/// A loaded scene: triangles grouped into objects.
#[derive(Clone, Debug)]
pub struct Scene {
    triangles: Vec<Triangle>,
    /// Per triangle, the cumulative area of its object's triangles up to and
    /// including it: the inverse-CDF table of surface sampling.
    area_cdf: Vec<f64>,
    objects: Vec<Object>,
    bounds: Aabb,
    frame: Frame,
    format: SceneFormat,
    report: LoadReport,
}

impl Scene {
    /// All triangles, grouped by object in object order.
    pub fn triangles(&self) -> &[Triangle] {
        &self.triangles
    }

    /// The objects, in file order. An object's index is its identity.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// The triangles of object `object`.
    pub fn object_triangles(&self, object: usize) -> &[Triangle] {
        let r = &self.objects[object].triangles;
        &self.triangles[r.start as usize..r.end as usize]
    }

    /// The object that triangle `triangle` belongs to (binary search).
    pub fn object_of_triangle(&self, triangle: u32) -> usize {
        self.objects
            .partition_point(|o| o.triangles.end <= triangle)
            .min(self.objects.len() - 1)
    }

    /// The bounding box of the whole scene, in local coordinates.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Where the local coordinates of [`triangles`](Self::triangles),
    /// [`bounds`](Self::bounds) and every other position of the scene sit
    /// in the world: the identity for a scene modelled around the origin,
    /// a translation for one far from it ([`Frame::for_bounds`]).
    pub fn frame(&self) -> Frame {
        self.frame
    }

    /// The same objects moved by `offset` (world units, f64): a scene put
    /// where a georeferenced model would be, for tests and `vis5d scene
    /// --offset`. The moved scene gets its own frame, so it is refused only
    /// where a loaded model would be.
    pub fn translated(&self, offset: DVec3, name: &Path) -> Result<Scene, SceneError> {
        let mut b = SceneBuilder::new(self.format);
        self.copy_into(&mut b, offset, 0, name)?;
        Ok(b.finish(name)?.with_up(self.frame.up))
    }

    /// `copies` copies of the scene side by side on the ground (a square
    /// grid of `ceil(sqrt(copies))` columns in the local x and y, the up
    /// axis kept, a gap of a tenth of the larger horizontal size between
    /// copies, the first copy where the scene is): a bigger world made of
    /// a real one, for measuring how builds scale (`vis5d scene --tile`).
    /// Copy `k` > 0 of an object is named `name#k`, and its id, when it
    /// has one, `id#k`; flags are kept. `name` names the result in errors.
    ///
    /// # Errors
    /// When a copy's coordinates are not finite (a scene near the f64
    /// range, copied far enough), or the result has more than
    /// [`MAX_TRIANGLES`] triangles.
    pub fn tiled(&self, copies: u32, name: &Path) -> Result<Scene, SceneError> {
        let copies = copies.max(1);
        let size = self.bounds.size().as_dvec3();
        let gap = 0.1 * size.x.max(size.y);
        let cols = f64::from(copies).sqrt().ceil() as u32;
        let mut b = SceneBuilder::new(self.format);
        for k in 0..copies {
            let (col, row) = (f64::from(k % cols), f64::from(k / cols));
            // In the local frame (z up), turned to the world's axes.
            let shift = DVec3::new(col * (size.x + gap), row * (size.y + gap), 0.0);
            let shift = self.frame.dir_to_world(shift.as_vec3()).as_dvec3();
            self.copy_into(&mut b, shift, k, name)?;
        }
        Ok(b.finish(name)?.with_up(self.frame.up))
    }

    /// Adds every object to `b`, moved by `shift` (world units), with `#k`
    /// after each name and id unless `k` is 0. `name` names the scene in
    /// errors.
    fn copy_into(
        &self,
        b: &mut SceneBuilder,
        shift: DVec3,
        k: u32,
        name: &Path,
    ) -> Result<(), SceneError> {
        for (i, o) in self.objects.iter().enumerate() {
            let (copy_name, id) = if k == 0 {
                (o.name.clone(), o.id.clone())
            } else {
                (
                    format!("{}#{k}", o.name),
                    o.id.as_ref().map(|id| format!("{id}#{k}")),
                )
            };
            b.begin_object_with(copy_name, id, o.flags);
            for t in self.object_triangles(i) {
                b.push_triangle_f64(t.map(|v| self.frame.to_world(v) + shift))
                    .map_err(|bad| SceneError::NonFinite {
                        path: name.to_owned(),
                        line: 0,
                        object: o.name.clone(),
                        value: bad.0.to_string(),
                    })?;
            }
        }
        Ok(())
    }

    /// The same scene with world axis `up` as its up axis (`vis5d --up`):
    /// its local coordinates turned so that `up` is local +z
    /// ([`Frame`]), exactly (the axes are permuted), and its areas
    /// recomputed in the new coordinates, so that it is the very scene a
    /// model turned that way in the file would give.
    pub fn with_up(mut self, up: Up) -> Scene {
        if up == self.frame.up {
            return self;
        }
        let (old, new) = (self.frame, Frame { up, ..self.frame });
        let turn = |v: Vec3| new.dir_to_local(old.dir_to_world(v));
        for t in &mut self.triangles {
            *t = t.map(turn);
        }
        for o in &mut self.objects {
            o.bounds = Aabb::new(turn(o.bounds.min), turn(o.bounds.max));
            let range = o.triangles.start as usize..o.triangles.end as usize;
            let mut area = 0.0;
            for (t, c) in self.triangles[range.clone()]
                .iter()
                .zip(&mut self.area_cdf[range])
            {
                area += triangle_area(t);
                *c = area;
            }
            o.area = area;
        }
        self.bounds = Aabb::new(turn(self.bounds.min), turn(self.bounds.max));
        self.frame = new;
        self
    }

    /// The same scene with object `i`'s flags set to `flags[i]`: what the
    /// builder, the tracer and the oracles honour (see [`ObjectFlags`]).
    ///
    /// # Panics
    /// When `flags` has not one entry per object.
    pub fn with_flags(mut self, flags: &[ObjectFlags]) -> Scene {
        assert_eq!(flags.len(), self.objects.len(), "one flag set per object");
        for (o, &f) in self.objects.iter_mut().zip(flags) {
            o.flags = f;
        }
        self
    }

    /// The objects' ids, as a `.v5d` stores them: each object's own id
    /// from the model ([`Object::id`]) where it has one, else its default
    /// id ([`crate::codec::default_ids`] over the names: the name, or
    /// `name#k` where names repeat). Unique (checked at load).
    pub fn ids(&self) -> Vec<String> {
        object_ids(&self.objects)
    }

    /// Whether every object occludes (no [`ObjectFlags::NEVER_OCCLUDER`]).
    pub fn all_occlude(&self) -> bool {
        self.objects.iter().all(|o| o.flags.occludes())
    }

    /// The objects flagged [`ObjectFlags::ALWAYS_VISIBLE`], in order, but
    /// the empty ones: with nothing to draw they are never visible, flag or
    /// not.
    pub fn always_visible(&self) -> impl Iterator<Item = usize> + '_ {
        self.objects
            .iter()
            .enumerate()
            .filter(|(_, o)| o.flags.always_visible() && !o.is_empty())
            .map(|(i, _)| i)
    }

    /// The empty objects ([`Object::is_empty`]), in order.
    pub fn empty_objects(&self) -> impl Iterator<Item = usize> + '_ {
        self.objects
            .iter()
            .enumerate()
            .filter(|(_, o)| o.is_empty())
            .map(|(i, _)| i)
    }

    /// The objects that have a surface (every one but the empty ones): all
    /// that can ever be visible, the candidates of a tree's root.
    pub fn surface_objects(&self) -> crate::bitset::ObjectSet {
        let mut set = crate::bitset::ObjectSet::full(self.objects.len());
        for o in self.empty_objects() {
            set.remove(o);
        }
        set
    }

    /// The format the scene was read from.
    pub fn format(&self) -> SceneFormat {
        self.format
    }

    /// The fingerprint of the scene's geometry
    /// ([`crate::codec::geometry_fingerprint`] of its local triangles and
    /// its frame): stored in `.v5d` files so that a file built for another
    /// version of the scene, or the scene somewhere else, is detected.
    /// Empty objects count (as objects of no triangles): adding or
    /// removing one shifts the indices the file's sets stand for.
    pub fn fingerprint(&self) -> u64 {
        crate::codec::geometry_fingerprint(
            (0..self.objects.len()).map(|o| self.object_triangles(o)),
            &self.frame,
        )
    }

    /// What loading dropped, skipped and noticed.
    pub fn report(&self) -> &LoadReport {
        &self.report
    }

    /// A point uniform on the surface of object `object`: a triangle chosen
    /// with probability proportional to its area, then a uniform point in it.
    ///
    /// # Panics
    /// When the object is empty ([`Object::is_empty`]): it has no surface.
    #[inline(always)]
    pub fn sample_surface<R: Rng + ?Sized>(&self, object: usize, rng: &mut R) -> Vec3 {
        let o = &self.objects[object];
        assert!(!o.is_empty(), "object {object} has no surface to sample");
        let (start, end) = (o.triangles.start as usize, o.triangles.end as usize);
        let cdf = &self.area_cdf[start..end];
        let u = rng.random::<f64>() * o.area;
        let i = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
        let [a, b, c] = self.triangles[start + i];
        let s = rng.random::<f32>().sqrt();
        let r = rng.random::<f32>();
        a * (1.0 - s) + b * (s * (1.0 - r)) + c * (s * r)
    }

    /// Checks the invariants listed in the module docs; returns the first
    /// broken one. Tests call it on every scene they make.
    pub fn validate(&self) -> Result<(), InvariantError> {
        self.check_invariants()
            .map_err(|what| InvariantError::new("scene", what))
    }

    fn check_invariants(&self) -> Result<(), String> {
        if self.objects.is_empty() || self.triangles.is_empty() {
            return Err("the scene has no objects or no triangles".into());
        }
        if self.area_cdf.len() != self.triangles.len() {
            return Err("the area table does not cover every triangle".into());
        }
        let mut next = 0u32;
        let mut bounds = Aabb::EMPTY;
        for (i, o) in self.objects.iter().enumerate() {
            if o.triangles.start != next || o.triangles.end < o.triangles.start {
                return Err(format!(
                    "object {i} ({:?}) has range {:?}",
                    o.name, o.triangles
                ));
            }
            next = o.triangles.end;
            let tris = self.object_triangles(i);
            let b = Aabb::from_points(tris.iter().flatten().copied());
            if b != o.bounds {
                return Err(format!("object {i} ({:?}) has wrong bounds", o.name));
            }
            bounds = bounds.union(&b);
            let mut sum = 0.0;
            for (k, t) in tris.iter().enumerate() {
                if !t.iter().all(|v| v.is_finite()) || is_degenerate(t) {
                    return Err(format!(
                        "object {i} triangle {k} is non-finite or degenerate"
                    ));
                }
                sum += triangle_area(t);
                let cdf = self.area_cdf[o.triangles.start as usize + k];
                if (cdf - sum).abs() > 1e-9 * sum.max(1.0) {
                    return Err(format!("object {i} area table is wrong at triangle {k}"));
                }
            }
            if (sum - o.area).abs() > 1e-9 * sum.max(1.0) {
                return Err(format!("object {i} ({:?}) has wrong area", o.name));
            }
        }
        if next as usize != self.triangles.len() {
            return Err("object ranges do not cover the triangle array".into());
        }
        if bounds != self.bounds {
            return Err("scene bounds are not the union of object bounds".into());
        }
        if let Some((i, o)) = self.objects.iter().enumerate().find(|(_, o)| {
            o.id.as_deref()
                .is_some_and(|id| !crate::codec::is_valid_id(id))
        }) {
            return Err(format!("object {i} ({:?}) has an invalid id", o.name));
        }
        if let Some((i, j)) = crate::codec::first_duplicate(&self.ids()) {
            return Err(format!("objects {i} and {j} have one id"));
        }
        Ok(())
    }
}

/// The ids of `objects` ([`Scene::ids`]).
fn object_ids(objects: &[Object]) -> Vec<String> {
    let mut ids = crate::codec::default_ids(objects.iter().map(|o| o.name.as_str()));
    for (id, o) in ids.iter_mut().zip(objects) {
        if let Some(own) = &o.id {
            id.clone_from(own);
        }
    }
    ids
}

/// Loads a scene from an OBJ, glTF or GLB file, chosen by extension.
pub fn load(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    load_with_progress(path, &mut |_, _| {})
}

/// As [`load`], calling `progress(done, total)` with bytes parsed so far
/// while it works (often enough for a progress bar, rarely enough to cost
/// nothing).
pub fn load_with_progress(
    path: impl AsRef<Path>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Scene, SceneError> {
    load_with(path, &LoadOptions::default(), progress)
}

/// As [`load_with_progress`], reading files as `options` say. Only regular
/// files are read (a FIFO or a device is refused, not waited on).
pub fn load_with(
    path: impl AsRef<Path>,
    options: &LoadOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Scene, SceneError> {
    let path = path.as_ref();
    let format = format_of(path)?;
    let bytes = crate::input::read_regular(path, options.max_file_bytes).map_err(|cause| {
        SceneError::Io {
            path: path.to_owned(),
            cause,
        }
    })?;
    parse(path, format, &bytes, options, progress)
}

/// Parses a scene file held in memory, its format chosen by `path`'s
/// extension; `path` names it in messages and, for glTF, its folder is
/// where buffer files are looked for (the fuzz targets use this).
pub fn load_bytes(
    path: impl AsRef<Path>,
    bytes: &[u8],
    options: &LoadOptions,
) -> Result<Scene, SceneError> {
    let path = path.as_ref();
    let format = format_of(path)?;
    parse(path, format, bytes, options, &mut |_, _| {})
}

/// The format `path`'s extension names.
fn format_of(path: &Path) -> Result<SceneFormat, SceneError> {
    SceneFormat::from_path(path).ok_or_else(|| SceneError::UnknownFormat {
        path: path.to_owned(),
        ext: path
            .extension()
            .map(|e| e.to_string_lossy().into_owned())
            .unwrap_or_default(),
    })
}

fn parse(
    path: &Path,
    format: SceneFormat,
    bytes: &[u8],
    options: &LoadOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Scene, SceneError> {
    let scene = match format {
        SceneFormat::Obj => load_obj::load_obj(path, bytes, progress),
        SceneFormat::Gltf | SceneFormat::Glb => load_gltf::load_gltf(path, bytes, format, options),
        SceneFormat::Procedural => unreachable!("no extension maps to Procedural"),
    }?;
    Ok(scene.with_up(options.up))
}

/// Parses OBJ text held in memory; `path` is only used in messages and to
/// name a file without groups.
pub fn load_obj_bytes(path: impl AsRef<Path>, bytes: &[u8]) -> Result<Scene, SceneError> {
    load_obj::load_obj(path.as_ref(), bytes, &mut |_, _| {})
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn two_triangle_scene() -> Scene {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("pair");
        // Areas 0.5 and 1.5.
        b.push_triangle([Vec3::ZERO, Vec3::X, Vec3::Y]).unwrap();
        b.push_triangle([
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(13.0, 0.0, 0.0),
            Vec3::new(10.0, 1.0, 0.0),
        ])
        .unwrap();
        b.finish(Path::new("pair")).unwrap()
    }

    #[test]
    fn sampling_is_area_weighted_and_on_the_surface() {
        let scene = two_triangle_scene();
        scene.validate().unwrap();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let n = 40_000;
        let mut big = 0usize;
        let mut mean_small = Vec3::ZERO;
        for _ in 0..n {
            let p = scene.sample_surface(0, &mut rng);
            assert_eq!(p.z, 0.0);
            if p.x >= 10.0 {
                big += 1;
                let (u, v) = ((p.x - 10.0) / 3.0, p.y);
                assert!(u >= -1e-6 && v >= -1e-6 && u + v <= 1.0 + 1e-6, "{p}");
            } else {
                assert!(p.x >= 0.0 && p.y >= 0.0 && p.x + p.y <= 1.0 + 1e-6, "{p}");
                mean_small += p;
            }
        }
        // P(big) = 0.75, standard error ~0.0022.
        let frac = big as f64 / n as f64;
        assert!(
            (frac - 0.75).abs() < 0.01,
            "fraction on the big triangle {frac}"
        );
        // Uniform in a triangle: the mean is the centroid (1/3, 1/3).
        let mean = mean_small / (n - big) as f32;
        assert!(
            (mean - Vec3::new(1.0 / 3.0, 1.0 / 3.0, 0.0)).length() < 0.01,
            "{mean}"
        );
    }

    #[test]
    fn far_scenes_keep_their_precision_through_obj() {
        // The apartment in UTM coordinates and at offsets a review found
        // unstable (a centre on the old rounding rule's tie, a -0.0
        // origin): held relative to a frame near its centre, written in
        // world coordinates, read back the same.
        let near = procedural::generate(procedural::SceneKind::Apartment, 1, 1);
        assert!(near.frame().is_identity());
        for offset in [
            DVec3::new(500_123.7, 4_649_876.3, 250.0),
            DVec3::new(-1579.4, 3785.3, 42.7),
            DVec3::new(498.6, -241.3, -1.3),
        ] {
            let far = near.translated(offset, Path::new("far.obj")).unwrap();
            far.validate().unwrap();
            let origin = far.frame().origin;
            assert!((origin - offset).abs().max_element() < 16.0, "{offset}");
            // Local coordinates are as fine as the near scene's: every
            // corner within an f32 step of the near one, moved.
            let shift = (offset - origin).as_vec3();
            for (a, b) in near.triangles().iter().zip(far.triangles()) {
                for (p, q) in a.iter().zip(b) {
                    assert!((*p + shift - *q).abs().max_element() < 1e-4, "{p} {q}");
                }
            }
            let mut text = Vec::new();
            write_obj(&far, &[], &mut text).unwrap();
            let back = load_obj_bytes("far.obj", &text).unwrap();
            assert_eq!(back.frame(), far.frame(), "{offset}");
            assert_eq!(back.triangles(), far.triangles(), "{offset}");
            assert_eq!(back.fingerprint(), far.fingerprint(), "{offset}");
            assert_ne!(far.fingerprint(), near.fingerprint());
        }
    }

    #[test]
    fn tiles_are_copies_side_by_side_on_the_ground() {
        // The apartment with y up (its z turned into y), tiled five times:
        // three columns on the ground (world x and z), two rows.
        let one = procedural::generate(procedural::SceneKind::Apartment, 1, 1).with_up(Up::Y);
        let tiled = one.tiled(5, Path::new("tiled.obj")).unwrap();
        tiled.validate().unwrap();
        assert_eq!(tiled.frame().up, Up::Y);
        let n = one.objects().len();
        assert_eq!(tiled.objects().len(), 5 * n);
        assert_eq!(tiled.triangles().len(), 5 * one.triangles().len());
        let size = one.bounds().size();
        let gap = 0.1 * size.x.max(size.y);
        let world = |s: &Scene, v: Vec3| s.frame().to_world(v);
        for k in 0..5 {
            let (col, row) = ((k % 3) as f32, (k / 3) as f32);
            // Local x and y are the ground (local z is up).
            let shift = DVec3::new(
                f64::from(col * (size.x + gap)),
                f64::from(row * (size.y + gap)),
                0.0,
            );
            for (i, o) in one.objects().iter().enumerate() {
                let c = &tiled.objects()[k * n + i];
                let name = if k == 0 {
                    o.name.clone()
                } else {
                    format!("{}#{k}", o.name)
                };
                assert_eq!(c.name, name);
                assert_eq!(c.flags, o.flags);
                for (a, b) in one
                    .object_triangles(i)
                    .iter()
                    .zip(tiled.object_triangles(k * n + i))
                {
                    for (p, q) in a.iter().zip(b) {
                        let moved = one.frame().to_world(*p)
                            + one.frame().dir_to_world(shift.as_vec3()).as_dvec3();
                        assert!((moved - world(&tiled, *q)).abs().max_element() < 1e-3);
                    }
                }
            }
            // The up axis is untouched: every copy spans the same heights.
            let copy = tiled.objects()[k * n..(k + 1) * n]
                .iter()
                .fold(Aabb::EMPTY, |b, o| b.union(&o.bounds));
            assert!((copy.min.z - tiled.bounds().min.z).abs() < 1e-3);
        }
        // One copy is the scene itself; zero copies are one.
        let same = one.tiled(1, Path::new("one.obj")).unwrap();
        assert_eq!(same.triangles(), one.triangles());
        assert_eq!(same.fingerprint(), one.fingerprint());
        assert_eq!(
            one.tiled(0, Path::new("zero.obj")).unwrap().objects().len(),
            n
        );
    }

    #[test]
    fn degenerate_triangles() {
        assert!(is_degenerate(&[Vec3::ZERO, Vec3::ZERO, Vec3::ZERO]));
        assert!(is_degenerate(&[Vec3::ZERO, Vec3::X, Vec3::X * 2.0]));
        assert!(is_degenerate(&[Vec3::ZERO, Vec3::X, Vec3::X]));
        assert!(!is_degenerate(&[Vec3::ZERO, Vec3::X, Vec3::Y * 1e-3]));
        assert_eq!(triangle_area(&[Vec3::ZERO, Vec3::X, Vec3::Y]), 0.5);
    }

    #[test]
    fn object_of_triangle_finds_owner() {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        for (name, n) in [("a", 2), ("b", 1), ("c", 3)] {
            b.begin_object(name);
            for k in 0..n {
                let o = Vec3::splat(k as f32);
                b.push_triangle([o, o + Vec3::X, o + Vec3::Y]).unwrap();
            }
        }
        let s = b.finish(Path::new("abc")).unwrap();
        let owners: Vec<usize> = (0..6).map(|t| s.object_of_triangle(t)).collect();
        assert_eq!(owners, [0, 0, 1, 2, 2, 2]);
    }
}
