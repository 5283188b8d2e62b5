//! Assembling a [`Scene`] from triangles streamed object by object: the one
//! place where the load-time invariants (finite coordinates, no degenerate
//! triangles, every object begun kept, empty or not, unique ids) are
//! established, whatever the file format.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

use glam::DVec3;

use super::{
    LoadReport, MAX_EXTENT, MIN_EXTENT, Object, ObjectFlags, Scene, SceneError, SceneFormat,
    Triangle, is_degenerate, triangle_area,
};
use crate::geom::frame::MAX_DIAGONALS;
use crate::geom::{Aabb, Frame};

/// A coordinate that is NaN or infinite, refused by
/// [`SceneBuilder::push_triangle`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NonFinite(pub f64);

/// Builds a [`Scene`]: call [`begin_object`](Self::begin_object), push its
/// triangles, repeat, then [`finish`](Self::finish).
///
/// Triangles are kept in world coordinates (f64) until `finish`, which
/// chooses the scene's [`Frame`] from their bounds and converts them to
/// local f32 coordinates; zero-area triangles are found there, in the
/// coordinates every stage will use.
#[derive(Debug)]
pub struct SceneBuilder {
    format: SceneFormat,
    world: Vec<[DVec3; 3]>,
    /// The objects begun, in order.
    groups: Vec<Group>,
    skipped_non_triangles: usize,
}

/// An object being built.
#[derive(Debug)]
struct Group {
    name: String,
    /// Its triangles, a range of `world`.
    range: Range<usize>,
    /// The model's own id for it.
    id: Option<String>,
    /// The flags the model gives it.
    flags: ObjectFlags,
    /// How messages name it (`node 5 "door"`), when not by its index and
    /// name.
    label: Option<String>,
}

impl SceneBuilder {
    /// An empty builder for a scene read from `format`.
    pub fn new(format: SceneFormat) -> Self {
        Self {
            format,
            world: Vec::new(),
            groups: Vec::new(),
            skipped_non_triangles: 0,
        }
    }

    /// Starts a new object; the triangles pushed from now on belong to it.
    /// An object that ends with no triangle of non-zero area is kept, empty
    /// ([`super::Object::is_empty`]), and reported
    /// ([`LoadReport::empty_objects`]).
    pub fn begin_object(&mut self, name: impl Into<String>) {
        self.begin_object_with(name, None, ObjectFlags::NONE);
    }

    /// As [`begin_object`](Self::begin_object), with what the model says
    /// of the object beyond its name: its own id (a glTF node's
    /// `extras.vis5d.id`; [`Object::id`]) and its flags. The id must be
    /// valid ([`crate::codec::is_valid_id`]) and the scene's ids unique
    /// ([`Scene::ids`]): [`finish`](Self::finish) checks both.
    pub fn begin_object_with(
        &mut self,
        name: impl Into<String>,
        id: Option<String>,
        flags: ObjectFlags,
    ) {
        let start = self.world.len();
        self.groups.push(Group {
            name: name.into(),
            range: start..start,
            id,
            flags,
            label: None,
        });
    }

    /// How messages name the object being built (a glTF loader: `node 5
    /// "door"`), instead of by its index and name.
    pub fn label_object(&mut self, label: impl Into<String>) {
        if let Some(g) = self.groups.last_mut() {
            g.label = Some(label.into());
        }
    }

    /// The name of the object being built, if any.
    pub fn current_object(&self) -> Option<&str> {
        self.groups.last().map(|g| g.name.as_str())
    }

    /// Adds a triangle, in world coordinates, to the current object
    /// (starting an unnamed one if none was begun). A non-finite coordinate
    /// is refused.
    pub fn push_triangle(&mut self, t: Triangle) -> Result<(), NonFinite> {
        self.push_triangle_f64(t.map(|v| v.as_dvec3()))
    }

    /// As [`push_triangle`](Self::push_triangle), with f64 corners: a
    /// model in georeferenced coordinates keeps its precision until the
    /// scene's frame is chosen.
    pub fn push_triangle_f64(&mut self, t: [DVec3; 3]) -> Result<(), NonFinite> {
        if let Some(bad) = t.iter().flat_map(|v| v.to_array()).find(|c| !c.is_finite()) {
            return Err(NonFinite(bad));
        }
        if self.groups.is_empty() {
            self.begin_object("unnamed");
        }
        self.world.push(t);
        self.groups
            .last_mut()
            .expect("an object was begun above")
            .range
            .end += 1;
        Ok(())
    }

    /// Counts a primitive that is not a surface (a line or a point).
    pub fn skip_non_triangle(&mut self) {
        self.skipped_non_triangles += 1;
    }

    /// Finishes the scene; `path` names the source in errors.
    ///
    /// Refuses a scene whose size f32 cannot resolve ([`MIN_EXTENT`],
    /// [`MAX_EXTENT`]) or that lies so far from the origin that its own
    /// coordinates cannot ([`MAX_DIAGONALS`]); picks its frame
    /// ([`Frame::for_bounds`]), converts every triangle to local
    /// coordinates and drops those of zero area there.
    pub fn finish(self, path: &Path) -> Result<Scene, SceneError> {
        let mut report = LoadReport {
            skipped_non_triangles: self.skipped_non_triangles,
            ..LoadReport::default()
        };
        // The frame is chosen from the triangles of non-zero area: a stray
        // zero-area triangle at (0, 0, 0) in a georeferenced model must not
        // make it look like a scene around the origin (a review found one
        // that did: 1,463 triangles of 3,196 then rounded to zero area).
        let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for t in self.world.iter().filter(|t| !crate::geom::zero_area(t)) {
            for v in t {
                min = min.min(*v);
                max = max.max(*v);
            }
        }
        // A scene of zero-area triangles only is empty, whatever its size.
        if min.x > max.x {
            return Err(SceneError::Empty {
                path: path.to_owned(),
                dropped: self.world.len(),
            });
        }
        let diagonal = (max - min).length();
        if !(f64::from(MIN_EXTENT)..=f64::from(MAX_EXTENT)).contains(&diagonal) {
            return Err(SceneError::Extent {
                path: path.to_owned(),
                diagonal,
            });
        }
        // The largest coordinate of the centre: no overflow where the
        // length would.
        let distance = ((min + max) * 0.5).abs().max_element();
        if distance > MAX_DIAGONALS * diagonal {
            return Err(SceneError::FarFromOrigin {
                path: path.to_owned(),
                distance,
                diagonal,
            });
        }
        // Local coordinates are now within a few diagonals of zero, at most
        // a few times MAX_EXTENT: finite in f32.
        let frame = Frame::for_bounds(min, max, crate::geom::Up::Z);
        let mut triangles = Vec::with_capacity(self.world.len());
        let mut area_cdf = Vec::with_capacity(self.world.len());
        let mut objects = Vec::with_capacity(self.groups.len());
        let mut labels = Vec::with_capacity(self.groups.len());
        for group in self.groups {
            let Group {
                name,
                range,
                id,
                flags,
                label,
            } = group;
            let start = triangles.len() as u64;
            let mut area = 0.0;
            let mut bounds = Aabb::EMPTY;
            for w in &self.world[range] {
                let t = w.map(|v| frame.to_local(v));
                if is_degenerate(&t) {
                    report.dropped_degenerate += 1;
                    continue;
                }
                area += triangle_area(&t);
                for v in t {
                    bounds.grow(v);
                }
                area_cdf.push(area);
                triangles.push(t);
            }
            let end = triangles.len() as u64;
            if end == start {
                report.empty_objects.push(objects.len());
            }
            if end > u64::from(super::MAX_TRIANGLES) {
                return Err(SceneError::TooLarge {
                    path: path.to_owned(),
                });
            }
            labels.push(label);
            objects.push(Object {
                name,
                id,
                triangles: start as u32..end as u32,
                bounds,
                area,
                flags,
            });
        }
        drop(self.world);
        if triangles.is_empty() {
            return Err(SceneError::Empty {
                path: path.to_owned(),
                dropped: report.dropped_degenerate,
            });
        }
        let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
        for o in &objects {
            *counts.entry(o.name.as_str()).or_default() += 1;
        }
        report.duplicate_names = counts
            .into_iter()
            .filter(|&(_, n)| n > 1)
            .map(|(name, n)| (name.to_owned(), n))
            .collect();
        check_ids(path, &objects, &labels)?;
        let bounds = objects.iter().fold(Aabb::EMPTY, |b, o| b.union(&o.bounds));
        Ok(Scene {
            triangles,
            area_cdf,
            objects,
            bounds,
            frame,
            format: self.format,
            report,
        })
    }
}

/// Refuses a model id that is not valid and two objects with one id
/// ([`Scene::ids`]), naming the objects by `labels` where given.
fn check_ids(path: &Path, objects: &[Object], labels: &[Option<String>]) -> Result<(), SceneError> {
    let what = |i: usize| {
        labels[i]
            .clone()
            .unwrap_or_else(|| format!("object {i} {:?}", objects[i].name))
    };
    for (i, o) in objects.iter().enumerate() {
        if let Some(id) = &o.id
            && !crate::codec::is_valid_id(id)
        {
            return Err(SceneError::Id {
                path: path.to_owned(),
                message: format!(
                    "{}: the id {id:?} is empty, longer than {} bytes or holds a NUL byte",
                    what(i),
                    crate::codec::MAX_ID_BYTES
                ),
            });
        }
    }
    let ids = super::object_ids(objects);
    if let Some((i, j)) = crate::codec::first_duplicate(&ids) {
        return Err(SceneError::Id {
            path: path.to_owned(),
            message: format!(
                "{} and {} would both have the id {:?} (an object's id is the model's id for \
                 it, else its name, or name#k where names repeat): give one of them another id",
                what(i),
                what(j),
                ids[i]
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn drops_degenerate_keeps_empty_objects_and_reports_duplicates() {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("a");
        b.push_triangle([Vec3::ZERO, Vec3::X, Vec3::Y]).unwrap();
        b.begin_object("empty");
        b.push_triangle([Vec3::ZERO, Vec3::X, Vec3::X]).unwrap();
        b.begin_object("a");
        b.push_triangle([Vec3::Z, Vec3::X, Vec3::Y]).unwrap();
        let e = b
            .push_triangle([Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)])
            .unwrap_err();
        assert!(e.0.is_nan());
        b.begin_object_with("none", None, ObjectFlags::ALWAYS_VISIBLE);
        let s = b.finish(Path::new("t")).unwrap();
        s.validate().unwrap();
        let got: Vec<(&str, usize)> = s
            .objects()
            .iter()
            .map(|o| (o.name.as_str(), o.triangle_count()))
            .collect();
        assert_eq!(got, [("a", 1), ("empty", 0), ("a", 1), ("none", 0)]);
        assert_eq!(s.report().dropped_degenerate, 1);
        assert_eq!(s.report().empty_objects, [1, 3]);
        assert_eq!(s.empty_objects().collect::<Vec<_>>(), [1, 3]);
        assert_eq!(s.surface_objects().iter().collect::<Vec<_>>(), [0, 2]);
        // Nothing to draw: never always visible.
        assert_eq!(s.always_visible().count(), 0);
        let empty = &s.objects()[1];
        assert!(empty.is_empty() && empty.bounds == Aabb::EMPTY && empty.area == 0.0);
        assert_eq!(empty.triangles, 1..1);
        assert_eq!(s.object_of_triangle(1), 2);
        assert_eq!(s.report().duplicate_names, [("a".to_owned(), 2)]);
    }

    #[test]
    fn a_scene_its_coordinates_cannot_resolve_is_refused() {
        // A millimetre-wide part 1e6 m out: 1e9 diagonals from the origin.
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        let o = DVec3::new(1e6, 0.0, 0.0);
        b.push_triangle_f64([o, o + DVec3::X * 1e-3, o + DVec3::Y * 1e-3])
            .unwrap();
        let e = b.finish(Path::new("part.obj")).unwrap_err();
        assert!(matches!(e, SceneError::FarFromOrigin { .. }), "{e}");
        assert!(e.to_string().contains("move the model nearer"), "{e}");
        // A metre-wide one there is held in a frame centred on it.
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.push_triangle_f64([o, o + DVec3::X, o + DVec3::Y])
            .unwrap();
        let s = b.finish(Path::new("part.obj")).unwrap();
        s.validate().unwrap();
        // Near the centre (1e6 + 0.5, 0.5, 0) on whole metres (the
        // largest power of two not above the diagonal, 1.41).
        assert_eq!(s.frame().origin, DVec3::new(1_000_000.0, 0.0, 0.0));
        let b = s.bounds();
        assert!(b.min.abs().max(b.max.abs()).max_element() <= 1.0, "{b:?}");
    }

    #[test]
    fn zero_area_triangles_do_not_choose_the_frame() {
        // A georeferenced part and a stray zero-area triangle at the
        // origin: the frame is the part's.
        let o = DVec3::new(500_123.7, 4_649_876.3, 12.0);
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("part");
        b.push_triangle_f64([o, o + DVec3::X, o + DVec3::Y])
            .unwrap();
        b.begin_object("junk");
        b.push_triangle_f64([DVec3::ZERO; 3]).unwrap();
        let s = b.finish(Path::new("geo.obj")).unwrap();
        assert!(
            (s.frame().origin - o).abs().max_element() < 2.0,
            "{:?}",
            s.frame()
        );
        assert_eq!(s.report().empty_objects, [1]);
        // Huge corners are not mistaken for a zero area: the size is refused.
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.push_triangle_f64([DVec3::ZERO, DVec3::X * 1e160, DVec3::Y * 1e160])
            .unwrap();
        let e = b.finish(Path::new("huge.obj")).unwrap_err();
        assert!(matches!(e, SceneError::Extent { .. }), "{e}");
    }

    #[test]
    fn model_ids_replace_default_ids_and_must_be_valid_and_unique() {
        let build = |ids: [Option<&str>; 3]| {
            let mut b = SceneBuilder::new(SceneFormat::Procedural);
            for (k, (name, id)) in ["a", "b", "b"].into_iter().zip(ids).enumerate() {
                b.begin_object_with(name, id.map(str::to_owned), ObjectFlags::NEVER_OCCLUDER);
                if k == 2 {
                    b.label_object("node 7 \"b\"");
                }
                let o = Vec3::splat(k as f32);
                b.push_triangle([o, o + Vec3::X, o + Vec3::Y]).unwrap();
            }
            b.finish(Path::new("m.gltf"))
        };
        let s = build([None, Some("door"), None]).unwrap();
        s.validate().unwrap();
        assert_eq!(s.ids(), ["a", "door", "b#2"]);
        assert!(s.objects().iter().all(|o| !o.flags.occludes()));
        for (ids, want) in [
            (
                [Some("x"), Some("x"), None],
                "m.gltf: object 0 \"a\" and object 1 \"b\" would both have the id \"x\"",
            ),
            (
                [None, Some("b#2"), None],
                "m.gltf: object 1 \"b\" and node 7 \"b\" would both have the id \"b#2\"",
            ),
            (
                [Some(""), None, None],
                "m.gltf: object 0 \"a\": the id \"\" is empty",
            ),
        ] {
            let e = build(ids).unwrap_err();
            assert!(matches!(e, SceneError::Id { .. }), "{e}");
            assert!(e.to_string().starts_with(want), "{e}");
        }
    }

    #[test]
    fn empty_scene_is_an_error() {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("flat");
        b.push_triangle([Vec3::ZERO, Vec3::ZERO, Vec3::Y]).unwrap();
        let e = b.finish(Path::new("flat.obj")).unwrap_err();
        assert!(matches!(e, SceneError::Empty { dropped: 1, .. }), "{e}");
        assert!(e.to_string().starts_with("flat.obj:"), "{e}");
    }
}
