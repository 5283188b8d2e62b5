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
//! children and putting its two children in its place.
//!
//! Exact, as the other traversal is: the boxes are the padded boxes of
//! the triangles (`BOX_PAD`) and their unions, unrounded; the slab test
//! is `(plane - origin) * inverse` per axis, as obvhs's, on the same scaled
//! ray ([`super::ScaledRay`]); an entry is dropped only when it starts
//! strictly beyond the ray's `tmax`, so the triangles tied at the closest
//! `t` are all tested and the tie goes to the lowest index. The answers
//! are the other traversal's bit for bit
//! (`trace::the_wide_and_the_portable_tracer_agree`, and the brute-force
//! tests).

use std::arch::x86_64::*;

use obvhs::bvh2::Bvh2;

use super::{Hit, NO_HIT, Ray, ScaledRay, Shear, Tracer, Tri};

/// Children a node has at most.
const WIDTH: usize = 8;

/// Triangles a leaf holds at most.
pub(super) const LEAF_MAX: u32 = 2;

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
    tris: Vec<Tri>,
    /// The root's reference (a node, or a leaf for a scene of few
    /// triangles).
    root: u32,
}

impl std::fmt::Debug for Bvh8 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh8")
            .field("nodes", &self.nodes.len())
            .field("triangles", &self.tris.len())
            .finish()
    }
}

impl Bvh8 {
    /// The wide BVH of `bvh` (a binary BVH over the padded boxes of
    /// `scene_tris`, in scene order, with at most [`LEAF_MAX`] triangles a
    /// leaf), or `None` when it has no triangles or its traversal could
    /// need more than the stack holds.
    pub(super) fn new(bvh: &Bvh2, scene_tris: &[Tri]) -> Option<Self> {
        let leaf = |n: &obvhs::bvh2::node::Bvh2Node, tris: &mut Vec<Tri>| {
            let first = tris.len() as u32;
            let range = n.first_index as usize..(n.first_index + n.prim_count) as usize;
            tris.extend(
                bvh.primitive_indices[range]
                    .iter()
                    .map(|&i| scene_tris[i as usize]),
            );
            LEAF | (n.prim_count << COUNT_SHIFT) | first
        };
        if bvh.nodes.is_empty()
            || bvh.primitive_indices.len() > FIRST_MASK as usize
            || bvh.nodes.iter().any(|n| n.prim_count > 15)
        {
            return None;
        }
        let mut tris = Vec::with_capacity(bvh.primitive_indices.len());
        let mut nodes = Vec::new();
        if bvh.nodes[0].is_leaf() {
            let root = leaf(&bvh.nodes[0], &mut tris);
            return Some(Self { nodes, tris, root });
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
                    leaf(n, &mut tris)
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
            tris,
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
        let p = bvh.tris[first..].as_ptr().cast::<u8>();
        line(p);
        line(p.wrapping_add(64));
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
    let tmin = r.tmin;
    let mut tmax = r.tmax;
    let mut best = NO_HIT;
    let origin = [r.origin.x, r.origin.y, r.origin.z];
    let inv = [r.inv_direction.x, r.inv_direction.y, r.inv_direction.z];
    let negative = inv.map(|i| i < 0.0);
    let org = origin.map(|v| _mm256_set1_ps(v));
    let rinv = inv.map(|v| _mm256_set1_ps(v));
    let tmin_v = _mm256_set1_ps(tmin);

    let mut top = 1usize;
    stack[0] = (bvh.root, tmin);
    while top > 0 {
        top -= 1;
        let (reference, enter) = stack[top];
        if enter > tmax {
            continue;
        }
        if reference & LEAF != 0 {
            let first = (reference & FIRST_MASK) as usize;
            let count = ((reference & !LEAF) >> COUNT_SHIFT) as usize;
            for tri in &bvh.tris[first..first + count] {
                tracer.offer(&shear, tri, target, tmin, &mut tmax, &mut best);
            }
            continue;
        }
        let node = &bvh.nodes[reference as usize];
        let slab = |k: usize| {
            let (near, far) = if negative[k] {
                (&node.hi[k], &node.lo[k])
            } else {
                (&node.lo[k], &node.hi[k])
            };
            (
                _mm256_mul_ps(_mm256_sub_ps(load(near), org[k]), rinv[k]),
                _mm256_mul_ps(_mm256_sub_ps(load(far), org[k]), rinv[k]),
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
        if mask == 0 {
            continue;
        }
        let near: [f32; WIDTH] = bytemuck::cast(near);
        // Push the children entered, then order the new entries so that
        // the nearest is on top.
        let base = top;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let entry = (node.child[lane], near[lane]);
            prefetch(bvh, entry.0);
            // Insertion among the new entries, farthest at the bottom.
            let mut at = top;
            while at > base && stack[at - 1].1 < entry.1 {
                stack[at] = stack[at - 1];
                at -= 1;
            }
            stack[at] = entry;
            top += 1;
        }
    }
    tracer.hit(best, scaled.t_factor)
}
