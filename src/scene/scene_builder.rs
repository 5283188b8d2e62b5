//! Assembling a [`Scene`] from triangles streamed object by object: the one
//! place where the load-time invariants (finite coordinates, no degenerate
//! triangles, no empty objects) are established, whatever the file format.

use std::collections::BTreeMap;
use std::path::Path;

use super::{
    LoadReport, MAX_EXTENT, MIN_EXTENT, Object, Scene, SceneError, SceneFormat, Triangle,
    is_degenerate, triangle_area,
};
use crate::geom::Aabb;

/// A coordinate that is NaN or infinite, refused by
/// [`SceneBuilder::push_triangle`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NonFinite(pub f32);

/// Builds a [`Scene`]: call [`begin_object`](Self::begin_object), push its
/// triangles, repeat, then [`finish`](Self::finish).
#[derive(Debug)]
pub struct SceneBuilder {
    format: SceneFormat,
    triangles: Vec<Triangle>,
    area_cdf: Vec<f64>,
    objects: Vec<Object>,
    report: LoadReport,
}

impl SceneBuilder {
    /// An empty builder for a scene read from `format`.
    pub fn new(format: SceneFormat) -> Self {
        Self {
            format,
            triangles: Vec::new(),
            area_cdf: Vec::new(),
            objects: Vec::new(),
            report: LoadReport::default(),
        }
    }

    /// Starts a new object; the triangles pushed from now on belong to it.
    /// An object that ends with no triangle is dropped (and reported).
    pub fn begin_object(&mut self, name: impl Into<String>) {
        self.close_object();
        let start = self.triangles.len() as u32;
        self.objects.push(Object {
            name: name.into(),
            triangles: start..start,
            bounds: Aabb::EMPTY,
            area: 0.0,
        });
    }

    /// The name of the object being built, if any.
    pub fn current_object(&self) -> Option<&str> {
        self.objects.last().map(|o| o.name.as_str())
    }

    /// Adds a triangle to the current object (starting an unnamed one if
    /// none was begun). Degenerate triangles are counted and dropped; a
    /// non-finite coordinate is refused.
    pub fn push_triangle(&mut self, t: Triangle) -> Result<(), NonFinite> {
        if let Some(bad) = t.iter().flat_map(|v| v.to_array()).find(|c| !c.is_finite()) {
            return Err(NonFinite(bad));
        }
        if self.objects.is_empty() {
            self.begin_object("unnamed");
        }
        if is_degenerate(&t) {
            self.report.dropped_degenerate += 1;
            return Ok(());
        }
        let o = self.objects.last_mut().expect("an object was begun above");
        o.area += triangle_area(&t);
        for v in t {
            o.bounds.grow(v);
        }
        o.triangles.end += 1;
        self.area_cdf.push(o.area);
        self.triangles.push(t);
        Ok(())
    }

    /// Counts a primitive that is not a surface (a line or a point).
    pub fn skip_non_triangle(&mut self) {
        self.report.skipped_non_triangles += 1;
    }

    fn close_object(&mut self) {
        if self.objects.last().is_some_and(|o| o.triangles.is_empty()) {
            let o = self.objects.pop().expect("checked above");
            self.report.dropped_empty_objects.push(o.name);
        }
    }

    /// Finishes the scene; `path` names the source in errors.
    pub fn finish(mut self, path: &Path) -> Result<Scene, SceneError> {
        self.close_object();
        if self.triangles.is_empty() {
            return Err(SceneError::Empty {
                path: path.to_owned(),
                dropped: self.report.dropped_degenerate,
            });
        }
        if self.triangles.len() >= u32::MAX as usize {
            return Err(SceneError::TooLarge {
                path: path.to_owned(),
            });
        }
        let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
        for o in &self.objects {
            *counts.entry(o.name.as_str()).or_default() += 1;
        }
        self.report.duplicate_names = counts
            .into_iter()
            .filter(|&(_, n)| n > 1)
            .map(|(name, n)| (name.to_owned(), n))
            .collect();
        let bounds = self
            .objects
            .iter()
            .fold(Aabb::EMPTY, |b, o| b.union(&o.bounds));
        let diagonal = bounds.diagonal();
        if !(MIN_EXTENT..=MAX_EXTENT).contains(&diagonal) {
            return Err(SceneError::Extent {
                path: path.to_owned(),
                diagonal,
            });
        }
        Ok(Scene {
            triangles: self.triangles,
            area_cdf: self.area_cdf,
            objects: self.objects,
            bounds,
            format: self.format,
            report: self.report,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn drops_degenerate_and_empty_and_reports_duplicates() {
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
        let s = b.finish(Path::new("t")).unwrap();
        s.validate().unwrap();
        assert_eq!(s.objects().len(), 2);
        assert_eq!(s.report().dropped_degenerate, 1);
        assert_eq!(s.report().dropped_empty_objects, ["empty"]);
        assert_eq!(s.report().duplicate_names, [("a".to_owned(), 2)]);
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
