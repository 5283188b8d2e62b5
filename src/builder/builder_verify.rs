//! The pixel error of a tree: how often a rendered pixel shows an object
//! that the tree says cannot be seen. For random views in the view box,
//! an object-ID image is rendered by casting one ray per pixel with the
//! tracer, and each pixel's object is looked up in the set of the leaf its
//! ray falls in. This is the check of issue #3: against rays, not against
//! the builder's own opinion.

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use crate::geom::cell::direction_to_angles;
use crate::scene::Scene;
use crate::trace::{Ray, Tracer};
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

/// The pixel rays of a square view from `eye` along `forward`.
pub fn view_rays(eye: Vec3, forward: Vec3, resolution: u32, fov_degrees: f32) -> Vec<Ray> {
    let f = forward.normalize();
    let up = if f.z.abs() > 0.99 { Vec3::X } else { Vec3::Z };
    let right = f.cross(up).normalize();
    let up = right.cross(f);
    let half = (fov_degrees.to_radians() * 0.5).tan();
    let n = resolution as f32;
    (0..resolution * resolution)
        .map(|i| {
            let x = ((i % resolution) as f32 + 0.5) / n * 2.0 - 1.0;
            let y = 1.0 - ((i / resolution) as f32 + 0.5) / n * 2.0;
            Ray::new(eye, f + right * (x * half) + up * (y * half))
        })
        .collect()
}

/// Renders `params.views` random views inside the tree's view box and
/// counts the pixels whose object is missing from the set of the leaf the
/// pixel's ray falls in.
pub fn pixel_error(
    scene: &Scene,
    tracer: &Tracer,
    tree: &VisTree,
    params: &VerifyParams,
) -> PixelError {
    let mut rng = Pcg64::seed_from_u64(params.seed);
    let space = tree.root_cell().space();
    let mut out = PixelError {
        views: params.views,
        ..Default::default()
    };
    let mut missing = vec![0u64; scene.objects().len()];
    for _ in 0..params.views {
        let eye = space.lerp(Vec3::new(rng.random(), rng.random(), rng.random()));
        let z = rng.random_range(-1.0..1.0f32);
        let a = rng.random_range(0.0..std::f32::consts::TAU);
        let forward = Vec3::new(
            (1.0 - z * z).sqrt() * a.cos(),
            (1.0 - z * z).sqrt() * a.sin(),
            z,
        );
        let rays = view_rays(eye, forward, params.resolution, params.fov_degrees);
        let hits = tracer.closest_hits(&rays);
        let (mut hit, mut miss) = (0u64, 0u64);
        for (r, h) in rays.iter().zip(&hits) {
            let Some(h) = h else { continue };
            hit += 1;
            let (theta, phi) = direction_to_angles(r.dir);
            let leaf = tree.locate([r.origin.x, r.origin.y, r.origin.z, theta, phi]);
            if !tree.nodes()[leaf].set.contains(h.object as usize) {
                miss += 1;
                missing[h.object as usize] += 1;
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
