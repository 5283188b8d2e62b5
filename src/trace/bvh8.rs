//! The single-ray traversal on CPUs with AVX2: a BVH of eight children a
//! node with full-precision f32 boxes, all eight tested against the ray
//! in one 256-bit pass, and a stack of entries ordered by entry distance,
//! so that the nearest child is visited first and a popped entry that
//! starts beyond the ray's closest hit so far is dropped without reading
//! it (the design of CPU ray tracers such as Embree's BVH8; Wald, Benthin
//! and Boulos 2008, *Getting rid of packets*).
//!
//! obvhs's compressed wide BVH (`CwBvh`) is made for GPUs: each visit
//! decodes 8-bit child boxes, and its traversal never drops an entry by
//! distance. The nodes here are built from the same binary BVH (obvhs's
//! PLOC build and reinsertion), collapsed to leaves of at most
//! [`LEAF_MAX`] triangles by obvhs's SAH collapse and widened by taking,
//! eight times at most, the largest-area inner node among a node's
//! children and putting its two children in its place. A leaf's triangles
//! are stored in one or two [`Pack`]s of four (corners by axis and lane,
//! as Embree's `Triangle4`), and all of them are tested against the ray in
//! one 256-bit pass of the watertight test. The nearest child entered is
//! visited next without a trip through the stack.
//!
//! Exact, as the other traversal is:
//! - the boxes are the padded boxes of the triangles (`BOX_PAD`) and
//!   their unions, unrounded;
//! - the slab test is `plane * inverse - origin * inverse` per axis, one
//!   fused multiply-subtract (obvhs computes `(plane - origin) *
//!   inverse`), on the same scaled ray ([`super::ScaledRay`]). Its
//!   rounding moves a plane by at most `2^-24 (|origin| + 2 |plane -
//!   origin|)` along its axis: under the padding for origins within
//!   about fifty times the scene's rounding scale, as the unfused form's
//!   `3 * 2^-24 |plane - origin|`;
//! - an entry is dropped only when it starts strictly beyond the ray's
//!   `tmax`, so the triangles tied at the closest `t` are all tested and
//!   the tie goes to the lowest index;
//! - the packed triangle test does the scalar test's operations in the
//!   same order on every lane, and leaves a lane with an edge function of
//!   zero to the scalar test (which decides it in f64).
//!
//! The answers are the other traversal's bit for bit
//! (`trace::the_wide_and_the_portable_tracer_agree`, and the brute-force
//! tests).

use std::arch::x86_64::*;

use obvhs::bvh2::Bvh2;

use super::{Hit, NO_HIT, Ray, ScaledRay, Shear, Tracer, Tri};

/// Children a node has at most.
const WIDTH: usize = 8;

/// Triangles a leaf holds at most: two [`Pack`]s, tested together.
pub(super) const LEAF_MAX: u32 = 2 * LANES as u32;

/// Triangles a [`Pack`] holds.
const LANES: usize = 4;

/// Up to [`LANES`] triangles of a leaf, by corner, axis and lane, for one
/// 128-bit test of all of them; unused lanes have NaN corners, which no
/// ray hits.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Pack {
    v: [[[f32; LANES]; 3]; 3],
    id: [u32; LANES],
    object: [u32; LANES],
}

impl Pack {
    const EMPTY: Self = Self {
        v: [[[f32::NAN; LANES]; 3]; 3],
        id: [u32::MAX; LANES],
        object: [0; LANES],
    };

    /// Its triangle in `lane`.
    fn tri(&self, lane: usize) -> Tri {
        let corner = |k: usize| [0, 1, 2].map(|axis| self.v[k][axis][lane]);
        Tri {
            a: corner(0),
            id: self.id[lane],
            b: corner(1),
            object: self.object[lane],
            c: corner(2),
            _pad: 0,
        }
    }
}

/// Entries of the traversal stack. A BVH whose traversal could need more
/// (seven entries a level) is not built: the tracer keeps the other
/// traversal then.
const STACK: usize = 256;

/// A child reference with this bit is a leaf: `count << COUNT_SHIFT |
/// first triangle`.
const LEAF: u32 = 1 << 31;
const COUNT_SHIFT: u32 = 27;
const FIRST_MASK: u32 = (1 << COUNT_SHIFT) - 1;

/// An empty child slot: a box no ray enters.
const NONE: u32 = u32::MAX;

/// A node: its children's boxes by axis and bound (lane `i` is child
/// `i`), and the children: inner nodes by index, leaves as [`LEAF`]
/// references. Empty slots have an inverted box (`+inf` to `-inf`).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node {
    lo: [[f32; WIDTH]; 3],
    hi: [[f32; WIDTH]; 3],
    child: [u32; WIDTH],
}

impl Node {
    const EMPTY: Self = Self {
        lo: [[f32::INFINITY; WIDTH]; 3],
        hi: [[f32::NEG_INFINITY; WIDTH]; 3],
        child: [NONE; WIDTH],
    };
}

/// The eight-wide BVH and its triangles in leaf order.
pub(super) struct Bvh8 {
    nodes: Vec<Node>,
    packs: Vec<Pack>,
    /// The root's reference (a node, or a leaf for a scene of few
    /// triangles).
    root: u32,
}

impl std::fmt::Debug for Bvh8 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh8")
            .field("nodes", &self.nodes.len())
            .field("packs", &self.packs.len())
            .finish()
    }
}

impl Bvh8 {
    /// The wide BVH of `bvh` (a binary BVH over the padded boxes of
    /// `scene_tris`, in scene order, with at most [`LEAF_MAX`] triangles a
    /// leaf), or `None` when it has no triangles or its traversal could
    /// need more than the stack holds.
    pub(super) fn new(bvh: &Bvh2, scene_tris: &[Tri]) -> Option<Self> {
        let leaf = |n: &obvhs::bvh2::node::Bvh2Node, packs: &mut Vec<Pack>| {
            let first = packs.len() as u32;
            let range = n.first_index as usize..(n.first_index + n.prim_count) as usize;
            for chunk in bvh.primitive_indices[range].chunks(LANES) {
                let mut pack = Pack::EMPTY;
                for (lane, &i) in chunk.iter().enumerate() {
                    let t = &scene_tris[i as usize];
                    for (rows, corner) in pack.v.iter_mut().zip([t.a, t.b, t.c]) {
                        for (row, value) in rows.iter_mut().zip(corner) {
                            row[lane] = value;
                        }
                    }
                    pack.id[lane] = t.id;
                    pack.object[lane] = t.object;
                }
                packs.push(pack);
            }
            let count = packs.len() as u32 - first;
            LEAF | (count << COUNT_SHIFT) | first
        };
        if bvh.nodes.is_empty()
            || bvh.primitive_indices.len() > FIRST_MASK as usize
            || bvh.nodes.iter().any(|n| n.prim_count > 15 * LANES as u32)
        {
            return None;
        }
        let mut packs = Vec::with_capacity(bvh.primitive_indices.len().div_ceil(LANES));
        let mut nodes = Vec::new();
        if bvh.nodes[0].is_leaf() {
            let root = leaf(&bvh.nodes[0], &mut packs);
            return Some(Self { nodes, packs, root });
        }
        // (binary node, wide node to fill, its depth)
        let mut work = vec![(0usize, 0usize, 1usize)];
        nodes.push(Node::EMPTY);
        let mut depth = 1;
        while let Some((b, slot, d)) = work.pop() {
            depth = depth.max(d);
            let first = bvh.nodes[b].first_index as usize;
            let mut kids = vec![first, first + 1];
            while kids.len() < WIDTH {
                let widest = kids
                    .iter()
                    .enumerate()
                    .filter(|(_, k)| !bvh.nodes[**k].is_leaf())
                    .max_by(|a, b| {
                        let area = |k: usize| bvh.nodes[k].aabb().half_area();
                        area(*a.1).total_cmp(&area(*b.1))
                    })
                    .map(|(i, _)| i);
                let Some(i) = widest else { break };
                let f = bvh.nodes[kids[i]].first_index as usize;
                kids[i] = f;
                kids.push(f + 1);
            }
            let mut node = Node::EMPTY;
            for (lane, &k) in kids.iter().enumerate() {
                let n = &bvh.nodes[k];
                let bounds = n.aabb();
                for axis in 0..3 {
                    node.lo[axis][lane] = bounds.min[axis];
                    node.hi[axis][lane] = bounds.max[axis];
                }
                node.child[lane] = if n.is_leaf() {
                    leaf(n, &mut packs)
                } else {
                    let at = nodes.len();
                    nodes.push(Node::EMPTY);
                    work.push((k, at, d + 1));
                    at as u32
                };
            }
            nodes[slot] = node;
        }
        if 1 + (WIDTH - 1) * depth > STACK {
            return None;
        }
        Some(Self {
            nodes,
            packs,
            root: 0,
        })
    }
}

/// Eight f32 as a register.
#[inline]
#[target_feature(enable = "avx")]
fn load(a: &[f32; WIDTH]) -> __m256 {
    bytemuck::cast(*a)
}

/// The traversal's stack: (child reference, entry `t`) pairs. Made once
/// for many rays (it is 2 KiB).
pub(super) type Stack = [(u32, f32); STACK];

/// A new [`Stack`].
pub(super) fn stack() -> Stack {
    [(0, 0.0); STACK]
}

/// Asks the CPU to start loading what `reference` points to (a node's
/// four cache lines, or a leaf's triangles), to be read when it is popped.
#[inline(always)]
fn prefetch(bvh: &Bvh8, reference: u32) {
    let line = |p: *const u8| {
        // SAFETY: a prefetch never faults, and reads nothing the program
        // sees; `p` is in bounds of a live allocation besides.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p.cast()) }
    };
    if reference & LEAF != 0 {
        let first = (reference & FIRST_MASK) as usize;
        let count = ((reference & !LEAF) >> COUNT_SHIFT) as usize;
        let p = bvh.packs[first..].as_ptr().cast::<u8>();
        for k in 0..3 * count.min(2) {
            line(p.wrapping_add(64 * k));
        }
    } else {
        let p = (&bvh.nodes[reference as usize] as *const Node).cast::<u8>();
        for k in 0..4 {
            line(p.wrapping_add(64 * k));
        }
    }
}

/// The closest hit of `ray` on an occluder or on `target` (see
/// [`Tracer::closest_hit_towards`]), with `stack` as scratch.
#[target_feature(enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
pub(super) fn closest_hit(
    tracer: &Tracer,
    bvh: &Bvh8,
    ray: &Ray,
    target: u32,
    stack: &mut Stack,
) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let scaled = ScaledRay::new(ray, tracer.dir_exponent);
    let r = &scaled.ray;
    let shear = Shear::new(r);
    let sheared = Sheared::new(&shear);
    let tmin = r.tmin;
    let mut tmax = r.tmax;
    let mut best = NO_HIT;
    let origin = [r.origin.x, r.origin.y, r.origin.z];
    let inv = [r.inv_direction.x, r.inv_direction.y, r.inv_direction.z];
    let negative = inv.map(|i| i < 0.0);
    let rinv = inv.map(|v| _mm256_set1_ps(v));
    let org_rinv = [0, 1, 2].map(|k| _mm256_set1_ps(origin[k] * inv[k]));
    let tmin_v = _mm256_set1_ps(tmin);

    // The reference visited now (entered within `tmax`), and the stack of
    // those entered but not visited yet.
    let mut current = bvh.root;
    let mut top = 0usize;
    'visit: loop {
        if current & LEAF != 0 {
            let first = (current & FIRST_MASK) as usize;
            let count = ((current & !LEAF) >> COUNT_SHIFT) as usize;
            for two in bvh.packs[first..first + count].chunks(2) {
                let (lo, hi) = (&two[0], &two[two.len() - 1]);
                let both = two.len() == 2;
                tmax = test_packs(
                    tracer, &sheared, &shear, lo, hi, both, target, tmin, tmax, &mut best,
                );
            }
        } else {
            let node = &bvh.nodes[current as usize];
            let slab = |k: usize| {
                let (near, far) = if negative[k] {
                    (&node.hi[k], &node.lo[k])
                } else {
                    (&node.lo[k], &node.hi[k])
                };
                (
                    _mm256_fmsub_ps(load(near), rinv[k], org_rinv[k]),
                    _mm256_fmsub_ps(load(far), rinv[k], org_rinv[k]),
                )
            };
            let (nx, fx) = slab(0);
            let (ny, fy) = slab(1);
            let (nz, fz) = slab(2);
            let near = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, tmin_v));
            let far = _mm256_min_ps(
                _mm256_min_ps(fx, fy),
                _mm256_min_ps(fz, _mm256_set1_ps(tmax)),
            );
            let mut mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
            if mask & mask.wrapping_sub(1) == 0 && mask != 0 {
                // One child entered: visit it next, no stack.
                current = node.child[mask.trailing_zeros() as usize % WIDTH];
                continue 'visit;
            }
            if mask != 0 {
                let near: [f32; WIDTH] = bytemuck::cast(near);
                // Push the children entered, ordered so that the nearest
                // is on top, then visit it.
                let base = top;
                while mask != 0 {
                    let lane = mask.trailing_zeros() as usize % WIDTH;
                    mask &= mask - 1;
                    let entry = (node.child[lane], near[lane]);
                    prefetch(bvh, entry.0);
                    // Insertion among the new entries, farthest at the
                    // bottom.
                    let mut at = top;
                    while at > base && stack[(at - 1) % STACK].1 < entry.1 {
                        stack[at % STACK] = stack[(at - 1) % STACK];
                        at -= 1;
                    }
                    stack[at % STACK] = entry;
                    top += 1;
                }
                top -= 1;
                current = stack[top % STACK].0;
                continue 'visit;
            }
        }
        // The next entry that starts within `tmax`.
        loop {
            if top == 0 {
                break 'visit;
            }
            top -= 1;
            let (reference, enter) = stack[top % STACK];
            if enter <= tmax {
                current = reference;
                continue 'visit;
            }
        }
    }
    tracer.hit(best, scaled.t_factor)
}

/// A [`Shear`] as registers: the origin's coordinates in the sheared
/// frame's axis order, and the shear's three factors, in every lane.
struct Sheared {
    origin: [__m256; 3],
    s: [__m256; 3],
}

impl Sheared {
    #[inline]
    #[target_feature(enable = "avx")]
    fn new(shear: &Shear) -> Self {
        let o = shear.origin;
        Self {
            origin: shear.k.map(|k| _mm256_set1_ps(o[k])),
            s: shear.s.map(|s| _mm256_set1_ps(s)),
        }
    }
}

/// [`Tracer::offer`] of each triangle of packs `lo` and `hi` (lanes 0-3
/// and 4-7; `hi` counts only when `both`), the watertight test of
/// [`Shear::intersect`] run on all lanes at once with the same operations
/// in the same order (so the same `t`, bit for bit); a lane with an edge
/// function of zero is left to the scalar test, which decides it in f64.
#[inline(never)]
#[target_feature(enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[allow(clippy::too_many_arguments)]
fn test_packs(
    tracer: &Tracer,
    sheared: &Sheared,
    shear: &Shear,
    lo: &Pack,
    hi: &Pack,
    both: bool,
    target: u32,
    tmin: f32,
    mut tmax: f32,
    best: &mut (f32, u32),
) -> f32 {
    let [kx, ky, kz] = shear.k;
    let [ox, oy, oz] = sheared.origin;
    let [sx, sy, sz] = sheared.s;
    let ld = |k: usize, axis: usize| -> __m256 { bytemuck::cast([lo.v[k][axis], hi.v[k][axis]]) };
    // A corner's sheared x and y, and its z scaled by the shear's sz.
    let corner = |k: usize| {
        let x = _mm256_sub_ps(ld(k, kx), ox);
        let y = _mm256_sub_ps(ld(k, ky), oy);
        let z = _mm256_sub_ps(ld(k, kz), oz);
        (
            _mm256_sub_ps(x, _mm256_mul_ps(sx, z)),
            _mm256_sub_ps(y, _mm256_mul_ps(sy, z)),
            _mm256_mul_ps(sz, z),
        )
    };
    let (ax, ay, az) = corner(0);
    let (bx, by, bz) = corner(1);
    let (cx, cy, cz) = corner(2);
    let u = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
    let v = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
    let w = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));
    let zero = _mm256_setzero_ps();
    let cmp_any = |f: fn(__m256, __m256) -> __m256| {
        _mm256_or_ps(_mm256_or_ps(f(u, zero), f(v, zero)), f(w, zero))
    };
    let on_edge = cmp_any(|a, b| _mm256_cmp_ps::<_CMP_EQ_OQ>(a, b));
    let negative = cmp_any(|a, b| _mm256_cmp_ps::<_CMP_LT_OQ>(a, b));
    let positive = cmp_any(|a, b| _mm256_cmp_ps::<_CMP_GT_OQ>(a, b));
    let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
    let tt = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(u, az), _mm256_mul_ps(v, bz)),
        _mm256_mul_ps(w, cz),
    );
    // Both negated where det < 0 (det == 0 is no hit).
    let sign = _mm256_and_ps(det, _mm256_set1_ps(-0.0));
    let tt = _mm256_xor_ps(tt, sign);
    let det = _mm256_xor_ps(det, sign);
    let t = _mm256_div_ps(tt, det);
    let inside = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GE_OQ>(t, _mm256_set1_ps(tmin)),
        _mm256_cmp_ps::<_CMP_LE_OQ>(t, _mm256_set1_ps(tmax)),
    );
    let miss = _mm256_or_ps(
        _mm256_and_ps(negative, positive),
        _mm256_cmp_ps::<_CMP_EQ_OQ>(det, zero),
    );
    let lanes = if both { 0xff } else { 0x0f };
    let mut hits =
        _mm256_movemask_ps(_mm256_andnot_ps(_mm256_or_ps(miss, on_edge), inside)) as u32 & lanes;
    let mut edges = _mm256_movemask_ps(on_edge) as u32 & lanes;
    if hits | edges == 0 {
        return tmax;
    }
    let t: [f32; 2 * LANES] = bytemuck::cast(t);
    let pack = |lane: usize| {
        if lane < LANES {
            (lo, lane)
        } else {
            (hi, lane - LANES)
        }
    };
    let limit = tmax;
    while hits != 0 {
        let lane = hits.trailing_zeros() as usize;
        hits &= hits - 1;
        let (p, l) = pack(lane);
        if tracer.passes_through(p.object[l], target) {
            continue;
        }
        let (t, id) = (t[lane], p.id[l]);
        if t < best.0 || (t == best.0 && id < best.1) {
            *best = (t, id);
        }
        if t < tmax {
            tmax = t;
        }
    }
    while edges != 0 {
        let lane = edges.trailing_zeros() as usize;
        edges &= edges - 1;
        let (p, l) = pack(lane);
        // The lanes above were tested within `limit`; so is this one.
        let mut lane_tmax = limit;
        tracer.offer(shear, &p.tri(l), target, tmin, &mut lane_tmax, best);
        if lane_tmax < tmax {
            tmax = lane_tmax;
        }
    }
    tmax
}
