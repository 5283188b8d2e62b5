//! The ground truth of a view and a method's figures against it.

use crate::bitset::ObjectSet;
use crate::geom::Aabb;
use crate::query::{Frustum, View};
use crate::render::{Camera, IdBuffer};
use crate::scene::Scene;
use crate::trace::Tracer;

/// What the ground truth saw in one view.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewTruth {
    /// The objects seen, with their pixel counts, by object index.
    pub seen: Vec<(u32, u64)>,
    /// Pixels whose ray hit something.
    pub hit_pixels: u64,
    /// Pixels in the image.
    pub pixels: u64,
}

impl ViewTruth {
    /// The set of objects seen (`S_E`).
    pub fn set(&self, objects: usize) -> ObjectSet {
        let mut s = ObjectSet::new(objects);
        for &(o, _) in &self.seen {
            s.insert(o as usize);
        }
        s
    }
}

/// Renders the ID buffer of `camera` ([`IdBuffer`]: one ray per pixel
/// centre) and counts each object's pixels.
pub fn truth(scene: &Scene, tracer: &Tracer, camera: &Camera) -> ViewTruth {
    truth_of(scene, &IdBuffer::render(tracer, camera))
}

/// The ground truth of a view's ID buffer `ids` (of `scene`).
pub fn truth_of(scene: &Scene, ids: &IdBuffer) -> ViewTruth {
    ViewTruth {
        seen: ids.object_pixels(scene.objects().len()),
        hit_pixels: ids.hit_pixels(),
        pixels: u64::from(ids.width()) * u64::from(ids.height()),
    }
}

/// View-frustum culling: the objects whose bounding box may meet the
/// frustum of `view` from its eye ([`Frustum`], the test
/// [`crate::query::Pvs::query_view`] culls with), into `out` (cleared
/// first).
pub fn frustum_set(scene: &Scene, view: &View, out: &mut ObjectSet) {
    out.clear();
    let frustum = Frustum::new(view, &Aabb::new(view.position, view.position));
    for (i, o) in scene.objects().iter().enumerate() {
        // An empty object's box is empty: `may_see` says no.
        if frustum.may_see(&o.bounds) {
            out.insert(i);
        }
    }
}

/// One method's figures for one view.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewMetrics {
    /// Objects drawn, `|S_A|`.
    pub objects: usize,
    /// Triangles drawn.
    pub triangles: u64,
    /// Pixels whose object the method does not draw.
    pub missing_pixels: u64,
    /// The share of hit pixels missing (0 when nothing was hit).
    pub pixel_error: f64,
    /// Objects seen but not drawn, `|S_E \ S_A|`.
    pub missed_objects: usize,
    /// Under-estimation `|S_E \ S_A| / |S_E|` (0 when nothing is seen; see
    /// `seen`).
    pub q_u: f64,
    /// Over-estimation `|S_A \ S_E| / |S_E|` (0 when nothing is seen).
    pub q_o: f64,
    /// Seconds the method took for this view.
    pub seconds: f64,
    /// Objects the view shows, `|S_E|` (when 0, `q_u`, `q_o` and the
    /// pixel error are undefined, and left out of means).
    pub seen: usize,
    /// Triangles drawn at slice granularity (papers/004 sec. 3): those of
    /// the objects drawn less what their hidden slices cull; `None` for a
    /// method without slices or when the report was run without them.
    pub slice_triangles: Option<u64>,
}

impl ViewMetrics {
    /// The figures of the set `drawn` against the view's ground truth.
    pub fn of(scene: &Scene, truth: &ViewTruth, drawn: &ObjectSet, seconds: f64) -> Self {
        let objects = drawn.count();
        let triangles = drawn
            .iter()
            .map(|o| scene.objects()[o].triangle_count() as u64)
            .sum();
        let mut missing_pixels = 0;
        let mut missed_objects = 0;
        for &(o, px) in &truth.seen {
            if !drawn.contains(o as usize) {
                missing_pixels += px;
                missed_objects += 1;
            }
        }
        let seen = truth.seen.len();
        let extra = objects - (seen - missed_objects);
        let share = |x: usize| {
            if seen == 0 {
                0.0
            } else {
                x as f64 / seen as f64
            }
        };
        Self {
            objects,
            triangles,
            missing_pixels,
            pixel_error: if truth.hit_pixels == 0 {
                0.0
            } else {
                missing_pixels as f64 / truth.hit_pixels as f64
            },
            missed_objects,
            q_u: share(missed_objects),
            q_o: share(extra),
            seconds,
            seen,
            slice_triangles: None,
        }
    }
}

/// One method's figures over a set of views. Q_u, Q_o and the pixel error
/// are means over the views that show something (undefined otherwise).
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct MethodSummary {
    /// Objects drawn per view, mean.
    pub mean_objects: f64,
    /// Objects drawn in one view, most.
    pub max_objects: usize,
    /// Triangles drawn per view, mean.
    pub mean_triangles: f64,
    /// Triangles drawn in one view, most.
    pub max_triangles: u64,
    /// Triangles after frustum culling over triangles drawn, summed over
    /// the views (the papers' geometry ratio); `None` when the method
    /// draws no triangle at all.
    pub geometry_ratio: Option<f64>,
    /// Pixel error, mean over the views that show something.
    pub mean_pixel_error: f64,
    /// Pixel error of the worst view.
    pub worst_pixel_error: f64,
    /// The view with the worst pixel error (its index).
    pub worst_view: usize,
    /// Misses summed over the views (an object missed in 3 views counts 3).
    pub missed_objects: usize,
    /// Distinct objects missed in some view.
    pub distinct_missed_objects: usize,
    /// Views where the method missed an object.
    pub views_with_misses: usize,
    /// Under-estimation Q_u, mean over the views that show something.
    pub mean_q_u: f64,
    /// Over-estimation Q_o, mean over the views that show something.
    pub mean_q_o: f64,
    /// Milliseconds per view, mean.
    pub mean_ms_per_view: f64,
    /// Mean triangles drawn per view at slice granularity, when every
    /// view had slices ([`ViewMetrics::slice_triangles`]).
    pub mean_slice_triangles: Option<f64>,
}

impl MethodSummary {
    /// The summary of a method's `views` (with, per view, the objects
    /// `missed`), its geometry ratio against the frustum culling's figures
    /// `frustum` of the same views.
    pub fn of(views: &[ViewMetrics], frustum: &[ViewMetrics], missed: &[Vec<u32>]) -> Self {
        let n = views.len().max(1) as f64;
        let defined: Vec<&ViewMetrics> = views.iter().filter(|v| v.seen > 0).collect();
        let d = defined.len().max(1) as f64;
        let frustum_tris: u64 = frustum.iter().map(|v| v.triangles).sum();
        let tris: u64 = views.iter().map(|v| v.triangles).sum();
        let mut distinct: Vec<u32> = missed.iter().flatten().copied().collect();
        distinct.sort_unstable();
        distinct.dedup();
        let (worst_view, worst) = views
            .iter()
            .enumerate()
            .map(|(i, v)| (i, v.pixel_error))
            .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        Self {
            mean_objects: views.iter().map(|v| v.objects).sum::<usize>() as f64 / n,
            max_objects: views.iter().map(|v| v.objects).max().unwrap_or(0),
            mean_triangles: tris as f64 / n,
            max_triangles: views.iter().map(|v| v.triangles).max().unwrap_or(0),
            geometry_ratio: (tris > 0).then(|| frustum_tris as f64 / tris as f64),
            mean_pixel_error: defined.iter().map(|v| v.pixel_error).sum::<f64>() / d,
            worst_pixel_error: worst,
            worst_view,
            missed_objects: views.iter().map(|v| v.missed_objects).sum(),
            distinct_missed_objects: distinct.len(),
            views_with_misses: views.iter().filter(|v| v.missed_objects > 0).count(),
            mean_q_u: defined.iter().map(|v| v.q_u).sum::<f64>() / d,
            mean_q_o: defined.iter().map(|v| v.q_o).sum::<f64>() / d,
            mean_ms_per_view: 1e3 * views.iter().map(|v| v.seconds).sum::<f64>() / n,
            mean_slice_triangles: views
                .iter()
                .map(|v| v.slice_triangles)
                .sum::<Option<u64>>()
                .filter(|_| !views.is_empty())
                .map(|t| t as f64 / n),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::random_views;
    use crate::scene::procedural::{SceneKind, generate};

    #[test]
    fn frustum_culling_keeps_everything_the_truth_sees() {
        let scene = generate(SceneKind::Apartment, 1, 1);
        let tracer = Tracer::new(&scene);
        let mut set = ObjectSet::new(scene.objects().len());
        for view in random_views(&scene.bounds(), 20, 90.0, 3) {
            let cam = Camera::new(&view, 64, 64).expect("valid views");
            let t = truth(&scene, &tracer, &cam);
            frustum_set(&scene, &view, &mut set);
            let m = ViewMetrics::of(&scene, &t, &set, 0.0);
            assert_eq!((m.missing_pixels, m.missed_objects), (0, 0), "{view:?}");
            assert!(t.set(scene.objects().len()).is_subset(&set));
            assert!(m.objects < scene.objects().len() || t.seen.len() > 100);
        }
    }

    #[test]
    fn metrics_count_what_is_missing_and_extra() {
        let scene = generate(SceneKind::Apartment, 1, 1);
        let truth = ViewTruth {
            seen: vec![(0, 10), (1, 30)],
            hit_pixels: 40,
            pixels: 100,
        };
        let mut drawn = ObjectSet::new(scene.objects().len());
        drawn.insert(1);
        drawn.insert(2);
        drawn.insert(3);
        let m = ViewMetrics::of(&scene, &truth, &drawn, 0.5);
        assert_eq!((m.objects, m.missing_pixels, m.missed_objects), (3, 10, 1));
        assert!((m.pixel_error - 0.25).abs() < 1e-12);
        assert!((m.q_u - 0.5).abs() < 1e-12 && (m.q_o - 1.0).abs() < 1e-12);
    }
}
