//! Rays kept for timing ray casters on exactly the same work: the rays a
//! real build traces ([`crate::builder::record_rays`]), random rays
//! ([`random_rays`]), and the file other ray casters read them from
//! (`vis5d trace --write-rays`; the format is in notes/trace.md).
//!
//! A ray file is a flat array of 28-byte records, nothing else: per ray
//! the origin (x, y, z), the unit direction (x, y, z) and `tmax` (how far
//! the ray reaches: for the builder's object samples, 1 + 1e-4 times the
//! segment's length; +inf for an unbounded ray), seven little-endian f32. `tmin` is 0 for
//! every ray. The triangles go beside them ([`write_triangles`]): nine
//! little-endian f32 per triangle, in the scene's order, in the same
//! coordinates as the rays.

use std::io::{self, Write};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use glam::Vec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;

use crate::geom::Aabb;
use crate::random::{uniform_direction, uniform_point};
use crate::scene::Scene;
use crate::trace::Ray;

/// The bytes of one ray in a ray file.
pub const RAY_BYTES: usize = 28;

/// The bytes of one triangle in a triangle file.
pub const TRIANGLE_BYTES: usize = 36;

/// The first rays handed to it, up to a cap, from any thread.
#[derive(Debug)]
pub struct RayLog {
    cap: usize,
    rays: Mutex<Vec<Ray>>,
    full: AtomicBool,
}

impl RayLog {
    /// A log that keeps the first `cap` rays.
    pub fn new(cap: usize) -> RayLog {
        RayLog {
            cap,
            rays: Mutex::new(Vec::new()),
            full: AtomicBool::new(cap == 0),
        }
    }

    /// Keeps as many of `rays` as the cap leaves room for.
    pub fn push(&self, rays: &[Ray]) {
        if self.is_full() {
            return;
        }
        let mut kept = self.rays.lock().unwrap_or_else(|e| e.into_inner());
        let room = self.cap.saturating_sub(kept.len());
        kept.extend_from_slice(&rays[..rays.len().min(room)]);
        if kept.len() >= self.cap {
            self.full.store(true, Ordering::Relaxed);
        }
    }

    /// Whether the cap is reached.
    pub fn is_full(&self) -> bool {
        self.full.load(Ordering::Relaxed)
    }

    /// The rays kept, in the order they came.
    pub fn into_rays(self) -> Vec<Ray> {
        self.rays.into_inner().unwrap_or_else(|e| e.into_inner())
    }
}

/// `n` rays with origins uniform in `bounds` and directions uniform on the
/// sphere, infinite, from `seed` (what benches/trace.rs traces).
pub fn random_rays(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|_| Ray::new(uniform_point(&mut rng, bounds), uniform_direction(&mut rng)))
        .collect()
}

/// `ray` as a ray file holds it: the direction scaled to unit length,
/// `tmax` by the same factor, `tmin` 0. `None` for a ray that cannot be
/// traced ([`Ray::is_valid`]) or starts past 0.
pub fn portable(ray: &Ray) -> Option<Ray> {
    if !ray.is_valid() || ray.tmin != 0.0 {
        return None;
    }
    let len = ray.dir.length();
    let dir = ray.dir / len;
    (len > 0.0 && dir.is_finite()).then_some(Ray {
        origin: ray.origin,
        dir,
        tmin: 0.0,
        tmax: ray.tmax * len,
    })
}

/// Writes `rays` as a ray file (see the module docs).
pub fn write_rays(mut out: impl Write, rays: &[Ray]) -> io::Result<()> {
    let mut buf = Vec::with_capacity(rays.len().min(1 << 16) * RAY_BYTES);
    for chunk in rays.chunks(1 << 16) {
        buf.clear();
        for r in chunk {
            for v in r.origin.to_array().into_iter().chain(r.dir.to_array()) {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            buf.extend_from_slice(&r.tmax.to_le_bytes());
        }
        out.write_all(&buf)?;
    }
    out.flush()
}

/// Why bytes are not a ray file.
#[derive(Debug, thiserror::Error, PartialEq)]
#[non_exhaustive]
pub enum RayFileError {
    /// The length is not a whole number of rays.
    #[error("{len} bytes are not a whole number of {RAY_BYTES}-byte rays")]
    Length {
        /// The length found.
        len: usize,
    },
    /// A ray cannot be traced: a coordinate not finite, a direction not of
    /// unit length, `tmax` NaN or negative.
    #[error("ray {index} cannot be traced: {why}")]
    Ray {
        /// Its index in the file.
        index: usize,
        /// What is wrong.
        why: &'static str,
    },
}

/// Reads a ray file (see the module docs), checking every ray.
pub fn read_rays(bytes: &[u8]) -> Result<Vec<Ray>, RayFileError> {
    if !bytes.len().is_multiple_of(RAY_BYTES) {
        return Err(RayFileError::Length { len: bytes.len() });
    }
    bytes
        .chunks_exact(RAY_BYTES)
        .enumerate()
        .map(|(index, b)| {
            let f =
                |k: usize| f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]]);
            let origin = Vec3::new(f(0), f(1), f(2));
            let dir = Vec3::new(f(3), f(4), f(5));
            let tmax = f(6);
            let why = if !origin.is_finite() {
                Some("its origin is not finite")
            } else if !dir.is_finite() || (dir.length() - 1.0).abs() > 1e-3 {
                Some("its direction is not of unit length")
            } else if tmax.is_nan() || tmax < 0.0 {
                Some("its tmax is NaN or negative")
            } else {
                None
            };
            match why {
                Some(why) => Err(RayFileError::Ray { index, why }),
                None => Ok(Ray::new(origin, dir).with_tmax(tmax)),
            }
        })
        .collect()
}

/// Writes the scene's triangles (nine little-endian f32 each, in the
/// scene's order: see the module docs).
pub fn write_triangles(mut out: impl Write, scene: &Scene) -> io::Result<()> {
    let mut buf = Vec::with_capacity(scene.triangles().len().min(1 << 16) * TRIANGLE_BYTES);
    for chunk in scene.triangles().chunks(1 << 16) {
        buf.clear();
        for t in chunk {
            for v in t.iter().flat_map(|p| p.to_array()) {
                buf.extend_from_slice(&v.to_le_bytes());
            }
        }
        out.write_all(&buf)?;
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_come_back_from_their_file() {
        let bounds = Aabb::new(Vec3::splat(-3.0), Vec3::new(4.0, 5.0, 6.0));
        let mut rays = random_rays(&bounds, 100, 7);
        rays.push(Ray::segment(Vec3::ZERO, Vec3::new(3.0, 4.0, 0.0)));
        let portable: Vec<Ray> = rays.iter().map(|r| portable(r).unwrap()).collect();
        assert_eq!(portable[100].tmax, 5.0);
        assert_eq!(portable[100].dir, Vec3::new(0.6, 0.8, 0.0));
        let mut bytes = Vec::new();
        write_rays(&mut bytes, &portable).unwrap();
        assert_eq!(bytes.len(), 101 * RAY_BYTES);
        assert_eq!(read_rays(&bytes).unwrap(), portable);
        // Same seed, same rays.
        assert_eq!(random_rays(&bounds, 100, 7), rays[..100]);
    }

    #[test]
    fn bad_ray_files_are_refused() {
        let mut bytes = Vec::new();
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        write_rays(&mut bytes, &[ray, ray]).unwrap();
        assert_eq!(
            read_rays(&bytes[..30]),
            Err(RayFileError::Length { len: 30 })
        );
        let mut nan = bytes.clone();
        nan[RAY_BYTES..RAY_BYTES + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(
            read_rays(&nan),
            Err(RayFileError::Ray { index: 1, .. })
        ));
        let mut zero = bytes.clone();
        zero[12..16].copy_from_slice(&0f32.to_le_bytes());
        assert!(matches!(
            read_rays(&zero),
            Err(RayFileError::Ray { index: 0, .. })
        ));
        assert_eq!(portable(&Ray::new(Vec3::ZERO, Vec3::ZERO)), None);
        assert_eq!(portable(&ray.with_tmin(0.5)), None);
    }

    #[test]
    fn the_log_keeps_the_first_rays() {
        let log = RayLog::new(5);
        let rays: Vec<Ray> = (0..4)
            .map(|i| Ray::new(Vec3::splat(i as f32), Vec3::X))
            .collect();
        log.push(&rays);
        assert!(!log.is_full());
        log.push(&rays);
        assert!(log.is_full());
        log.push(&rays);
        let kept = log.into_rays();
        assert_eq!(kept.len(), 5);
        assert_eq!(kept[4], rays[0]);
    }
}
