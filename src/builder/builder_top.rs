//! The fixed top of the tree, for builds split into shards (issue 17,
//! notes/scale.md): with [`BuildParams::top_levels`] = k > 0, the root
//! is cut k times before any ray is cast, each time at the midpoint of the
//! longest spatial axis of the cell, into 2^k subtrees. Each subtree is
//! built as a root of its own: every object is a candidate, it inherits no
//! ray, and its random streams are seeded by (seed, subtree index), so it
//! does not depend on the others; the fixed nodes' sets are the unions of
//! their children's. A shard builds some of the subtrees; [`graft`] puts
//! all of them under the fixed top, and the tree is the one a single
//! build makes, node for node.

use crate::bitset::ObjectSet;
use crate::geom::cell::{Cell, THETA, grid_value};
use crate::tree::{LeafRecord, Node, Split, VisTree};

use super::BuildParams;

/// The most fixed levels: 2^10 = 1,024 subtrees.
pub const MAX_TOP_LEVELS: u32 = 10;

/// [`BuildParams::subtree_objects`]'s default: more objects than any
/// real scene measured has (San Francisco: 2,368), so that their builds
/// keep one root and their files their bytes.
pub const DEFAULT_SUBTREE_OBJECTS: u64 = 4096;

/// The stream family of the subtrees' seeds.
pub(super) const TOP_STREAM: u64 = 0x746f_705f_6c65_7665;

/// The fixed cut of `cell` at level `level`: (dimension, grid code,
/// value), the midpoint of its widest spatial axis (the first among
/// equals).
fn top_cut(cell: &Cell, grid_bits: u32) -> (usize, u32, f32) {
    let dim = (0..THETA).fold(0, |best, d| {
        if cell.width(d) > cell.width(best) {
            d
        } else {
            best
        }
    });
    let code = 1u32 << (grid_bits - 1);
    (
        dim,
        code,
        grid_value(cell.lo[dim], cell.hi[dim], code, grid_bits),
    )
}

/// The cells of the 2^`levels` subtrees of `root`, in preorder (left to
/// right): subtree `i` is the `i`-th.
pub fn subtree_cells(root: Cell, levels: u32, grid_bits: u32) -> Vec<Cell> {
    fn walk(cell: Cell, levels: u32, grid_bits: u32, out: &mut Vec<Cell>) {
        if levels == 0 {
            out.push(cell);
            return;
        }
        let (dim, _, value) = top_cut(&cell, grid_bits);
        let (below, above) = cell.split(dim, value);
        walk(below, levels - 1, grid_bits, out);
        walk(above, levels - 1, grid_bits, out);
    }
    let mut out = Vec::with_capacity(1 << levels);
    walk(root, levels, grid_bits, &mut out);
    out
}

/// Which shard builds each subtree, for `shards` shards: the subtrees by
/// decreasing `cost`, each to the shard with the least cost so far (the
/// lowest among equals): shards of about the same work.
pub fn deal(costs: &[u64], shards: u32) -> Vec<u32> {
    let mut order: Vec<usize> = (0..costs.len()).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(costs[i]), i));
    let mut load = vec![0u64; shards.max(1) as usize];
    let mut owner = vec![0u32; costs.len()];
    for i in order {
        let (s, _) = load
            .iter()
            .enumerate()
            .min_by_key(|&(s, &l)| (l, s))
            .expect("at least one shard");
        owner[i] = s as u32;
        load[s] += costs[i];
    }
    owner
}

/// The estimated cost of building each subtree of `cells`: one plus the
/// triangles of the objects whose boxes meet its positions (the geometry
/// its rays meet first and most).
pub fn subtree_costs(scene: &crate::scene::Scene, cells: &[Cell]) -> Vec<u64> {
    cells
        .iter()
        .map(|c| {
            let space = c.space();
            1 + scene
                .objects()
                .iter()
                .filter(|o| {
                    !o.is_empty()
                        && o.bounds.min.cmple(space.max).all()
                        && space.min.cmple(o.bounds.max).all()
                })
                .map(|o| o.triangle_count() as u64)
                .sum::<u64>()
        })
        .collect()
}

/// Why subtrees cannot be put together.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GraftError {
    /// Not 2^levels subtrees.
    #[error("{levels} fixed levels (at most 10) take 2^{levels} subtrees, not {got}")]
    Count {
        /// The fixed levels.
        levels: u32,
        /// The subtrees given.
        got: usize,
    },
    /// A subtree's cell, grid or object count is not the one its place
    /// in the top needs.
    #[error("subtree {index} was built for another cell, grid or scene than its place needs")]
    Misplaced {
        /// The subtree's index.
        index: usize,
    },
}

/// The tree whose fixed top (`levels` cuts of `root`, as [`subtree_cells`] makes them) has
/// `subtrees` (in [`subtree_cells`]' order) under it: the fixed nodes'
/// sets are the unions of their children's; the leaves' records are the
/// subtrees' (when every subtree has them).
pub fn graft(
    root: Cell,
    levels: u32,
    grid_bits: u32,
    subtrees: &[VisTree],
) -> Result<VisTree, GraftError> {
    if levels > MAX_TOP_LEVELS || subtrees.len() as u64 != 1u64 << levels {
        return Err(GraftError::Count {
            levels,
            got: subtrees.len(),
        });
    }
    let cells = subtree_cells(root, levels, grid_bits);
    let objects = subtrees[0].object_count();
    for (index, (t, c)) in subtrees.iter().zip(&cells).enumerate() {
        if t.root_cell() != *c || t.grid_bits() != grid_bits || t.object_count() != objects {
            return Err(GraftError::Misplaced { index });
        }
    }
    let mut nodes = Vec::new();
    let mut records = subtrees
        .iter()
        .all(|t| t.leaf_records().is_some())
        .then(Vec::new);
    let mut next = 0;
    fn walk(
        cell: Cell,
        levels: u32,
        grid_bits: u32,
        subtrees: &[VisTree],
        next: &mut usize,
        nodes: &mut Vec<Node>,
        records: &mut Option<Vec<LeafRecord>>,
    ) -> ObjectSet {
        if levels == 0 {
            let t = &subtrees[*next];
            *next += 1;
            let offset = nodes.len() as u32;
            nodes.extend(t.nodes().iter().map(|n| Node {
                split: n.split.map(|s| Split {
                    above: s.above + offset,
                    ..s
                }),
                set: n.set.clone(),
            }));
            if let (Some(r), Some(own)) = (records.as_mut(), t.leaf_records()) {
                r.extend_from_slice(own);
            }
            return t.nodes()[0].set.clone();
        }
        let (dim, code, value) = top_cut(&cell, grid_bits);
        let (below, above) = cell.split(dim, value);
        let me = nodes.len();
        nodes.push(Node {
            split: None,
            set: ObjectSet::new(0),
        });
        let mut set = walk(below, levels - 1, grid_bits, subtrees, next, nodes, records);
        let above_index = nodes.len() as u32;
        set.union_with(&walk(
            above,
            levels - 1,
            grid_bits,
            subtrees,
            next,
            nodes,
            records,
        ));
        nodes[me] = Node {
            split: Some(Split {
                dim: dim as u8,
                code,
                above: above_index,
            }),
            set: set.clone(),
        };
        set
    }
    walk(
        root,
        levels,
        grid_bits,
        subtrees,
        &mut next,
        &mut nodes,
        &mut records,
    );
    Ok(VisTree::from_parts(root, grid_bits, objects, nodes)
        .with_leaf_records(records)
        .expect("one record per leaf of every subtree"))
}

/// Why parts cannot be merged. Messages name what is wrong; the caller
/// adds the files' names.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MergeError {
    /// No parts given.
    #[error("no parts to merge")]
    Empty,
    /// The parts disagree on how the build was split (or a part's split
    /// is impossible: a shard beyond its count, too many levels).
    #[error(
        "part {part} is shard {shard} of {shards} with {levels} fixed levels, the first part \
         one of {first_shards} with {first_levels}: parts of different builds"
    )]
    Split {
        /// Which part (in the order given).
        part: usize,
        /// Its shard.
        shard: u32,
        /// Its shard count.
        shards: u32,
        /// Its fixed levels.
        levels: u32,
        /// The first part's shard count.
        first_shards: u32,
        /// The first part's fixed levels.
        first_levels: u32,
    },
    /// Two parts are the same shard.
    #[error("shard {0} is given twice")]
    RepeatedShard(u32),
    /// A shard is missing.
    #[error("shard {missing} of {shards} is missing (shards count from 0)")]
    MissingShard {
        /// The first missing shard.
        missing: u32,
        /// The shard count.
        shards: u32,
    },
    /// A subtree was built by two parts, or by none.
    #[error("subtree {0} is in no part or in two: the parts were not dealt by the same build")]
    Subtree(u32),
    /// A subtree was built for another scene, other parameters or
    /// another coding.
    #[error(
        "subtree {0} was built for another scene or with other parameters than the first \
         part's: parts of different builds"
    )]
    Foreign(u32),
    /// The subtrees do not fit the fixed top.
    #[error(transparent)]
    Graft(#[from] GraftError),
}

/// The `.v5d` file of the build that `parts` (every shard's, in any
/// order) were cut from: the same bytes (through
/// [`write_file`](crate::codec::write_file)) as the file of a single
/// build with the same scene, parameters and coding. Checks that the
/// parts are every shard of one build, once each, and that every subtree
/// was built for the same scene and parameters.
pub fn merge(parts: Vec<crate::codec::V5dPart>) -> Result<crate::codec::V5dFile, MergeError> {
    let first = parts.first().ok_or(MergeError::Empty)?;
    let (levels, shards, coding) = (first.top_levels, first.shards, first.coding);
    let mut seen = vec![false; shards as usize];
    for (i, p) in parts.iter().enumerate() {
        if p.top_levels != levels
            || p.shards != shards
            || p.coding != coding
            || p.shard >= p.shards
            || p.top_levels > MAX_TOP_LEVELS
        {
            return Err(MergeError::Split {
                part: i,
                shard: p.shard,
                shards: p.shards,
                levels: p.top_levels,
                first_shards: shards,
                first_levels: levels,
            });
        }
        if std::mem::replace(&mut seen[p.shard as usize], true) {
            return Err(MergeError::RepeatedShard(p.shard));
        }
    }
    if let Some(missing) = seen.iter().position(|&s| !s) {
        return Err(MergeError::MissingShard {
            missing: missing as u32,
            shards,
        });
    }
    let count = 1usize << levels;
    let mut files: Vec<Option<crate::codec::V5dFile>> = vec![None; count];
    for p in parts {
        for (index, file) in p.subtrees {
            let slot = files
                .get_mut(index as usize)
                .ok_or(MergeError::Subtree(index))?;
            if slot.replace(file).is_some() {
                return Err(MergeError::Subtree(index));
            }
        }
    }
    let mut trees = Vec::with_capacity(count);
    let mut model: Option<crate::codec::V5dFile> = None;
    for (index, f) in files.into_iter().enumerate() {
        let f = f.ok_or(MergeError::Subtree(index as u32))?;
        if let Some(m) = &model
            && (f.fingerprint != m.fingerprint
                || f.frame != m.frame
                || f.params != m.params
                || f.objects != m.objects
                || f.slices.is_some())
        {
            return Err(MergeError::Foreign(index as u32));
        }
        trees.push(f.tree.clone());
        model.get_or_insert(f);
    }
    let model = model.expect("at least one subtree");
    // The root: the union of the subtrees' cells (the fixed cuts share
    // their planes, so the union is exact).
    let mut root = trees[0].root_cell();
    for t in &trees {
        let c = t.root_cell();
        for d in 0..crate::geom::cell::DIMS {
            root.lo[d] = root.lo[d].min(c.lo[d]);
            root.hi[d] = root.hi[d].max(c.hi[d]);
        }
    }
    let tree = graft(root, levels, model.tree.grid_bits(), &trees)?;
    let coding = coding.unwrap_or_else(|| super::smallest_coding(&tree));
    Ok(crate::codec::V5dFile {
        coding,
        tree,
        ..model
    })
}

impl BuildParams {
    /// The seed of subtree `index` of a fixed top of `fixed` levels: the
    /// build's seed itself without a fixed top.
    pub(super) fn subtree_seed(&self, fixed: u32, index: usize) -> u64 {
        if fixed == 0 {
            self.seed
        } else {
            super::mix(self.seed, TOP_STREAM ^ index as u64)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Aabb;
    use glam::Vec3;

    #[test]
    fn the_top_cuts_the_longest_axis_at_its_middle() {
        let root = Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::new(8.0, 2.0, 1.0)));
        let cells = subtree_cells(root, 3, 10);
        assert_eq!(cells.len(), 8);
        // x is halved twice (8 -> 4 -> 2), then x and y are equal (2, 2):
        // the first of them, x, again.
        for (i, c) in cells.iter().enumerate() {
            assert_eq!(c.lo[0], i as f32, "{c:?}");
            assert_eq!(c.hi[0], i as f32 + 1.0);
            assert_eq!((c.lo[1], c.hi[1]), (0.0, 2.0));
            assert_eq!((c.lo[THETA], c.hi[THETA]), (root.lo[THETA], root.hi[THETA]));
        }
        assert_eq!(subtree_cells(root, 0, 10), vec![root]);
    }

    #[test]
    fn dealing_balances_the_costs() {
        let owner = deal(&[5, 1, 4, 2, 3, 3], 3);
        let mut load = [0u64; 3];
        for (i, &s) in owner.iter().enumerate() {
            load[s as usize] += [5, 1, 4, 2, 3, 3][i];
        }
        assert_eq!(load, [6, 6, 6]);
        // More shards than subtrees: the extra shards get nothing.
        assert_eq!(deal(&[1, 1], 3), vec![0, 1]);
    }
}
