//! Comparison reports (`vis5d report`): per view, what each visibility
//! method would draw, against a ground truth rendered by ray casting.
//!
//! - **Ground truth** ([`truth`]): an ID buffer of one ray per pixel
//!   through the shared [`Camera`] ([`crate::render`]); per view the
//!   objects seen and their pixel counts (the set `S_E`).
//! - **Methods**, each giving the set `S_A` of objects to draw per view:
//!   view-frustum culling ([`frustum_set`]: the objects whose bounding box
//!   meets the frustum), the lazy occlusion grid of papers/002, the vis5d
//!   tree (a `.v5d` queried per view), and the extended-projection oracle of
//!   a small cell around the eye (restricted to the frustum).
//! - **Metrics** ([`ViewMetrics::of`]): objects and triangles drawn, pixels
//!   whose object is missing (the pixel error), missed objects, and the set
//!   errors of papers/003: under-estimation `Q_u = |S_E \ S_A| / |S_E|` and
//!   over-estimation `Q_o = |S_A \ S_E| / |S_E|`.
//!
//! The command (`src/cli_report.rs`) runs the methods and writes the page,
//! the JSON and the Markdown.

use glam::Vec3;

use crate::bitset::ObjectSet;
use crate::geom::Aabb;
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
    let ids = IdBuffer::render(tracer, camera);
    ViewTruth {
        seen: ids.object_pixels(scene.objects().len()),
        hit_pixels: ids.hit_pixels(),
        pixels: u64::from(ids.width()) * u64::from(ids.height()),
    }
}

/// The camera's frustum as five planes `(n, d)` (a point `p` is inside
/// when `n . p >= d` for all): the four sides through the eye and the
/// eye's plane (the near plane at distance 0).
pub fn frustum_planes(camera: &Camera) -> [(Vec3, f32); 5] {
    let (f, r, u) = (camera.forward, camera.right, camera.up);
    let (tx, ty) = (camera.tan_x, camera.tan_y);
    // Edge directions of the four side planes.
    let left = (f - r * tx).cross(u);
    let right = u.cross(f + r * tx);
    let top = (f + u * ty).cross(r);
    let bottom = r.cross(f - u * ty);
    let e = camera.eye;
    let plane = |n: Vec3| {
        let n = n.normalize();
        (n, n.dot(e))
    };
    [
        plane(f),
        plane(left),
        plane(right),
        plane(top),
        plane(bottom),
    ]
}

/// Whether the box `b` may meet the frustum: false only when all its
/// corners are strictly outside one plane (conservative: some boxes near
/// the frustum's edges are kept though outside).
pub fn box_in_frustum(planes: &[(Vec3, f32); 5], b: &Aabb) -> bool {
    planes.iter().all(|&(n, d)| {
        // The corner furthest along n.
        let p = Vec3::select(n.cmpge(Vec3::ZERO), b.max, b.min);
        n.dot(p) >= d - 1e-6 * (1.0 + d.abs())
    })
}

/// View-frustum culling: the objects whose bounding box may meet the
/// camera's frustum, into `out` (cleared first).
pub fn frustum_set(scene: &Scene, camera: &Camera, out: &mut ObjectSet) {
    out.clear();
    let planes = frustum_planes(camera);
    for (i, o) in scene.objects().iter().enumerate() {
        if box_in_frustum(&planes, &o.bounds) {
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
            frustum_set(&scene, &cam, &mut set);
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
