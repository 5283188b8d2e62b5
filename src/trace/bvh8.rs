//! The tracer's BVH: eight children a node with full-precision f32
//! boxes, and a stack of entries ordered by entry distance, so that the
//! nearest child is visited first and a popped entry that starts beyond
//! the ray's closest hit so far is dropped without reading it (the design
//! of CPU ray tracers such as Embree's BVH8; Wald, Benthin and Boulos
//! 2008, *Getting rid of packets*).
//!
//! The nodes are built from obvhs's binary BVH (its PLOC build and
//! reinsertion) by the surface-area-optimal widening of Ylitie, Karras
//! and Laine (2017), which also decides the leaves (at most [`LEAF_MAX`]
//! triangles). A leaf's triangles are stored in one or two [`Pack`]s of
//! four (corners by axis and lane, as Embree's `Triangle4`).
//!
//! Two traversals: on CPUs with AVX2, [`avx2`] tests a node's eight boxes
//! in one 256-bit pass and a leaf's triangles in another, and visits the
//! nearest child entered next without a trip through the stack; on any
//! CPU, [`Bvh8::walk`] does the same in plain code, one box and one
//! triangle at a time. (obvhs's own compressed wide BVH, `CwBvh`, was the
//! portable traversal until 2026-12-05: made for GPUs, it decodes 8-bit
//! child boxes at each visit, never drops an entry by distance, and
//! starts its box tests at a fixed `t = 1e-4`, which missed hits that
//! close to the origin.)
//!
//! Exact, in both traversals:
//! - the boxes are the padded boxes of the triangles (`BOX_PAD`) and
//!   their unions, unrounded;
//! - the slab test is `plane * inverse - origin * inverse` per axis in
//!   the AVX2 code, one fused multiply-subtract, and `(plane - origin) *
//!   inverse` in the portable code (as obvhs's), on the same scaled ray
//!   ([`super::ScaledRay`]). The fused form's rounding moves a plane by at
//!   most `2^-24 (|origin| + 2 |plane - origin|)` along its axis, the
//!   other's by `3 * 2^-24 |plane - origin|`: both under the padding for
//!   origins within about fifty times the scene's rounding scale;
//! - an entry is dropped only when it starts strictly beyond the ray's
//!   `tmax`, so the triangles tied at the closest `t` are all tested and
//!   the tie goes to the lowest index;
//! - the packed triangle test does the scalar test's operations in the
//!   same order on every lane, and leaves a lane with an edge function of
//!   zero to the scalar test (which decides it in f64).
//!
//! The answers are the same bit for bit in both, and the brute force's
//! (`trace::the_wide_and_the_portable_tracer_agree`, and the brute-force
//! tests).

use obvhs::bvh2::Bvh2;

use super::huge::HugeArray;
use super::{Hit, NO_HIT, Ray, ScaledRay, Shear, Tracer, Tri};

#[cfg(target_arch = "x86_64")]
pub(super) mod avx2;

/// Children a node has at most.
const WIDTH: usize = 8;

/// Triangles a leaf holds at most: two [`Pack`]s, tested together.
pub(super) const LEAF_MAX: u32 = 2 * LANES as u32;

/// The cost of visiting a node (its eight box tests), per unit of its
/// area, in [`Bvh8::new`]'s surface area cost.
const NODE_COST: f32 = 1.0;

/// The cost of testing a leaf (one pass over its one or two packs), per
/// unit of its area: in `perf` of San Francisco's builder rays, a leaf
/// visit takes about 1.5 times a node visit. Costs from 1 to 4 trace
/// within 3% of each other (notes/trace.md, step 7).
const LEAF_COST: f32 = 1.5;

/// Triangles a [`Pack`] holds.
const LANES: usize = 4;

/// Up to [`LANES`] triangles of a leaf, by corner, axis and lane, for one
/// test of all of them (a leaf's two packs in one 256-bit pass in the
/// AVX2 code, one by one in the portable code); unused lanes have NaN
/// corners, which no ray hits, and the id [`NO_TRIANGLE`].
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct Pack {
    v: [[[f32; LANES]; 3]; 3],
    id: [u32; LANES],
    object: [u32; LANES],
}

impl Pack {
    const EMPTY: Self = Self {
        v: [[[f32::NAN; LANES]; 3]; 3],
        id: [NO_TRIANGLE; LANES],
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

/// Entries of the AVX2 traversal's stack. A BVH whose traversal could
/// need more (seven entries a level) is walked by the portable code,
/// whose stack grows.
const STACK: usize = 256;

/// A child reference with this bit is a leaf: `LEAF | [TWO] | first
/// pack`, with [`TWO`] when it has two packs.
const LEAF: u32 = 1 << 31;
/// A leaf reference with this bit has two packs, one without it.
const TWO: u32 = 1 << 30;
const FIRST_MASK: u32 = TWO - 1;

/// The packs of leaf reference `r`: (first, count).
#[inline(always)]
fn leaf_packs(r: u32) -> (usize, usize) {
    ((r & FIRST_MASK) as usize, 1 + ((r & TWO) >> 30) as usize)
}

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
    /// The children's bounds as six rows: the lower bounds along x, y
    /// and z, then the upper ones (row `3 + k` is `hi[k]`).
    #[inline(always)]
    fn rows(&self) -> &[[f32; WIDTH]; 6] {
        const _: () = assert!(std::mem::offset_of!(Node, hi) == 3 * WIDTH * 4);
        // SAFETY: `Node` is `repr(C)`: `lo` and `hi` are six `[f32;
        // WIDTH]` in a row from its start (the assertion above), with the
        // alignment of `f32`.
        unsafe { &*(self as *const Self).cast::<[[f32; WIDTH]; 6]>() }
    }

    const EMPTY: Self = Self {
        lo: [[f32::INFINITY; WIDTH]; 3],
        hi: [[f32::NEG_INFINITY; WIDTH]; 3],
        child: [NONE; WIDTH],
    };
}

/// The eight-wide BVH and its triangles in leaf order.
pub(super) struct Bvh8 {
    nodes: HugeArray<Node>,
    packs: HugeArray<Pack>,
    /// The root's reference (a node, or a leaf for a scene of few
    /// triangles).
    root: u32,
    /// Whether a traversal never needs more than 256 stack entries (seven
    /// a level): the AVX2 traversal's condition.
    fits_stack: bool,
}

impl std::fmt::Debug for Bvh8 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh8")
            .field("nodes", &self.nodes.len())
            .field("packs", &self.packs.len())
            .finish()
    }
}

/// Appends the packs of a leaf of triangles `prims` (scene indices, at
/// most [`LEAF_MAX`]) to `packs`; its reference.
fn push_leaf(prims: &[u32], scene_tris: &[Tri], packs: &mut Vec<Pack>) -> u32 {
    let first = packs.len() as u32;
    for chunk in prims.chunks(LANES) {
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
    let two = if packs.len() as u32 - first == 2 {
        TWO
    } else {
        0
    };
    LEAF | two | first
}

impl Bvh8 {
    /// The wide BVH of `bvh` (a binary BVH over the padded boxes of
    /// `scene_tris`, in scene order, with at most [`LEAF_MAX`] triangles a
    /// leaf; at least one triangle, and at most
    /// [`MAX_TRIANGLES`](crate::scene::MAX_TRIANGLES)), shaped to the
    /// least surface area cost by the dynamic programme of Ylitie, Karras
    /// and Laine (2017, *Efficient incoherent ray traversal on GPUs
    /// through compressed wide BVHs*): for each binary node, bottom up,
    /// the cheapest way to stand as one leaf (at most [`LEAF_MAX`]
    /// triangles, cost [`LEAF_COST`] times its area), as one wide node
    /// ([`NODE_COST`] times its area plus its children's), or as up to
    /// eight roots among its parent's children.
    ///
    /// # Panics
    /// When `bvh` has no triangles, more than that or larger leaves.
    pub(super) fn new(bvh: &Bvh2, scene_tris: &[Tri]) -> Self {
        let n = bvh.nodes.len();
        assert!(
            n > 0 && bvh.primitive_indices.len() <= FIRST_MASK as usize,
            "the tracer takes 1 to 2^30 triangles, not {}",
            bvh.primitive_indices.len()
        );
        let mut order = Vec::with_capacity(n);
        let mut todo = vec![0usize];
        while let Some(i) = todo.pop() {
            order.push(i);
            let node = &bvh.nodes[i];
            if !node.is_leaf() {
                todo.push(node.first_index as usize);
                todo.push(node.first_index as usize + 1);
            }
        }
        // cost[i][j - 1]: node i's subtree as at most j roots; split[i][j -
        // 1]: 0 for one root, else the roots its left child gets.
        let mut cost = vec![[f32::INFINITY; WIDTH]; n];
        let mut split = vec![[0u8; WIDTH]; n];
        let mut prims = vec![0u32; n];
        let mut as_leaf = vec![false; n];
        let mut wide_split = vec![0u8; n];
        for &i in order.iter().rev() {
            let node = &bvh.nodes[i];
            let area = node.aabb().half_area();
            if node.is_leaf() {
                assert!(
                    node.prim_count <= LEAF_MAX,
                    "leaves of at most {LEAF_MAX} triangles"
                );
                prims[i] = node.prim_count;
                as_leaf[i] = true;
                cost[i] = [area * LEAF_COST; WIDTH];
                continue;
            }
            let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
            prims[i] = prims[l] + prims[r];
            let (cl, cr) = (cost[l], cost[r]);
            let pair = |j: usize| {
                (1..j)
                    .map(|k| (cl[k - 1] + cr[j - k - 1], k as u8))
                    .fold((f32::INFINITY, 0u8), |a, b| if b.0 < a.0 { b } else { a })
            };
            let (children, k) = pair(WIDTH);
            let wide = area * NODE_COST + children;
            let leaf = if prims[i] <= LEAF_MAX {
                area * LEAF_COST
            } else {
                f32::INFINITY
            };
            let one = if leaf <= wide {
                as_leaf[i] = true;
                leaf
            } else {
                wide_split[i] = k;
                wide
            };
            cost[i][0] = one;
            for j in 2..=WIDTH {
                let (c, k) = pair(j);
                (cost[i][j - 1], split[i][j - 1]) = if c < one { (c, k) } else { (one, 0) };
            }
        }
        // The binary nodes that stand as roots when node i gets j.
        fn roots(bvh: &Bvh2, split: &[[u8; WIDTH]], i: usize, j: usize, out: &mut Vec<usize>) {
            let k = split[i][j - 1] as usize;
            if k == 0 {
                out.push(i);
            } else {
                let l = bvh.nodes[i].first_index as usize;
                roots(bvh, split, l, k, out);
                roots(bvh, split, l + 1, j - k, out);
            }
        }
        let subtree_prims = |i: usize| {
            let mut out = Vec::new();
            let mut todo = vec![i];
            while let Some(m) = todo.pop() {
                let node = &bvh.nodes[m];
                if node.is_leaf() {
                    let f = node.first_index as usize;
                    out.extend_from_slice(&bvh.primitive_indices[f..f + node.prim_count as usize]);
                } else {
                    todo.push(node.first_index as usize + 1);
                    todo.push(node.first_index as usize);
                }
            }
            out
        };
        let mut packs = Vec::with_capacity(bvh.primitive_indices.len().div_ceil(LANES));
        let mut nodes = Vec::new();
        if as_leaf[0] {
            let root = push_leaf(&subtree_prims(0), scene_tris, &mut packs);
            return Self {
                nodes: HugeArray::from_slice(&nodes),
                packs: HugeArray::from_slice(&packs),
                root,
                fits_stack: true,
            };
        }
        let mut work = vec![(0usize, 0usize, 1usize)];
        nodes.push(Node::EMPTY);
        let mut depth = 1;
        let mut kids = Vec::with_capacity(WIDTH);
        while let Some((b, slot, d)) = work.pop() {
            depth = depth.max(d);
            let l = bvh.nodes[b].first_index as usize;
            let k = wide_split[b] as usize;
            kids.clear();
            roots(bvh, &split, l, k, &mut kids);
            roots(bvh, &split, l + 1, WIDTH - k, &mut kids);
            let mut node = Node::EMPTY;
            for (lane, &m) in kids.iter().enumerate() {
                let bounds = bvh.nodes[m].aabb();
                for axis in 0..3 {
                    node.lo[axis][lane] = bounds.min[axis];
                    node.hi[axis][lane] = bounds.max[axis];
                }
                node.child[lane] = if as_leaf[m] {
                    push_leaf(&subtree_prims(m), scene_tris, &mut packs)
                } else {
                    let at = nodes.len();
                    nodes.push(Node::EMPTY);
                    work.push((m, at, d + 1));
                    at as u32
                };
            }
            nodes[slot] = node;
        }
        Self {
            nodes: HugeArray::from_slice(&nodes),
            packs: HugeArray::from_slice(&packs),
            root: 0,
            fits_stack: (WIDTH - 1) * depth < STACK,
        }
    }
}

impl Pack {
    /// Its triangles (the lanes in use).
    pub(super) fn triangles(&self) -> impl Iterator<Item = Tri> + '_ {
        (0..LANES)
            .filter(|&lane| self.id[lane] != NO_TRIANGLE)
            .map(|lane| self.tri(lane))
    }
}

/// The id of an unused lane of a [`Pack`].
const NO_TRIANGLE: u32 = u32::MAX;

impl Bvh8 {
    /// Calls `leaf` with each pack of every leaf whose box `r` enters
    /// within `[r.tmin, tmax]`, the nearest entries first, where `leaf`
    /// may lower `tmax` (to the closest hit so far); `stack` is scratch.
    /// The traversal for any CPU: the slab test is obvhs's `(plane -
    /// origin) * inverse` per axis, and an entry is dropped only when it
    /// starts beyond `tmax`, so every triangle that `r` hits within the
    /// final `tmax` is offered to `leaf`, as the AVX2 traversal offers
    /// it; the stack grows as deep as the tree needs.
    pub(super) fn walk(
        &self,
        r: &obvhs::ray::Ray,
        stack: &mut Vec<(u32, f32)>,
        mut leaf: impl FnMut(&Pack, &mut f32),
    ) {
        let origin = [r.origin.x, r.origin.y, r.origin.z];
        let inv = [r.inv_direction.x, r.inv_direction.y, r.inv_direction.z];
        let mut tmax = r.tmax;
        stack.clear();
        stack.push((self.root, r.tmin));
        while let Some((reference, enter)) = stack.pop() {
            if enter > tmax {
                continue;
            }
            if reference & LEAF != 0 {
                let (first, count) = leaf_packs(reference);
                for pack in &self.packs[first..first + count] {
                    leaf(pack, &mut tmax);
                }
                continue;
            }
            let node = &self.nodes[reference as usize];
            // The eight slab tests, axis by axis (loops the compiler can
            // vectorise; no value is NaN, so `>` and `<` pick as max and
            // min do).
            let mut near = [r.tmin; WIDTH];
            let mut far = [tmax; WIDTH];
            for k in 0..3 {
                let (a, b) = if inv[k] < 0.0 {
                    (&node.hi[k], &node.lo[k])
                } else {
                    (&node.lo[k], &node.hi[k])
                };
                for lane in 0..WIDTH {
                    let (ta, tb) = (
                        (a[lane] - origin[k]) * inv[k],
                        (b[lane] - origin[k]) * inv[k],
                    );
                    near[lane] = if ta > near[lane] { ta } else { near[lane] };
                    far[lane] = if tb < far[lane] { tb } else { far[lane] };
                }
            }
            // Push the children entered, the nearest on top.
            let base = stack.len();
            for lane in 0..WIDTH {
                if near[lane] <= far[lane] {
                    let entry = (node.child[lane], near[lane]);
                    stack.push(entry);
                    let mut at = stack.len() - 1;
                    while at > base && stack[at - 1].1 < entry.1 {
                        stack[at] = stack[at - 1];
                        at -= 1;
                    }
                    stack[at] = entry;
                }
            }
        }
    }
}

/// The closest hit of `ray` on an occluder or on `target` (see
/// [`Tracer::closest_hit_towards`]) by [`Bvh8::walk`], for any CPU, with
/// `stack` as scratch.
pub(super) fn closest_hit(
    tracer: &Tracer,
    bvh: &Bvh8,
    ray: &Ray,
    target: u32,
    stack: &mut Vec<(u32, f32)>,
) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let scaled = ScaledRay::new(ray, tracer.dir_exponent);
    let shear = Shear::new(&scaled.ray);
    let tmin = scaled.ray.tmin;
    let mut best = NO_HIT;
    bvh.walk(&scaled.ray, stack, |pack, tmax| {
        for tri in pack.triangles() {
            tracer.offer(&shear, &tri, target, tmin, tmax, &mut best);
        }
    });
    tracer.hit(best, scaled.t_factor)
}

impl Bvh8 {
    /// Whether a traversal never needs more than 256 stack entries (seven
    /// a level): the AVX2 traversal's condition.
    pub(super) fn fits_stack(&self) -> bool {
        self.fits_stack
    }
}
