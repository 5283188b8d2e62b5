//! The bounding-box hierarchy over objects' boxes, built once per scene
//! and shared by the oracle (to prove many occludees hidden with one box
//! where they are hidden together) and the lazy occlusion grid (traversed
//! front to back).
//!
//! Built top-down: a node's objects are split at the median of their box
//! centres along the axis where the centres spread most (ties by object
//! index), down to one object per leaf. Deterministic: the same boxes give
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
            build(boxes, &mut nodes, &mut ids);
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

/// Builds the subtree over `ids` at the end of `nodes`; returns its index.
fn build(boxes: &[Aabb], nodes: &mut Vec<BoxNode>, ids: &mut [u32]) -> u32 {
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
    let centres = Aabb::from_points(ids.iter().map(|&o| boxes[o as usize].center()));
    let axis = centres.size().max_position();
    let mid = ids.len() / 2;
    ids.select_nth_unstable_by(mid, |&a, &b| {
        let (ca, cb) = (
            boxes[a as usize].center()[axis],
            boxes[b as usize].center()[axis],
        );
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    let (left, right) = ids.split_at_mut(mid);
    let l = build(boxes, nodes, left);
    let r = build(boxes, nodes, right);
    nodes[me as usize] = BoxNode::Inner {
        bounds,
        children: [l, r],
    };
    me
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
