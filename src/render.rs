//! The one camera and the one ground-truth renderer, shared by every part
//! that looks at the scene through pixels: `vis5d build --verify-views`
//! (the tree's pixel error), `vis5d report` (the ground truth, the frustum
//! test and the lazy occlusion grid's projection) and the tests. A pixel
//! means the same thing to each.
//!
//! - [`Camera`]: the pinhole camera of a [`View`] (the runtime query's view
//!   description: eye, direction, up, fields of view). The up vector's
//!   fallback for vertical views is [`View::square`]'s, and only there.
//! - [`IdBuffer`]: the object seen through each pixel, by casting one ray
//!   through each pixel's centre with the exact [`Tracer`].
//! - [`random_views`]: seeded random views (eye uniform in a box,
//!   direction uniform on the sphere).

use glam::Vec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;

use crate::geom::Aabb;
use crate::query::View;
use crate::random::{uniform_direction, uniform_point};
use crate::trace::{Ray, Tracer};

/// A pinhole camera (pixels are square when `tan_x / tan_y` equals
/// `width / height`, as for square views): an orthonormal frame, the
/// tangents of the half fields of view and the image size. Pixel `(i, j)` (column `i` from
/// the left, row `j` from the top) covers the image-plane square
/// `x in [i, i + 1]`, `y in [j, j + 1]`; its centre ray goes through
/// `(i + 0.5, j + 0.5)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// The eye.
    pub eye: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit right vector (image x grows along it).
    pub right: Vec3,
    /// Unit up vector (image y grows against it: row 0 is the top).
    pub up: Vec3,
    /// `tan(fov_x / 2)`.
    pub tan_x: f32,
    /// `tan(fov_y / 2)`.
    pub tan_y: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// The camera of `view` (its position, direction, up and fields of
    /// view) rendering `width` x `height` pixels. `None` when the view is
    /// degenerate (zero direction, up parallel to it, fields of view
    /// outside (0, 180) degrees, up within a milliradian of the
    /// direction).
    pub fn new(view: &View, width: u32, height: u32) -> Option<Self> {
        let forward = view.dir.normalize_or_zero();
        let cross = forward.cross(view.up);
        // Up (nearly) along the direction leaves the frame to rounding.
        let right = if cross.length() > 1e-3 * view.up.length() {
            cross.normalize()
        } else {
            Vec3::ZERO
        };
        let ok = forward != Vec3::ZERO
            && right != Vec3::ZERO
            && view.fov_x > 0.0
            && view.fov_y > 0.0
            && view.fov_x < std::f32::consts::PI
            && view.fov_y < std::f32::consts::PI
            && width > 0
            && height > 0
            && view.position.is_finite();
        ok.then(|| Self {
            eye: view.position,
            forward,
            right,
            up: right.cross(forward),
            tan_x: (view.fov_x * 0.5).tan(),
            tan_y: (view.fov_y * 0.5).tan(),
            width,
            height,
        })
    }

    /// The ray through the image point `(x, y)` (pixel units, continuous).
    pub fn ray_through(&self, x: f32, y: f32) -> Ray {
        let u = (x / self.width as f32) * 2.0 - 1.0;
        let v = 1.0 - (y / self.height as f32) * 2.0;
        Ray::new(
            self.eye,
            self.forward + self.right * (u * self.tan_x) + self.up * (v * self.tan_y),
        )
    }

    /// The ray through the centre of pixel `(i, j)`.
    pub fn pixel_ray(&self, i: u32, j: u32) -> Ray {
        self.ray_through(i as f32 + 0.5, j as f32 + 0.5)
    }

    /// Every pixel's centre ray, row by row from the top.
    pub fn pixel_rays(&self) -> Vec<Ray> {
        (0..self.height)
            .flat_map(|j| (0..self.width).map(move |i| self.pixel_ray(i, j)))
            .collect()
    }

    /// A point in camera coordinates: `(x, y, z)` with `z` the depth along
    /// `forward` and `x, y` in pixels (the image position of the point when
    /// `z > 0`).
    pub fn to_image(&self, p: Vec3) -> Vec3 {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        let u = d.dot(self.right) / (z * self.tan_x);
        let v = d.dot(self.up) / (z * self.tan_y);
        Vec3::new(
            (u + 1.0) * 0.5 * self.width as f32,
            (1.0 - v) * 0.5 * self.height as f32,
            z,
        )
    }
}

/// The object seen through each pixel of a camera's image: one ray through
/// each pixel's centre, traced exactly (in parallel) to its closest hit.
#[derive(Clone, Debug, PartialEq)]
pub struct IdBuffer {
    width: u32,
    height: u32,
    /// Row by row from the top; `None` where the ray hits nothing.
    objects: Vec<Option<u32>>,
}

impl IdBuffer {
    /// Renders `camera`'s image of the scene `tracer` was built for.
    pub fn render(tracer: &Tracer, camera: &Camera) -> Self {
        let hits = tracer.closest_hits(&camera.pixel_rays());
        Self {
            width: camera.width,
            height: camera.height,
            objects: hits.iter().map(|h| h.map(|h| h.object)).collect(),
        }
    }

    /// Image width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The object seen through pixel `(i, j)` (column, row from the top).
    pub fn get(&self, i: u32, j: u32) -> Option<u32> {
        self.objects[(j * self.width + i) as usize]
    }

    /// Every pixel as `((i, j), object)`, row by row from the top.
    pub fn pixels(&self) -> impl Iterator<Item = ((u32, u32), Option<u32>)> + '_ {
        let w = self.width;
        self.objects
            .iter()
            .enumerate()
            .map(move |(k, &o)| ((k as u32 % w, k as u32 / w), o))
    }

    /// Pixels whose ray hit something.
    pub fn hit_pixels(&self) -> u64 {
        self.objects.iter().flatten().count() as u64
    }

    /// The objects seen with their pixel counts, by object index, for a
    /// scene of `objects` objects.
    pub fn object_pixels(&self, objects: usize) -> Vec<(u32, u64)> {
        let mut counts = vec![0u64; objects];
        for &o in self.objects.iter().flatten() {
            counts[o as usize] += 1;
        }
        counts
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(o, &c)| (o as u32, c))
            .collect()
    }
}

/// `n` random views (seeded): eyes uniform in `space`, directions uniform
/// on the sphere ([`uniform_direction`]), square fields of view of
/// `fov_degrees` ([`View::square`]).
pub fn random_views(space: &Aabb, n: usize, fov_degrees: f32, seed: u64) -> Vec<View> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let eye = uniform_point(&mut rng, space);
            View::square(eye, uniform_direction(&mut rng), fov_degrees)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_rays_project_back_to_their_pixels() {
        let view = View::square(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 0.5, -0.2), 70.0);
        let cam = Camera::new(&view, 64, 48).expect("a valid view");
        for (i, j) in [(0, 0), (63, 47), (10, 30)] {
            let r = cam.pixel_ray(i, j);
            let p = cam.to_image(r.origin + r.dir * 7.0);
            assert!(
                (p.x - (i as f32 + 0.5)).abs() < 1e-3 && (p.y - (j as f32 + 0.5)).abs() < 1e-3,
                "{p}"
            );
            assert!(p.z > 0.0);
        }
        assert!(Camera::new(&View::square(Vec3::ZERO, Vec3::ZERO, 90.0), 8, 8).is_none());
    }
}
