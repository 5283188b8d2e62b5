//! Closest-hit ray casting against a whole scene, answering "which object,
//! which triangle, at what distance" for one ray or for batches traced in
//! parallel with rayon. One BVH, built by obvhs (PLOC and reinsertion)
//! and widened here to eight children a node with full f32 boxes and
//! leaves of up to eight triangles (`trace::bvh8`); two traversals of it:
//! where the CPU has AVX2, one compiled for it (the builder's tracer),
//! elsewhere a portable one. Their answers are the same bit for bit.
//!
//! This is the measuring instrument of the builder (papers/003 sec. 5 casts
//! rays "from a random point in the cell to a random point on the object"),
//! so it must be exact, not approximately right:
//! - the result is the triangle with the smallest `t` in `[tmin, tmax]`, as
//!   computed by a watertight ray-triangle test (Woop, Benthin and Wald
//!   2013; [`brute_force_closest_hit`] runs that same test over every
//!   triangle, and the tests check the two agree bit for bit on many random
//!   rays). obvhs's own Möller-Trumbore test is not watertight: rays
//!   through the shared edge of two triangles could pass between them (a
//!   review found 70% of rays along a quad's diagonal did), and a ray that
//!   slips through a wall reports what lies behind it;
//! - ties (a ray through a shared edge or vertex, coplanar overlaps) go to
//!   the lowest triangle index, so the answer does not depend on the BVH's
//!   layout or traversal order.
//!
//! Invariants: triangles are stored in BVH leaf order, so traversal reads
//! them without the `primitive_indices` indirection that raw obvhs use
//! needs; each record holds its scene index and object. Every triangle's
//! box is padded (`BOX_PAD`), so that the rounded slab tests never skip a
//! triangle the ray hits.
//!
//! Limit: the padding covers the slab test's rounding for origins within
//! about a hundred scene diagonals of the scene; the builder's and the
//! tests' rays start inside or next to it.

use std::time::Duration;

use glam::Vec3;
use obvhs::BvhBuildParams;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::PlocBuilder;
use rayon::prelude::*;

use crate::geom::Aabb;
use crate::scene::{Scene, Triangle};

/// How much every triangle's box is grown before the BVH is built, relative
/// to the scene's size plus its largest coordinate: about 170 ulps of the
/// largest coordinate. obvhs's slab test rounds, and a triangle's box can
/// be flat (an axis-aligned wall) or share a face with the hit point: a
/// rounded entry a few ulps past the hit, or an exit a few ulps before the
/// entry, would skip a triangle that the ray does hit. Padded, every box
/// holds a neighbourhood of each of its triangle's points, so the ray is
/// inside it a margin before and after any hit, and ties at the closest `t`
/// are all visited. Costs nothing measurable (notes/trace.md).
const BOX_PAD: f32 = 1e-5;

/// A ray segment: the points `origin + t * dir` for `t` in `[tmin, tmax]`.
///
/// `t` is measured in units of `dir`'s length: with a unit `dir` it is a
/// distance; with `dir = q - p` the segment from `p` to `q` is `t` in
/// `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts (at `t = 0`).
    pub origin: Vec3,
    /// The direction; need not be unit length, must not be zero.
    pub dir: Vec3,
    /// The smallest `t` that counts as a hit.
    pub tmin: f32,
    /// The largest `t` that counts as a hit (may be infinite).
    pub tmax: f32,
}

impl Ray {
    /// The infinite ray from `origin` along `dir` (`t` in `[0, inf]`).
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self {
            origin,
            dir,
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }

    /// The segment from `from` to `to` (`dir = to - from`, `t` in `[0, 1]`).
    pub fn segment(from: Vec3, to: Vec3) -> Self {
        Self {
            origin: from,
            dir: to - from,
            tmin: 0.0,
            tmax: 1.0,
        }
    }

    /// The same ray with another `tmin`.
    pub fn with_tmin(self, tmin: f32) -> Self {
        Self { tmin, ..self }
    }

    /// The same ray with another `tmax`.
    pub fn with_tmax(self, tmax: f32) -> Self {
        Self { tmax, ..self }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// Whether the ray can be traced: finite origin, finite non-zero
    /// direction, `tmin <= tmax`, `tmin` not NaN.
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite()
            && self.dir.is_finite()
            && self.dir != Vec3::ZERO
            && self.tmin <= self.tmax
    }
}

/// The binary exponent of `x` (`floor(log2 |x|)`), -126 for 0 and
/// subnormals.
fn exponent(x: f32) -> i32 {
    (((x.to_bits() >> 23) & 0xff) as i32 - 127).max(-126)
}

/// The size that sets the scale of rounding errors in a scene: its diagonal
/// plus its largest coordinate (a scene far from the origin rounds coarser;
/// scenes are held in a local frame, [`crate::geom::Frame`], so this is at
/// most a few diagonals).
fn rounding_scale(b: Aabb) -> f32 {
    b.diagonal() + b.min.abs().max(b.max.abs()).max_element()
}

/// The exponent `e` such that rays are handed to obvhs with `|dir|`
/// (largest component) near `2^e`: 2^-20 of the scene's rounding scale.
fn direction_exponent(b: Aabb) -> i32 {
    exponent(rounding_scale(b)) - 20
}

/// A ray prepared for the watertight triangle test (Woop, Benthin and Wald,
/// *Watertight ray/triangle intersection*, JCGT 2013): the axes permuted so
/// that `z` is the direction's largest component (`x`, `y` swapped when it
/// is negative, keeping the winding), and the shear that maps the ray onto
/// the `z` axis. A triangle's corners, sheared into the ray's frame, give
/// three 2D edge functions; two triangles sharing an edge compute that
/// edge's function from the same two corners, so exactly, with opposite
/// signs: no ray passes between them.
struct Shear {
    k: [usize; 3],
    s: [f32; 3],
    origin: [f32; 3],
}

impl Shear {
    /// The shear of ray `r`. Free of branches on the direction (the axes
    /// are picked by arithmetic and read by array index): a branch per
    /// axis choice mispredicts on every other ray of an incoherent
    /// stream.
    #[inline(always)]
    fn new(r: &obvhs::ray::Ray) -> Self {
        let d: [f32; 3] = [r.direction.x, r.direction.y, r.direction.z];
        let a = d.map(f32::abs);
        // 0 where x is the largest (ties to the lower axis), else 1 or 2.
        let x_first = (a[0] >= a[1]) & (a[0] >= a[2]);
        let kz = usize::from(!x_first) * (1 + usize::from(a[1] < a[2]));
        // x and y swapped where the direction along z is negative.
        let negative = usize::from(d[kz] < 0.0);
        let kx = (kz + 1 + negative) % 3;
        let ky = (kz + 2 - negative) % 3;
        Self {
            k: [kx, ky, kz],
            s: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
            origin: [r.origin.x, r.origin.y, r.origin.z],
        }
    }

    /// The hit's `t` in `[tmin, tmax]` (two-sided), or +inf. Always
    /// inlined: into the wide tracer it is compiled for the wide CPU.
    #[inline(always)]
    fn intersect(&self, t: &Tri, tmin: f32, tmax: f32) -> f32 {
        let [kx, ky, kz] = self.k;
        let [sx, sy, sz] = self.s;
        let o = self.origin;
        let rel = |p: [f32; 3]| [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
        let (a, b, c) = (rel(t.a), rel(t.b), rel(t.c));
        let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
        let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
        let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            // On an edge to f32 precision: decide in f64 (products of f32
            // are exact there), as the paper does.
            let e = |px: f32, py: f32, qx: f32, qy: f32| {
                (qx as f64 * py as f64 - qy as f64 * px as f64) as f32
            };
            u = e(bx, by, cx, cy);
            v = e(cx, cy, ax, ay);
            w = e(ax, ay, bx, by);
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return f32::INFINITY;
        }
        let det = u + v + w;
        if det == 0.0 {
            return f32::INFINITY;
        }
        let tt = u * (sz * a[kz]) + v * (sz * b[kz]) + w * (sz * c[kz]);
        let (tt, det) = if det < 0.0 { (-tt, -det) } else { (tt, det) };
        let t_hit = tt / det;
        if t_hit >= tmin && t_hit <= tmax {
            t_hit
        } else {
            f32::INFINITY
        }
    }
}

/// A ray as the traversals take it (obvhs's ray type), with `t_factor` to
/// turn its `t` back into the caller's `t`.
///
/// Note: deviations from obvhs's own `Ray::new`, each for exactness:
/// - the direction is scaled by an exact power of two to a length near
///   2^-20 of the scene's size. obvhs's own box test starts at `t = 1e-4`
///   (`cwbvh::node::EPSILON`) whatever the ray's `tmin`, which made its
///   traversal (used here until 2026-12-05) skip hits closer than that;
///   the traversals now are the project's own and have no such start, and
///   the scaling stays: it changes no answer (power-of-two scaling
///   commutes with rounding, so the triangle test gives exactly
///   `t / 2^k`, and `t_factor = 2^k` gives back exactly `t`), and the
///   slab test's bounds (notes/trace.md) are stated for it;
/// - -0.0 components become +0.0: the slabs are ordered by the inverse's
///   sign, and `safe_inverse(-0.0)` is negative while the component is
///   not: a ray along `-Vec3::Z` = (-0, -0, -1) missed everything in
///   obvhs's box test;
/// - the inverse direction is `1 / d` clamped in magnitude to `2^(50 -
///   e)`, where `2^e` is the scaled direction's size (about 2^-20 of the
///   scene's rounding scale), not `safe_inverse`'s 1 / `f32::EPSILON`,
///   which would make the box test treat nearly axis-parallel rays as
///   moving sideways faster than they do. A clamped inverse shrinks the
///   slab's `t` values, but a box that a hit lies in reaches past it by the
///   padding, at least 1e-5 of the rounding scale, which the clamp turns
///   into `t` of at least about 2^53, beyond any hit of a ray starting
///   within a hundred scales of the scene (`t` under about 2^29); and
///   `origin * inverse` stays under about 2^78, far from overflow. Until
///   2026-12-05 the clamp was a fixed 1e20, too small for scenes under
///   about 5e-8 across: some axis-parallel rays missed hits there.
struct ScaledRay {
    ray: obvhs::ray::Ray,
    t_factor: f32,
}

impl ScaledRay {
    fn new(ray: &Ray, dir_exponent: i32) -> Self {
        // dir * 2^shift has its largest component in [2^e, 2^(e+1)).
        let shift = (dir_exponent - exponent(ray.dir.abs().max_element())).clamp(-120, 120);
        let scale = f32::from_bits(((shift + 127) as u32) << 23);
        let unscale = f32::from_bits(((127 - shift) as u32) << 23);
        let dir = ray.dir * scale + Vec3::ZERO;
        // 2^50 times the inverse of the largest component's scale: see
        // the type's notes.
        let cap = f32::from_bits((((50 - dir_exponent).clamp(-126, 127) + 127) as u32) << 23);
        let inv = Vec3::select(
            dir.cmpeq(Vec3::ZERO),
            Vec3::splat(cap),
            dir.recip().clamp(Vec3::splat(-cap), Vec3::splat(cap)),
        );
        let ray = obvhs::ray::Ray {
            origin: ray.origin.into(),
            direction: dir.into(),
            inv_direction: inv.into(),
            tmin: ray.tmin * unscale,
            tmax: ray.tmax * unscale,
        };
        Self {
            ray,
            t_factor: scale,
        }
    }
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The object hit (index into [`Scene::objects`]).
    pub object: u32,
    /// The triangle hit (index into [`Scene::triangles`]).
    pub triangle: u32,
    /// The ray parameter of the hit point (a distance for unit directions).
    pub t: f32,
}

/// A triangle as the tracer stores it: its corners, with its scene index
/// and its object in two of the 16-byte rows' spare lanes, so that a hit
/// reads one record and no second array.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Tri {
    a: [f32; 3],
    /// The scene index of the triangle.
    id: u32,
    b: [f32; 3],
    /// Its object.
    object: u32,
    c: [f32; 3],
    _pad: u32,
}

impl Tri {
    fn new(t: &Triangle, id: u32, object: u32) -> Self {
        Self {
            a: t[0].to_array(),
            id,
            b: t[1].to_array(),
            object,
            c: t[2].to_array(),
            _pad: 0,
        }
    }

    /// Its box.
    fn aabb(&self) -> obvhs::aabb::Aabb {
        let (a, b, c) = (Vec3::from(self.a), Vec3::from(self.b), Vec3::from(self.c));
        obvhs::aabb::Aabb::new(a.min(b).min(c).into(), a.max(b).max(c).into())
    }
}

/// A traversal's best hit before any: (`t`, triangle) of none.
const NO_HIT: (f32, u32) = (f32::INFINITY, u32::MAX);

/// No target: [`Tracer::closest_hit_towards`] with it is
/// [`Tracer::closest_hit`].
pub const NO_TARGET: u32 = u32::MAX;

/// A BVH over a scene's triangles, answering closest-hit queries. Tracing
/// takes `&self` and is safe from many threads at once.
pub struct Tracer {
    /// The BVH, with its triangles in leaf order.
    bvh: bvh8::Bvh8,
    /// For each triangle in scene order, its object.
    tri_object: Vec<u32>,
    /// Per object, whether rays pass through it
    /// ([`crate::scene::ObjectFlags::NEVER_OCCLUDER`]); `None` when every
    /// object occludes (the fast path).
    see_through: Option<Vec<bool>>,
    /// See [`ScaledRay`].
    dir_exponent: i32,
    /// Whether rays take the traversal compiled for AVX2 ([`bvh8::avx2`]):
    /// where the CPU has it and the BVH is shallow enough for its stack;
    /// else the portable one ([`bvh8::Bvh8::walk`]).
    wide: bool,
    build_time: Duration,
}

impl std::fmt::Debug for Tracer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tracer")
            .field("triangles", &self.tri_object.len())
            .field("bvh", &self.bvh)
            .field("wide", &self.wide)
            .field("build_time", &self.build_time)
            .finish()
    }
}

impl Tracer {
    /// Builds the BVH over every triangle of `scene` (obvhs's PLOC build
    /// with a wide search and reinsertion, widened to eight children a
    /// node and leaves of up to eight triangles at the least surface area
    /// cost: the best trace speed for the build time on the scenes
    /// measured in notes/trace.md).
    pub fn new(scene: &Scene) -> Self {
        let start = std::time::Instant::now();
        let mut tri_object = vec![0u32; scene.triangles().len()];
        for (o, obj) in scene.objects().iter().enumerate() {
            tri_object[obj.triangles.start as usize..obj.triangles.end as usize].fill(o as u32);
        }
        let scene_tris: Vec<Tri> = scene
            .triangles()
            .iter()
            .zip(&tri_object)
            .enumerate()
            .map(|(i, (t, &o))| Tri::new(t, i as u32, o))
            .collect();
        let b = scene.bounds();
        let pad = BOX_PAD * rounding_scale(b);
        let boxes: Vec<obvhs::aabb::Aabb> = scene_tris
            .iter()
            .map(|t| {
                let a = t.aabb();
                obvhs::aabb::Aabb::new(a.min - pad, a.max + pad)
            })
            .collect();
        // obvhs's binary BVH (leaves of one triangle), widened to eight
        // children a node and leaves of up to eight triangles by
        // `Bvh8::new`.
        let p = BVH_PRESET;
        let mut bvh2 = PlocBuilder::with_capacity(boxes.len()).build(
            p.ploc_search_distance,
            &boxes,
            (0..boxes.len() as u32).collect(),
            p.sort_precision,
            p.search_depth_threshold,
        );
        ReinsertionOptimizer::default().run(&mut bvh2, p.reinsertion_batch_ratio, None);
        let bvh = bvh8::Bvh8::new(&bvh2, &scene_tris);
        let wide = wide_cpu() && bvh.fits_stack();
        let see_through = (!scene.all_occlude()).then(|| {
            scene
                .objects()
                .iter()
                .map(|o| !o.flags.occludes())
                .collect()
        });
        Self {
            bvh,
            tri_object,
            see_through,
            dir_exponent: direction_exponent(b),
            wide,
            build_time: start.elapsed(),
        }
    }

    /// The same tracer with the portable code only (never the AVX2
    /// code): the answers are the same bit for bit; for tests and
    /// measurements (`VIS5D_NARROW_TRACE=1` in the environment does the
    /// same for every tracer made).
    pub fn with_portable_code(self) -> Self {
        Self {
            wide: false,
            ..self
        }
    }

    /// Whether rays take the traversal compiled for AVX2 and FMA: where
    /// the CPU has them (unless `VIS5D_NARROW_TRACE` is set, or the tracer
    /// was made [portable](Tracer::with_portable_code)) and the BVH is
    /// shallow enough for its stack. The builder's sampling takes its
    /// code compiled for them on the same condition.
    pub fn is_wide(&self) -> bool {
        self.wide
    }

    /// How long [`Tracer::new`] took.
    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    /// The number of triangles traced against.
    pub fn triangle_count(&self) -> usize {
        self.tri_object.len()
    }

    /// The closest hit of `ray` in `[tmin, tmax]` on an object that
    /// occludes, or `None` when it hits none there (or is not
    /// [valid](Ray::is_valid)). Objects flagged
    /// [`NEVER_OCCLUDER`](crate::scene::ObjectFlags::NEVER_OCCLUDER) are
    /// passed through: see [`Tracer::closest_hit_towards`] and
    /// [`Tracer::seen_along`] for what sees them.
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_hit_towards(ray, NO_TARGET)
    }

    /// The closest hit of `ray` on an object that occludes or on object
    /// `target` (which may not occlude): what a segment aimed at a point of
    /// `target` meets first. The same as [`Tracer::closest_hit`] for an
    /// object that occludes.
    pub fn closest_hit_towards(&self, ray: &Ray, target: u32) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` is set only where the CPU has the features
            // `avx2::closest_hit` is compiled for.
            return unsafe {
                bvh8::avx2::closest_hit(self, &self.bvh, ray, target, &mut bvh8::avx2::stack())
            };
        }
        bvh8::closest_hit(self, &self.bvh, ray, target, &mut Vec::new())
    }

    /// Tests triangle `tri` for a ray sheared as `shear` and aimed at
    /// `target`, within `[tmin, *tmax]`: a closer hit, or one at the same
    /// `t` on a lower triangle index, becomes `best` (`t`, scene index),
    /// and any hit narrows `tmax`. The padded boxes of triangles tied at
    /// `t` are still entered before `t` and the test accepts `t == tmax`,
    /// so ties reach it. A triangle passed through changes nothing. Both
    /// traversals test their triangles with it.
    #[inline(always)]
    fn offer(
        &self,
        shear: &Shear,
        tri: &Tri,
        target: u32,
        tmin: f32,
        tmax: &mut f32,
        best: &mut (f32, u32),
    ) {
        if self.passes_through(tri.object, target) {
            return;
        }
        let t = shear.intersect(tri, tmin, *tmax);
        if t < f32::INFINITY && (t < best.0 || (t == best.0 && tri.id < best.1)) {
            *best = (t, tri.id);
        }
        if t < *tmax {
            *tmax = t;
        }
    }

    /// The hit that a traversal's `best` (see [`Tracer::offer`]) stands
    /// for, `t` scaled back by `t_factor` ([`ScaledRay`]).
    fn hit(&self, best: (f32, u32), t_factor: f32) -> Option<Hit> {
        (best.1 != NO_HIT.1).then(|| Hit {
            object: self.tri_object[best.1 as usize],
            triangle: best.1,
            t: best.0 * t_factor,
        })
    }

    /// Whether rays aimed at `target` pass through the triangles of
    /// object `o`: another object that does not occlude.
    #[inline]
    fn passes_through(&self, o: u32, target: u32) -> bool {
        self.see_through
            .as_ref()
            .is_some_and(|st| o != target && st[o as usize])
    }

    /// Every object `ray` sees, into `out` (cleared first, then in no
    /// particular order, each once): the object of its closest hit on an
    /// occluder, and every object that does not occlude and that the ray
    /// meets before that hit (or anywhere, when it hits no occluder). The
    /// ray truth of a scene with objects flagged
    /// [`NEVER_OCCLUDER`](crate::scene::ObjectFlags::NEVER_OCCLUDER); the
    /// closest hit alone where every object occludes.
    pub fn seen_along(&self, ray: &Ray, out: &mut Vec<u32>) {
        out.clear();
        if !ray.is_valid() {
            return;
        }
        let Some(see_through) = &self.see_through else {
            out.extend(self.closest_hit(ray).map(|h| h.object));
            return;
        };
        let scaled = ScaledRay::new(ray, self.dir_exponent);
        let shear = Shear::new(&scaled.ray);
        let tmin = scaled.ray.tmin;
        let mut best_t = f32::INFINITY;
        let mut best = u32::MAX;
        // (object, t) of the see-through hits.
        let mut through: Vec<(u32, f32)> = Vec::new();
        self.bvh.walk(&scaled.ray, &mut Vec::new(), |pack, tmax| {
            for tri in pack.triangles() {
                let t = shear.intersect(&tri, tmin, *tmax);
                if t == f32::INFINITY {
                    continue;
                }
                let o = tri.object;
                if see_through[o as usize] {
                    through.push((o, t));
                    continue;
                }
                if t < best_t || (t == best_t && tri.id < best) {
                    best_t = t;
                    best = tri.id;
                }
                *tmax = tmax.min(t);
            }
        });
        if best != u32::MAX {
            out.push(self.tri_object[best as usize]);
        }
        // A see-through surface at the occluder's very depth is seen (the
        // conservative reading of a tie).
        for &(o, t) in &through {
            if t <= best_t && !out.contains(&o) {
                out.push(o);
            }
        }
    }

    /// The closest hits of many rays, traced in parallel; `out[i]` is the
    /// hit of `rays[i]`. Allocates nothing.
    ///
    /// # Panics
    /// When `out` and `rays` differ in length.
    pub fn closest_hits_into(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), out.len(), "one output slot per ray");
        out.par_chunks_mut(CHUNK)
            .zip(rays.par_chunks(CHUNK))
            .with_max_len(CHUNKS_PER_JOB)
            .for_each(|(out, rays)| self.trace_run(rays, None, out));
    }

    /// The closest hits of `rays` into `out`, aimed at `targets` when
    /// given (one traversal stack for them all).
    fn trace_run(&self, rays: &[Ray], targets: Option<&[u32]>, out: &mut [Option<Hit>]) {
        let target = |i: usize| targets.map_or(NO_TARGET, |t| t[i]);
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            let mut stack = bvh8::avx2::stack();
            for (i, (o, r)) in out.iter_mut().zip(rays).enumerate() {
                // SAFETY: `wide` is set only where the CPU has the
                // features `avx2::closest_hit` is compiled for.
                *o = unsafe { bvh8::avx2::closest_hit(self, &self.bvh, r, target(i), &mut stack) };
            }
            return;
        }
        let mut stack = Vec::new();
        for (i, (o, r)) in out.iter_mut().zip(rays).enumerate() {
            *o = bvh8::closest_hit(self, &self.bvh, r, target(i), &mut stack);
        }
    }

    /// The closest hits of many rays, traced in parallel, in ray order.
    pub fn closest_hits(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        let mut out = vec![None; rays.len()];
        self.closest_hits_into(rays, &mut out);
        out
    }

    /// [`Tracer::closest_hit_towards`] of many rays, traced in parallel:
    /// `out[i]` is the hit of `rays[i]` aimed at `targets[i]`.
    ///
    /// # Panics
    /// When `rays`, `targets` and `out` differ in length.
    pub fn closest_hits_towards_into(
        &self,
        rays: &[Ray],
        targets: &[u32],
        out: &mut [Option<Hit>],
    ) {
        assert_eq!(rays.len(), out.len(), "one output slot per ray");
        assert_eq!(rays.len(), targets.len(), "one target per ray");
        out.par_chunks_mut(CHUNK)
            .zip(rays.par_chunks(CHUNK).zip(targets.par_chunks(CHUNK)))
            .with_max_len(CHUNKS_PER_JOB)
            .for_each(|(out, (rays, targets))| self.trace_run(rays, Some(targets), out));
    }
}

/// Rays a parallel batch hands each task.
const CHUNK: usize = 256;

/// The most chunks of [`CHUNK`] rays one rayon job traces: the batch is
/// cut down to jobs of at most 2,048 rays (about half a millisecond), so
/// a thread that runs out of work always finds some to steal. Without it
/// rayon cut a batch into two pieces a thread and cut further only a piece
/// that was stolen: a piece a thread had started could not be shared, and
/// where it held the costlier rays the other thread waited (two threads
/// traced 1.67x one thread's rays on a made office block, where two
/// processes traced 2.0x; notes/trace.md, stop 52).
const CHUNKS_PER_JOB: usize = 8;

mod bvh8;
mod huge;

/// How the tracer's binary BVH is built: obvhs's `medium_build` with the
/// search distance of `slow_build` and ten times the reinsertion (its
/// leaf collapse is not used: `Bvh8::new` decides the leaves). On the
/// rays of a build it traces 5-15% faster than `medium_build` for 2.5-4
/// times the BVH's time (0.47 s for San Francisco's 268k triangles, 2.3 s
/// for the forest's 767k: a small part of a build); notes/trace.md.
const BVH_PRESET: BvhBuildParams = BvhBuildParams {
    ploc_search_distance: obvhs::ploc::PlocSearchDistance::High,
    reinsertion_batch_ratio: 0.5,
    ..BvhBuildParams::medium_build()
};

/// Whether this CPU has what [`Tracer`]'s wide code is compiled for.
fn wide_cpu() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::env::var_os("VIS5D_NARROW_TRACE").is_none()
            && is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("fma")
            && is_x86_feature_detected!("bmi1")
            && is_x86_feature_detected!("bmi2")
            && is_x86_feature_detected!("lzcnt")
            && is_x86_feature_detected!("popcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The closest hit of `ray` by testing every triangle of `scene` in order
/// with the same triangle test as [`Tracer`]: the reference the tracer is
/// checked against. Linear in the triangle count.
pub fn brute_force_closest_hit(scene: &Scene, ray: &Ray) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let scaled = ScaledRay::new(ray, direction_exponent(scene.bounds()));
    let r = scaled.ray;
    let shear = Shear::new(&r);
    let mut best: Option<(u32, f32)> = None;
    for (i, tri) in scene.triangles().iter().enumerate() {
        let object = &scene.objects()[scene.object_of_triangle(i as u32)];
        if !object.flags.occludes() {
            continue;
        }
        let t = shear.intersect(&Tri::new(tri, i as u32, 0), r.tmin, r.tmax);
        if t < best.map_or(f32::INFINITY, |b| b.1) {
            best = Some((i as u32, t));
        }
    }
    best.map(|(triangle, t)| Hit {
        object: scene.object_of_triangle(triangle) as u32,
        triangle,
        t: t * scaled.t_factor,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{SceneBuilder, SceneFormat};
    use std::path::Path;

    fn quad_scene() -> Scene {
        // Two unit squares facing +z at z = 0 and z = 1, objects "near"
        // (z = 1) and "far" (z = 0).
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        for (name, z) in [("far", 0.0), ("near", 1.0)] {
            b.begin_object(name);
            let p = |x: f32, y: f32| Vec3::new(x, y, z);
            b.push_triangle([p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)])
                .unwrap();
            b.push_triangle([p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)])
                .unwrap();
        }
        b.finish(Path::new("quads")).unwrap()
    }

    #[test]
    fn closest_hit_picks_the_nearer_object_and_respects_the_interval() {
        let s = quad_scene();
        let tracer = Tracer::new(&s);
        let down = Ray::new(Vec3::new(0.3, 0.6, 2.0), -Vec3::Z);
        let h = tracer.closest_hit(&down).unwrap();
        assert_eq!((h.object, h.t), (1, 1.0));
        let h = tracer.closest_hit(&down.with_tmin(1.5)).unwrap();
        assert_eq!((h.object, h.t), (0, 2.0));
        assert_eq!(tracer.closest_hit(&down.with_tmax(0.5)), None);
        assert_eq!(
            tracer.closest_hit(&Ray::new(Vec3::splat(5.0), Vec3::Z)),
            None
        );
        let seg = Ray::segment(Vec3::new(0.5, 0.5, 0.5), Vec3::new(0.5, 0.5, -0.5));
        assert_eq!(tracer.closest_hit(&seg).unwrap().t, 0.5);
    }

    #[test]
    fn rays_pass_through_objects_that_never_occlude() {
        use crate::scene::ObjectFlags;
        let glass = quad_scene().with_flags(&[ObjectFlags::NONE, ObjectFlags::NEVER_OCCLUDER]);
        let tracer = Tracer::new(&glass);
        let down = Ray::new(Vec3::new(0.3, 0.6, 2.0), -Vec3::Z);
        // The near square (1) is glass: the far one (0) is hit through it.
        let h = tracer.closest_hit(&down).unwrap();
        assert_eq!((h.object, h.t), (0, 2.0));
        assert_eq!(Some(h), brute_force_closest_hit(&glass, &down));
        // Aimed at the glass, the glass is what is met first.
        let h = tracer.closest_hit_towards(&down, 1).unwrap();
        assert_eq!((h.object, h.t), (1, 1.0));
        assert_eq!(tracer.closest_hit_towards(&down, 0).unwrap().object, 0);
        // Both are seen along the ray; only the glass from between them
        // looking up, nothing past the far square looking down from under it.
        let mut seen = Vec::new();
        tracer.seen_along(&down, &mut seen);
        seen.sort_unstable();
        assert_eq!(seen, [0, 1]);
        tracer.seen_along(&Ray::new(Vec3::new(0.3, 0.6, 0.5), Vec3::Z), &mut seen);
        assert_eq!(seen, [1]);
        tracer.seen_along(&down.with_tmax(0.5), &mut seen);
        assert!(seen.is_empty());
        // The far square occludes: the glass behind it is not seen.
        let mut seen_up = Vec::new();
        tracer.seen_along(&Ray::new(Vec3::new(0.3, 0.6, -1.0), Vec3::Z), &mut seen_up);
        assert_eq!(seen_up, [0]);
        // Batches agree with single rays.
        let rays = [down, down, Ray::new(Vec3::splat(5.0), Vec3::Z)];
        let mut out = [None; 3];
        tracer.closest_hits_towards_into(&rays, &[1, NO_TARGET, 1], &mut out);
        assert_eq!(out.map(|h| h.map(|h| h.object)), [Some(1), Some(0), None]);
        // Without flags nothing changes.
        let plain = Tracer::new(&quad_scene());
        plain.seen_along(&down, &mut seen);
        assert_eq!(seen, [1]);
    }

    #[test]
    fn shared_edges_go_to_the_lowest_triangle() {
        let s = quad_scene();
        for tracer in [Tracer::new(&s), Tracer::new(&s).with_portable_code()] {
            // Straight down the diagonal shared by triangles 2 and 3.
            let r = Ray::new(Vec3::new(0.5, 0.5, 3.0), -Vec3::Z);
            let h = tracer.closest_hit(&r).unwrap();
            assert_eq!(Some(h), brute_force_closest_hit(&s, &r));
            assert_eq!(h.triangle, 2);
        }
    }

    #[test]
    fn invalid_rays_hit_nothing() {
        let s = quad_scene();
        let tracer = Tracer::new(&s);
        let o = Vec3::new(0.5, 0.5, 2.0);
        for r in [
            Ray::new(o, Vec3::ZERO),
            Ray::new(o, Vec3::new(f32::NAN, 0.0, -1.0)),
            Ray::new(Vec3::new(f32::INFINITY, 0.0, 0.0), -Vec3::Z),
            Ray::new(o, -Vec3::Z).with_tmin(2.0).with_tmax(1.0),
        ] {
            assert_eq!(tracer.closest_hit(&r), None, "{r:?}");
            assert_eq!(brute_force_closest_hit(&s, &r), None, "{r:?}");
        }
    }

    /// Rays through the shared edges and corners of a mesh never pass
    /// between its triangles (obvhs's Moller-Trumbore test let 70% of the
    /// rays along a quad's diagonal through).
    #[test]
    fn rays_through_shared_edges_do_not_leak() {
        use crate::scene::procedural::shapes::push_box;
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("wall");
        let p = |y: f32, z: f32| Vec3::new(2.0, y, z);
        for t in [
            [p(-128.0, -128.0), p(128.0, -128.0), p(128.0, 128.0)],
            [p(-128.0, -128.0), p(128.0, 128.0), p(-128.0, 128.0)],
        ] {
            b.push_triangle(t).unwrap();
        }
        b.begin_object("box");
        let mut tris = Vec::new();
        push_box(
            &mut tris,
            Vec3::new(5.0, -0.3, -0.7),
            Vec3::new(6.0, 0.9, 0.4),
        );
        for t in tris {
            b.push_triangle(t).unwrap();
        }
        let scene = b.finish(Path::new("leak")).unwrap();
        // Both traversals (the same one twice where the CPU lacks AVX2).
        for tracer in [
            Tracer::new(&scene),
            Tracer::new(&scene).with_portable_code(),
        ] {
            no_leaks(&tracer);
        }
    }

    /// The checks of [`rays_through_shared_edges_do_not_leak`] with
    /// `tracer`.
    fn no_leaks(tracer: &Tracer) {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for _ in 0..20_000 {
            // Along +x through a point of the diagonal y = z.
            let y: f32 = rng.random_range(-0.5..0.5);
            let r = Ray::new(Vec3::new(-9.5, y, y), Vec3::X);
            assert_eq!(tracer.closest_hit(&r).map(|h| h.object), Some(0), "{r:?}");
            // From a random point to a random point of the diagonal.
            let o = Vec3::new(
                -10.0 + rng.random::<f32>(),
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
            );
            let d = Vec3::new(2.0, y, y) - o;
            let r = Ray::new(o, d);
            assert_eq!(tracer.closest_hit(&r).map(|h| h.object), Some(0), "{r:?}");
        }
        // Aimed at the box's edges and corners from outside: always the box.
        let corners: Vec<Vec3> = (0..8)
            .map(|i| {
                Vec3::new(
                    if i & 1 == 0 { 5.0 } else { 6.0 },
                    if i & 2 == 0 { -0.3 } else { 0.9 },
                    if i & 4 == 0 { -0.7 } else { 0.4 },
                )
            })
            .collect();
        for _ in 0..20_000 {
            let (i, j) = (rng.random_range(0..8), rng.random_range(0..8));
            let q = corners[i].lerp(corners[j], rng.random::<f32>());
            let o = Vec3::new(5.5, 0.3, -0.15) + (q - Vec3::new(5.5, 0.3, -0.15)) * 3.0;
            let r = Ray::new(o, q - o);
            if let Some(h) = tracer.closest_hit(&r) {
                assert_eq!(h.object, 1, "{r:?}");
            } else {
                panic!("leaked through the box: {r:?}");
            }
        }
    }
}
