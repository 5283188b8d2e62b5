//! The pixel error of a tree: how often a rendered pixel shows an object
//! that the tree says cannot be seen. For random views in the view box
//! ([`random_views`]), an ID buffer is rendered through the shared
//! [`Camera`] ([`IdBuffer`]: one ray per pixel, exact tracer), and each
//! pixel's object is looked up in the set of the leaf its ray falls in.
//! This is the check of issue #3: against rays, not against the builder's
//! own opinion.

use crate::geom::cell::direction_to_angles;
use crate::render::{Camera, IdBuffer, random_views};
use crate::scene::Scene;
use crate::trace::Tracer;
use crate::tree::VisTree;

/// How to render the check's views.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VerifyParams {
    /// Random views.
    pub views: u32,
    /// Pixels per side of each (square) image.
    pub resolution: u32,
    /// Field of view (both axes), degrees.
    pub fov_degrees: f32,
    /// Seed of the views' positions and directions.
    pub seed: u64,
}

impl Default for VerifyParams {
    fn default() -> Self {
        Self {
            views: 200,
            resolution: 64,
            fov_degrees: 90.0,
            seed: 7,
        }
    }
}

/// The outcome of [`pixel_error`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PixelError {
    /// Views rendered.
    pub views: u32,
    /// Pixels whose ray hit an object.
    pub hit_pixels: u64,
    /// Of those, pixels whose object is missing from its leaf's set.
    pub missing_pixels: u64,
    /// The largest missing fraction of a single view.
    pub worst_view: f64,
    /// Objects that were missing, with their missing pixel counts, most
    /// first.
    pub missing_objects: Vec<(u32, u64)>,
}

impl PixelError {
    /// Missing pixels over hit pixels (0 when nothing was hit).
    pub fn fraction(&self) -> f64 {
        if self.hit_pixels == 0 {
            0.0
        } else {
            self.missing_pixels as f64 / self.hit_pixels as f64
        }
    }
}

/// Renders `params.views` random views inside the tree's view box and
/// counts the pixels whose object is missing from the set of the leaf the
/// pixel's ray falls in. Nothing is rendered when the parameters give no
/// image (a field of view outside (0, 180) degrees, resolution 0).
pub fn pixel_error(
    scene: &Scene,
    tracer: &Tracer,
    tree: &VisTree,
    params: &VerifyParams,
) -> PixelError {
    let space = tree.root_cell().space();
    let mut out = PixelError::default();
    let mut missing = vec![0u64; scene.objects().len()];
    let n = params.resolution;
    for view in random_views(
        &space,
        params.views as usize,
        params.fov_degrees,
        params.seed,
    ) {
        // Random views always have a frame; a field of view outside
        // (0, 180) degrees or an empty image renders nothing.
        let Some(camera) = Camera::new(&view, n, n) else {
            continue;
        };
        out.views += 1;
        let ids = IdBuffer::render(tracer, &camera);
        let (mut hit, mut miss) = (0u64, 0u64);
        for ((i, j), object) in ids.pixels() {
            let Some(object) = object else { continue };
            hit += 1;
            let r = camera.pixel_ray(i, j);
            let (theta, phi) = direction_to_angles(r.dir);
            let leaf = tree.locate([r.origin.x, r.origin.y, r.origin.z, theta, phi]);
            if !tree.nodes()[leaf].set.contains(object as usize) {
                miss += 1;
                missing[object as usize] += 1;
            }
        }
        out.hit_pixels += hit;
        out.missing_pixels += miss;
        if hit > 0 {
            out.worst_view = out.worst_view.max(miss as f64 / hit as f64);
        }
    }
    out.missing_objects = missing
        .iter()
        .enumerate()
        .filter(|&(_, &n)| n > 0)
        .map(|(o, &n)| (o as u32, n))
        .collect();
    out.missing_objects
        .sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    out
}
