//! Edge rays: a leaf's guided samples past the silhouettes its cell rays
//! hit, after the adaptive border sampling of guided visibility sampling
//! (GVS, Wonka et al. 2006), at the level of objects.
//!
//! An object that peeks out from behind a nearer one, seen from a part of
//! the cell only (a building over the roofs, a roof from inside the void
//! under it), is hit by few uniform cell rays, and its visible share of
//! its own surface is small, so neither the cache nor the SPRT's object
//! samples find it reliably. What does find it is a ray that passes just
//! beside an edge of a nearer surface. For each cached cell ray that hit a
//! triangle, [`BuildParams::edge_rays`](super::BuildParams::edge_rays)
//! rays start from the same origin toward a point just past one of that
//! triangle's edges: the edge and the point along it uniform, pushed out
//! of the triangle in its plane by [`EDGE_OFFSET`] times its distance from
//! the origin. A ray whose direction leaves the cell's angular box is not
//! cast. Every object such a ray hits is visible from the cell (a ray of
//! the cell reaches it), so edge rays only add proven objects, like the
//! cached rays themselves.
//!
//! GVS recurses on the triangles each new hit finds; at the object level
//! that changed nothing measurable (notes/build.md), so one round is cast.
//! Streams are seeded by the node, and the cache's order is deterministic:
//! the result does not depend on the thread count.

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use super::builder_node::{CachedRay, Ctx};
use super::{BuildStats, mix};
use crate::bitset::ObjectSet;
use crate::geom::cell::Cell;
use crate::trace::Ray;

/// How far past an edge an edge ray aims, in radians seen from its origin
/// (the offset over the distance): far enough that the ray clears the
/// edge in f32, near enough that it grazes the silhouette. On the city,
/// 2e-3 and 1e-2 left the same missing coverage (1.9e-5 of the leaves'
/// rays, notes/build.md).
pub const EDGE_OFFSET: f32 = 2e-3;

/// The stream family of edge rays.
const EDGE_STREAM: u64 = 0x6564_6765;

/// Casts the edge rays of a leaf whose cached rays are `cache` and adds
/// every object they hit to `set`.
pub(super) fn edge_rays(
    ctx: &Ctx,
    cell: &Cell,
    seed: u64,
    cache: &[CachedRay],
    set: &mut ObjectSet,
    stats: &mut BuildStats,
) {
    let per_hit = ctx.params.edge_rays;
    if per_hit == 0 {
        return;
    }
    let angles = cell.angular_box();
    let triangles = ctx.scene.triangles();
    let mut rng = Pcg64::seed_from_u64(mix(seed, EDGE_STREAM));
    let mut rays = Vec::new();
    for r in cache.iter().filter(|r| r.hit.is_some()) {
        let origin = Vec3::new(r.p[0], r.p[1], r.p[2]);
        let t = triangles[r.triangle as usize];
        for _ in 0..per_hit {
            let e = rng.random_range(0..3usize);
            let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
            let q = a + (b - a) * rng.random::<f32>();
            // Out of the triangle, in its plane, across the edge a-b: away
            // from the opposite corner c.
            let along = (b - a).normalize_or_zero();
            let out = ((q - c) - along * (q - c).dot(along)).normalize_or_zero();
            let target = q + out * (EDGE_OFFSET * (q - origin).length());
            let d = target - origin;
            if d.is_finite() && d != Vec3::ZERO && angles.contains(d) {
                rays.push(Ray::new(origin, d));
            }
        }
    }
    let hits = ctx.trace(&rays, stats);
    stats.edge_rays += rays.len() as u64;
    for o in hits.into_iter().flatten() {
        if set.insert(o as usize) {
            stats.decisions.edge_found += 1;
        }
    }
}
