//! The bounding-box hierarchy over objects' boxes, built once per scene
//! and shared by the oracle (to prove many occludees hidden with one box
//! where they are hidden together) and the lazy occlusion grid (traversed
//! front to back).
//!
//! Built top-down: a node's objects are split at the median of their box
//! centres along the axis where the centres spread most (ties by object
//! index), down to one object per leaf ([`BoxTree::for_segments`] splits
//! by the surface area heuristic instead, for walks along segments). Deterministic: the same boxes give
//! the same tree. Empty boxes ([`Aabb::is_empty`]: objects without
//! triangles) are left out: they overlap nothing, are never marked, and
//! their centres (infinite sums) would not sort.

use crate::bitset::ObjectSet;
use crate::geom::Aabb;
use crate::invariant::InvariantError;

/// A node of a [`BoxTree`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BoxNode {
    /// One object, whose box is the node's.
    Object {
        /// The object's box.
        bounds: Aabb,
        /// The object's index.
        object: u32,
    },
    /// Two children, as indices into [`BoxTree::nodes`].
    Inner {
        /// The union of the children's boxes.
        bounds: Aabb,
        /// The children.
        children: [u32; 2],
    },
}

impl BoxNode {
    /// The node's box.
    pub fn bounds(&self) -> &Aabb {
        match self {
            BoxNode::Object { bounds, .. } | BoxNode::Inner { bounds, .. } => bounds,
        }
    }
}

/// A binary hierarchy of object boxes, root first (empty for no objects,
/// or none with a non-empty box).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BoxTree {
    nodes: Vec<BoxNode>,
}

impl BoxTree {
    /// The hierarchy over `boxes` (object `i`'s box is `boxes[i]`), the
    /// empty ones left out.
    pub fn new(boxes: &[Aabb]) -> Self {
        let mut ids: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| !boxes[i as usize].is_empty())
            .collect();
        let mut nodes = Vec::with_capacity(2 * ids.len());
        if !ids.is_empty() {
            build(boxes, &mut nodes, &mut ids, 0, median_split);
        }
        Self { nodes }
    }

    /// The hierarchy over `boxes` for walks along segments: each node's
    /// objects split where the surface area heuristic puts the cut (16
    /// bins of box centres per axis; at the median deeper than 48 levels or
    /// where all centres share a bin), so that a segment meets fewer
    /// boxes than in [`BoxTree::new`]'s median splits where objects of
    /// very different sizes mix (a city's buildings among its terrain's
    /// polygons). Deterministic, and the empty boxes left out, likewise.
    pub fn for_segments(boxes: &[Aabb]) -> Self {
        let mut ids: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| !boxes[i as usize].is_empty())
            .collect();
        let mut nodes = Vec::with_capacity(2 * ids.len());
        if !ids.is_empty() {
            build(boxes, &mut nodes, &mut ids, 0, sah_split);
        }
        Self { nodes }
    }

    /// The nodes; the root is the first.
    pub fn nodes(&self) -> &[BoxNode] {
        &self.nodes
    }

    /// Marks in `out` every object under a node whose box passes `test`,
    /// descending into the children of the nodes that fail it (an object
    /// whose own box fails is not marked). Each node is tested at most
    /// once.
    pub fn mark_where(&self, test: &dyn Fn(&Aabb) -> bool, out: &mut ObjectSet) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![0u32];
        while let Some(k) = stack.pop() {
            let node = &self.nodes[k as usize];
            if test(node.bounds()) {
                self.mark_all(k, out);
            } else if let BoxNode::Inner { children, .. } = node {
                stack.extend_from_slice(children);
            }
        }
    }

    /// Appends to `out` every object whose box overlaps `b` (closed boxes:
    /// touching counts), in the tree's order.
    pub fn overlapping(&self, b: &Aabb, out: &mut Vec<u32>) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![0u32];
        while let Some(k) = stack.pop() {
            let node = &self.nodes[k as usize];
            if !node.bounds().overlaps(b) {
                continue;
            }
            match node {
                BoxNode::Object { object, .. } => out.push(*object),
                BoxNode::Inner { children, .. } => stack.extend_from_slice(children),
            }
        }
    }

    /// Marks every object under node `k`.
    fn mark_all(&self, k: u32, out: &mut ObjectSet) {
        let mut stack = vec![k];
        while let Some(k) = stack.pop() {
            match &self.nodes[k as usize] {
                BoxNode::Object { object, .. } => {
                    out.insert(*object as usize);
                }
                BoxNode::Inner { children, .. } => stack.extend_from_slice(children),
            }
        }
    }

    /// Checks the invariants for `boxes` (those it was built from): every
    /// object of a non-empty box in exactly one leaf holding its box (and
    /// no other object), every inner box the union of its children's,
    /// every node reached once from the root.
    pub fn validate(&self, boxes: &[Aabb]) -> Result<(), InvariantError> {
        self.check(boxes)
            .map_err(|what| InvariantError::new("box hierarchy", what))
    }

    fn check(&self, boxes: &[Aabb]) -> Result<(), String> {
        let mut seen = vec![false; boxes.len()];
        let mut reached = vec![false; self.nodes.len()];
        let mut stack = if self.nodes.is_empty() {
            vec![]
        } else {
            vec![0u32]
        };
        while let Some(k) = stack.pop() {
            let Some(r) = reached.get_mut(k as usize) else {
                return Err(format!("node {k} does not exist"));
            };
            if std::mem::replace(r, true) {
                return Err(format!("node {k} is reached twice"));
            }
            match self.nodes[k as usize] {
                BoxNode::Object { bounds, object } => {
                    let o = object as usize;
                    if o >= boxes.len()
                        || boxes[o].is_empty()
                        || std::mem::replace(&mut seen[o], true)
                    {
                        return Err(format!("object {object} is missing or repeated"));
                    }
                    if bounds != boxes[o] {
                        return Err(format!("object {object}'s leaf has another box"));
                    }
                }
                BoxNode::Inner { bounds, children } => {
                    let [a, b] = children.map(|c| self.nodes.get(c as usize).map(|n| *n.bounds()));
                    match (a, b) {
                        (Some(a), Some(b)) if a.union(&b) == bounds => {}
                        _ => return Err(format!("node {k}'s box is not its children's union")),
                    }
                    stack.extend_from_slice(&children);
                }
            }
        }
        let listed = |(o, &s): (usize, &bool)| s || boxes[o].is_empty();
        if !seen.iter().enumerate().all(listed) || !reached.iter().all(|&r| r) {
            return Err("an object or a node is not reached from the root".into());
        }
        Ok(())
    }
}

/// How a node's objects are split: puts those of one child first in
/// `ids` and returns where the other's start; given the node's depth.
type Split = fn(&[Aabb], &mut [u32], usize) -> usize;

/// Builds the subtree over `ids` (at `depth`) at the end of `nodes`,
/// each node's objects split by `split`; returns its index.
fn build(
    boxes: &[Aabb],
    nodes: &mut Vec<BoxNode>,
    ids: &mut [u32],
    depth: usize,
    split: Split,
) -> u32 {
    let bounds = ids
        .iter()
        .fold(Aabb::EMPTY, |b, &o| b.union(&boxes[o as usize]));
    let me = nodes.len() as u32;
    if let [object] = *ids {
        nodes.push(BoxNode::Object { bounds, object });
        return me;
    }
    nodes.push(BoxNode::Inner {
        bounds,
        children: [0, 0],
    });
    let mid = split(boxes, ids, depth);
    let (left, right) = ids.split_at_mut(mid);
    let l = build(boxes, nodes, left, depth + 1, split);
    let r = build(boxes, nodes, right, depth + 1, split);
    nodes[me as usize] = BoxNode::Inner {
        bounds,
        children: [l, r],
    };
    me
}

/// [`BoxTree::new`]'s split: at the median of the box centres along the
/// axis where they spread most.
fn median_split(boxes: &[Aabb], ids: &mut [u32], _depth: usize) -> usize {
    let centres = Aabb::from_points(ids.iter().map(|&o| boxes[o as usize].center()));
    split_at_median(boxes, ids, centres.size().max_position())
}

/// Puts the half of `ids` whose box centres are lowest along `axis` (ties
/// by object index) first; returns where the other half starts.
fn split_at_median(boxes: &[Aabb], ids: &mut [u32], axis: usize) -> usize {
    let mid = ids.len() / 2;
    ids.select_nth_unstable_by(mid, |&a, &b| {
        let (ca, cb) = (
            boxes[a as usize].center()[axis],
            boxes[b as usize].center()[axis],
        );
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    mid
}

/// Below this depth [`BoxTree::for_segments`] splits at the median, so
/// that no tree is deeper than it plus `log2` of its objects.
const SAH_DEPTH: usize = 48;

/// Half the surface area of `b`.
fn half_area(b: &Aabb) -> f32 {
    let s = b.size();
    s.x * s.y + s.y * s.z + s.z * s.x
}

/// [`BoxTree::for_segments`]'s split: where the surface area heuristic
/// puts the cut (the median past [`SAH_DEPTH`]).
fn sah_split(boxes: &[Aabb], ids: &mut [u32], depth: usize) -> usize {
    const BINS: usize = 16;
    let centres = Aabb::from_points(ids.iter().map(|&o| boxes[o as usize].center()));
    let (lo, size) = (centres.min, centres.size());
    let bin = |o: u32, axis: usize| {
        let t = (boxes[o as usize].center()[axis] - lo[axis]) / size[axis];
        ((t * BINS as f32) as usize).min(BINS - 1)
    };
    // The cheapest cut: after bin `i` along `axis`, by the areas of the
    // two sides' boxes times their counts.
    let mut best: Option<(f32, usize, usize)> = None;
    if depth < SAH_DEPTH {
        for axis in 0..3 {
            if size[axis] <= 0.0 || !size[axis].is_finite() {
                continue;
            }
            let mut counts = [0usize; BINS];
            let mut bins = [Aabb::EMPTY; BINS];
            for &o in ids.iter() {
                let k = bin(o, axis);
                counts[k] += 1;
                bins[k] = bins[k].union(&boxes[o as usize]);
            }
            let mut right = [0.0f32; BINS];
            let (mut r, mut n) = (Aabb::EMPTY, 0);
            for k in (1..BINS).rev() {
                r = r.union(&bins[k]);
                n += counts[k];
                right[k] = if n == 0 {
                    f32::NAN
                } else {
                    half_area(&r) * n as f32
                };
            }
            let (mut l, mut n) = (Aabb::EMPTY, 0);
            for k in 0..BINS - 1 {
                l = l.union(&bins[k]);
                n += counts[k];
                let cost = half_area(&l) * n as f32 + right[k + 1];
                if n > 0 && cost.is_finite() && best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, k));
                }
            }
        }
    }
    match best {
        Some((_, axis, k)) => {
            // Those in bins up to `k` first, in their order.
            let mut mid = 0;
            for i in 0..ids.len() {
                if bin(ids[i], axis) <= k {
                    ids.swap(i, mid);
                    mid += 1;
                }
            }
            mid
        }
        None => split_at_median(boxes, ids, size.max_position()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn boxes(n: usize) -> Vec<Aabb> {
        (0..n)
            .map(|i| {
                let c = Vec3::new((i * 7 % 13) as f32, (i * 3 % 5) as f32, (i % 4) as f32);
                Aabb::new(c, c + Vec3::splat(0.5 + (i % 3) as f32))
            })
            .collect()
    }

    #[test]
    fn every_object_once_and_boxes_nest() {
        for n in [0, 1, 2, 3, 17, 100] {
            let b = boxes(n);
            let t = BoxTree::new(&b);
            t.validate(&b).unwrap();
            assert_eq!(t.nodes().len(), (2 * n).saturating_sub(1));
        }
    }

    #[test]
    fn the_segments_tree_holds_every_object_once_and_stays_shallow() {
        for n in [0, 1, 2, 3, 17, 100, 1000] {
            let b = boxes(n);
            let t = BoxTree::for_segments(&b);
            t.validate(&b).unwrap();
            assert_eq!(t.nodes().len(), (2 * n).saturating_sub(1));
        }
        // Boxes whose centres crowd at one end (each twice as far as the
        // last from the origin) would make a surface-area split peel one
        // off at a time: the median takes over, so the depth stays bounded.
        let b: Vec<Aabb> = (0..400)
            .map(|i| {
                let c = Vec3::splat(1.02f32.powi(i));
                Aabb::new(c, c + Vec3::splat(0.01))
            })
            .collect();
        let t = BoxTree::for_segments(&b);
        t.validate(&b).unwrap();
        let mut deepest = 0;
        let mut stack = vec![(0u32, 0usize)];
        while let Some((k, d)) = stack.pop() {
            deepest = deepest.max(d);
            if let BoxNode::Inner { children, .. } = t.nodes()[k as usize] {
                stack.extend(children.map(|c| (c, d + 1)));
            }
        }
        assert!(deepest <= SAH_DEPTH + 10, "{deepest}");
        // The same boxes give the same tree.
        assert_eq!(t.nodes(), BoxTree::for_segments(&b).nodes());
    }

    #[test]
    fn empty_boxes_are_left_out() {
        let mut b = boxes(9);
        for i in [0, 4, 8] {
            b[i] = Aabb::EMPTY;
        }
        let t = BoxTree::new(&b);
        t.validate(&b).unwrap();
        assert_eq!(t.nodes().len(), 2 * 6 - 1);
        let mut all = ObjectSet::new(b.len());
        t.mark_where(&|_| true, &mut all);
        assert_eq!(all.iter().collect::<Vec<_>>(), [1, 2, 3, 5, 6, 7]);
        let mut near = Vec::new();
        t.overlapping(&Aabb::new(Vec3::splat(-1e9), Vec3::splat(1e9)), &mut near);
        assert_eq!(near.len(), 6);
        let none = [Aabb::EMPTY; 3];
        let t = BoxTree::new(&none);
        t.validate(&none).unwrap();
        assert!(t.nodes().is_empty());
    }

    /// Marking equals a linear scan of the objects when the test is
    /// monotone (a box passes whenever a box holding it does).
    #[test]
    fn marking_equals_a_linear_scan_for_monotone_tests() {
        let b = boxes(100);
        let t = BoxTree::new(&b);
        for limit in [-1.0, 2.0, 5.0, 9.0, 20.0] {
            let test = |x: &Aabb| x.max.x <= limit;
            let mut marked = ObjectSet::new(b.len());
            t.mark_where(&test, &mut marked);
            for (i, x) in b.iter().enumerate() {
                assert_eq!(marked.contains(i), test(x), "object {i} limit {limit}");
            }
        }
    }
}
