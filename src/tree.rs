//! The visibility tree in memory: a k-d tree over 5D view space whose every
//! node holds a potentially visible set (papers/003 sec. 4).
//!
//! Nodes are stored in preorder: node 0 is the root, an internal node's
//! first child ("below": `[lo, value)`) follows it, and its second child
//! ("above": `[value, hi)`) is at `Split::above`. A split is a dimension
//! and a code `k` on the q-bit grid of the node's range in that dimension:
//! the value is [`grid_value`]`(lo, hi, k, q)`, so cells are never stored,
//! only replayed from the root, and the decoder (issue #4) replays exactly
//! the builder's floats.
//!
//! Invariants ([`VisTree::validate`]): the preorder layout is consistent;
//! codes lie in `1..2^q`, so both children are non-empty; a child's set is
//! a subset of its parent's and an internal node's set is the union of its
//! children's; the leaves' cells tile the root (their measures sum to the
//! root's).

use crate::bitset::ObjectSet;
use crate::geom::cell::{Cell, DIMS, grid_value};
use crate::invariant::InvariantError;

/// The deepest a tree may be: the builder refuses deeper settings and the
/// decoder refuses deeper files, so recursion over a tree is bounded.
pub const MAX_DEPTH: u32 = 64;

/// The most bits a split code may have (the file format's limit).
pub const MAX_GRID_BITS: u32 = 16;

/// How a node is cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Split {
    /// The dimension: 0..3 = x, y, z, 3 = theta, 4 = phi.
    pub dim: u8,
    /// The split value's position on the q-bit grid of the node's range,
    /// in `1..2^q`.
    pub code: u32,
    /// The index of the second child (the first is the next node).
    pub above: u32,
}

/// One node: a set, and a split unless it is a leaf.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Node {
    /// `None` for a leaf.
    pub split: Option<Split>,
    /// The objects visible from some ray of the node's cell.
    pub set: ObjectSet,
}

/// A leaf with its cell, as [`VisTree::leaves`] lists them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafCell {
    /// The node index.
    pub node: usize,
    /// The node's cell.
    pub cell: Cell,
    /// The number of splits above it.
    pub depth: u32,
}

/// The shape of a tree and the sizes of its leaves' sets.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TreeSummary {
    /// All nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// The deepest leaf.
    pub depth: u32,
    /// The mean number of objects in a leaf's set.
    pub mean_leaf_objects: f64,
    /// The largest leaf set, in objects.
    pub max_leaf_objects: usize,
    /// The mean number of triangles in a leaf's set.
    pub mean_leaf_triangles: f64,
    /// The largest leaf set, in triangles.
    pub max_leaf_triangles: u64,
    /// The mean leaf set in objects, weighted by the leaves' measure: the
    /// expected set of a random view ray.
    pub measure_weighted_objects: f64,
}

/// How sure a leaf's set is: what the build's decisions for the leaf rest
/// on, so that a user can read the residual risk of a leaf
/// ([`LeafRecord::largest_missed_fraction`]). Stored per leaf in `.v5d`
/// files from version 3 (notes/format.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LeafRecord {
    /// Objects called invisible from the leaf's cell on ray evidence, by
    /// the leaf's own test or by an ancestor's (objects no direction of
    /// the cell reaches are not counted: that is proof, not evidence).
    pub rejected: u32,
    /// The fewest object samples, all misses, behind any of those
    /// rejections (0 when none was rejected).
    pub fewest_rays: u32,
    /// Objects kept in the set without a decision: their samples were
    /// almost all outside the cell's directions, or the test reached its
    /// ray cap (conservative: overdraw, not popping).
    pub undecided: u32,
}

impl LeafRecord {
    /// The largest visible fraction (of the object samples of the cell,
    /// papers/003's s) that an object called invisible could still have,
    /// with probability at least `1 - confidence` of getting only misses:
    /// `1 - (1 - confidence)^(1 / fewest_rays)`. 0 when nothing was
    /// rejected. With 0.95 and 200 rays, 1.5%.
    pub fn largest_missed_fraction(&self, confidence: f64) -> f64 {
        if self.rejected == 0 || self.fewest_rays == 0 {
            return if self.rejected == 0 { 0.0 } else { 1.0 };
        }
        1.0 - (1.0 - confidence.clamp(0.0, 1.0)).powf(1.0 / self.fewest_rays as f64)
    }
}

/// A 5D k-d tree of visible sets.
#[derive(Clone, Debug, PartialEq)]
pub struct VisTree {
    root: Cell,
    grid_bits: u32,
    objects: usize,
    nodes: Vec<Node>,
    /// Per leaf, in preorder, when known.
    records: Option<Vec<LeafRecord>>,
}

impl VisTree {
    /// A tree from its parts (not checked: call [`VisTree::validate`]).
    pub fn from_parts(root: Cell, grid_bits: u32, objects: usize, nodes: Vec<Node>) -> Self {
        Self {
            root,
            grid_bits,
            objects,
            nodes,
            records: None,
        }
    }

    /// The tree with a record per leaf, in preorder (`None` when they
    /// are not known). Fails (returns the records back) when their number
    /// is not the leaf count.
    pub fn with_leaf_records(
        mut self,
        records: Option<Vec<LeafRecord>>,
    ) -> Result<Self, Vec<LeafRecord>> {
        match records {
            Some(r) if r.len() != self.leaf_count() => Err(r),
            r => {
                self.records = r;
                Ok(self)
            }
        }
    }

    /// The record of each leaf, in preorder, when known (built trees and
    /// files from version 3).
    pub fn leaf_records(&self) -> Option<&[LeafRecord]> {
        self.records.as_deref()
    }

    /// The tree's nodes, in preorder, given up (so that a caller can turn
    /// their sets into another layout without holding both).
    pub fn into_nodes(self) -> Vec<Node> {
        self.nodes
    }

    /// The nodes and the leaf records, given up.
    pub fn into_parts(self) -> (Vec<Node>, Option<Vec<LeafRecord>>) {
        (self.nodes, self.records)
    }

    /// The root cell: the view box times all directions.
    pub fn root_cell(&self) -> Cell {
        self.root
    }

    /// q: the bits of every split code.
    pub fn grid_bits(&self) -> u32 {
        self.grid_bits
    }

    /// The number of objects the sets range over.
    pub fn object_count(&self) -> usize {
        self.objects
    }

    /// The nodes in preorder.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.nodes.iter().filter(|n| n.split.is_none()).count()
    }

    /// The split value of `split` in `cell`.
    pub fn split_value(&self, cell: &Cell, split: &Split) -> f32 {
        let d = split.dim as usize;
        grid_value(cell.lo[d], cell.hi[d], split.code, self.grid_bits)
    }

    /// The leaf whose cell holds the ray point `p` = (x, y, z, theta, phi):
    /// below the split value goes to the first child, at or above it to
    /// the second. Points outside the root go to the nearest leaf.
    pub fn locate(&self, p: [f32; DIMS]) -> usize {
        let mut i = 0;
        let mut cell = self.root;
        while let Some(s) = self.nodes[i].split {
            let v = self.split_value(&cell, &s);
            let (below, above) = cell.split(s.dim as usize, v);
            if p[s.dim as usize] < v {
                i += 1;
                cell = below;
            } else {
                i = s.above as usize;
                cell = above;
            }
        }
        i
    }

    /// Every leaf with its cell and depth, in preorder.
    pub fn leaves(&self) -> Vec<LeafCell> {
        let mut out = Vec::new();
        let mut stack = vec![(0usize, self.root, 0u32)];
        while let Some((i, cell, depth)) = stack.pop() {
            match self.nodes[i].split {
                None => out.push(LeafCell {
                    node: i,
                    cell,
                    depth,
                }),
                Some(s) => {
                    let (below, above) = cell.split(s.dim as usize, self.split_value(&cell, &s));
                    stack.push((s.above as usize, above, depth + 1));
                    stack.push((i + 1, below, depth + 1));
                }
            }
        }
        out
    }

    /// The largest leaf depth.
    pub fn depth(&self) -> u32 {
        self.leaves().iter().map(|l| l.depth).max().unwrap_or(0)
    }

    /// The tree's shape and leaf set sizes; `triangles[i]` is object i's
    /// triangle count.
    pub fn summarize(&self, triangles: &[u64]) -> TreeSummary {
        let leaves = self.leaves();
        let root = self.root.measure();
        let mut s = TreeSummary {
            nodes: self.nodes.len(),
            leaves: leaves.len(),
            ..Default::default()
        };
        for l in &leaves {
            let set = &self.nodes[l.node].set;
            let n = set.count();
            let t: u64 = set
                .iter()
                .map(|o| triangles.get(o).copied().unwrap_or(0))
                .sum();
            s.depth = s.depth.max(l.depth);
            s.mean_leaf_objects += n as f64;
            s.mean_leaf_triangles += t as f64;
            s.max_leaf_objects = s.max_leaf_objects.max(n);
            s.max_leaf_triangles = s.max_leaf_triangles.max(t);
            s.measure_weighted_objects += n as f64 * l.cell.measure() / root;
        }
        s.mean_leaf_objects /= leaves.len() as f64;
        s.mean_leaf_triangles /= leaves.len() as f64;
        s
    }

    /// Checks the invariants of the module docs; returns the first broken
    /// one.
    pub fn validate(&self) -> Result<(), InvariantError> {
        self.check_invariants()
            .map_err(|what| InvariantError::new("tree", what))
    }

    fn check_invariants(&self) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("the tree has no node".into());
        }
        if !(1..=MAX_GRID_BITS).contains(&self.grid_bits) {
            return Err(format!(
                "grid bits {} outside 1..={MAX_GRID_BITS}",
                self.grid_bits
            ));
        }
        let end = self.check_subtree(0, self.root)?;
        if end != self.nodes.len() {
            return Err(format!(
                "{} nodes but the preorder covers {end}",
                self.nodes.len()
            ));
        }
        let total: f64 = self.leaves().iter().map(|l| l.cell.measure()).sum();
        let root = self.root.measure();
        if (total - root).abs() > 1e-6 * root.max(1e-30) {
            return Err(format!(
                "leaf measures sum to {total}, the root's is {root}"
            ));
        }
        Ok(())
    }

    /// Checks the subtree at `i` with cell `cell`; returns the index after
    /// its last node.
    fn check_subtree(&self, i: usize, cell: Cell) -> Result<usize, String> {
        let node = self
            .nodes
            .get(i)
            .ok_or_else(|| format!("node {i} is missing"))?;
        if node.set.capacity() != self.objects {
            return Err(format!(
                "node {i} has a set over {} objects",
                node.set.capacity()
            ));
        }
        let Some(s) = node.split else {
            return Ok(i + 1);
        };
        let d = s.dim as usize;
        if d >= DIMS || s.code == 0 || s.code >= 1 << self.grid_bits {
            return Err(format!("node {i} has split dim {} code {}", s.dim, s.code));
        }
        let v = self.split_value(&cell, &s);
        if !(v > cell.lo[d] && v < cell.hi[d]) {
            return Err(format!(
                "node {i} splits {} at {v} outside ({}, {})",
                d, cell.lo[d], cell.hi[d]
            ));
        }
        let (below, above) = cell.split(d, v);
        let mid = self.check_subtree(i + 1, below)?;
        if s.above as usize != mid {
            return Err(format!(
                "node {i}: second child at {} but the first ends at {mid}",
                s.above
            ));
        }
        let end = self.check_subtree(mid, above)?;
        let (a, b) = (&self.nodes[i + 1].set, &self.nodes[mid].set);
        if !a.is_subset(&node.set) || !b.is_subset(&node.set) {
            return Err(format!(
                "node {i}: a child's set is not a subset of the parent's"
            ));
        }
        let mut union = a.clone();
        union.union_with(b);
        if union != node.set {
            return Err(format!(
                "node {i}: the set is not the union of the children's"
            ));
        }
        Ok(end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Aabb;
    use crate::geom::cell::THETA;
    use glam::Vec3;

    fn set(n: usize, items: &[usize]) -> ObjectSet {
        let mut s = ObjectSet::new(n);
        for &i in items {
            s.insert(i);
        }
        s
    }

    /// Root split on x at 1/2, its upper half split on theta at 1/4.
    fn small_tree() -> VisTree {
        let root = Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::splat(4.0)));
        let nodes = vec![
            Node {
                split: Some(Split {
                    dim: 0,
                    code: 2,
                    above: 2,
                }),
                set: set(3, &[0, 1, 2]),
            },
            Node {
                split: None,
                set: set(3, &[0]),
            },
            Node {
                split: Some(Split {
                    dim: THETA as u8,
                    code: 1,
                    above: 4,
                }),
                set: set(3, &[1, 2]),
            },
            Node {
                split: None,
                set: set(3, &[1]),
            },
            Node {
                split: None,
                set: set(3, &[2]),
            },
        ];
        VisTree::from_parts(root, 2, 3, nodes)
    }

    #[test]
    fn locate_and_leaves() {
        let t = small_tree();
        t.validate().unwrap();
        assert_eq!(t.leaf_count(), 3);
        assert_eq!(t.depth(), 2);
        assert_eq!(t.locate([1.0, 1.0, 1.0, 0.0, 1.0]), 1);
        // x = 2 is the split value: it goes above.
        assert_eq!(t.locate([2.0, 1.0, 1.0, -3.0, 1.0]), 3);
        assert_eq!(t.locate([3.0, 1.0, 1.0, 0.0, 1.0]), 4);
        let leaves = t.leaves();
        assert_eq!(leaves.iter().map(|l| l.node).collect::<Vec<_>>(), [1, 3, 4]);
        assert_eq!(leaves[1].cell.hi[THETA], -std::f32::consts::PI / 2.0);
    }

    #[test]
    fn validate_catches_broken_trees() {
        let mut t = small_tree();
        t.nodes[0].set.remove(2);
        assert!(t.validate().unwrap_err().what.contains("subset"));
        let mut t = small_tree();
        t.nodes[0].set = set(3, &[0, 1]);
        t.nodes[2].set = set(3, &[1]);
        assert!(t.validate().is_err());
        let mut t = small_tree();
        t.nodes[0].split = Some(Split {
            dim: 0,
            code: 4,
            above: 2,
        });
        assert!(t.validate().unwrap_err().what.contains("code"));
        let mut t = small_tree();
        t.nodes[0].split = Some(Split {
            dim: 0,
            code: 2,
            above: 3,
        });
        assert!(t.validate().is_err());
    }
}
