//! The hidden slices of a tree's leaves, proved by the extended-projection
//! oracle.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::{LeafSlices, SlicedScene};
use crate::bitset::ObjectSet;
use crate::oracle::Oracle;
use crate::tree::VisTree;

/// Per leaf of `tree` (preorder), the objects of its set that have
/// slices the `oracle` proves hidden from the leaf's box of positions
/// ([`Oracle::cell_slices`]), whatever the direction: so a slice culled
/// for a leaf is hidden from every ray of it, on a sampled tree as on a
/// conservative one. Leaves that share a box of positions (the sampled
/// tree's direction splits) share one oracle run. With `conservative`,
/// the objects a leaf does not hold were proved hidden from a box
/// holding it (the conservative bake) and the oracle takes them as
/// hidden, as the bake did. `progress(done, total)` is called after each
/// box. Deterministic: the same for any thread count.
pub fn leaf_slices(
    tree: &VisTree,
    oracle: &Oracle,
    sliced: &SlicedScene,
    conservative: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Vec<LeafSlices> {
    let leaves = tree.leaves();
    let n = tree.object_count();
    // Unique boxes (and, when conservative, sets), in first-seen order.
    let mut seen: HashMap<([u32; 6], Option<Vec<u64>>), usize> = HashMap::new();
    let mut jobs: Vec<usize> = Vec::new();
    let job_of: Vec<usize> = leaves
        .iter()
        .enumerate()
        .map(|(k, leaf)| {
            let b = leaf.cell.space();
            let key = [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z].map(f32::to_bits);
            let set = conservative.then(|| tree.nodes()[leaf.node].set.words().to_vec());
            *seen.entry((key, set)).or_insert_with(|| {
                jobs.push(k);
                jobs.len() - 1
            })
        })
        .collect();
    let done = AtomicUsize::new(0);
    let total = jobs.len();
    let answers: Vec<Vec<Option<super::HiddenSlices>>> = jobs
        .par_iter()
        .map(|&k| {
            let leaf = &leaves[k];
            let hidden = conservative.then(|| {
                let mut h = ObjectSet::full(n);
                h.subtract(&tree.nodes()[leaf.node].set);
                h
            });
            let r = oracle.cell_slices(&leaf.cell.space(), hidden.as_ref(), sliced);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            r.slices
        })
        .collect();
    leaves
        .iter()
        .zip(job_of)
        .map(|(leaf, job)| {
            let set = &tree.nodes()[leaf.node].set;
            answers[job]
                .iter()
                .enumerate()
                .filter(|(o, _)| set.contains(*o))
                .filter_map(|(o, h)| {
                    let h = h.as_ref()?;
                    Some((o as u32, h.pieces.iter().map(|&(i, _)| i).collect()))
                })
                .collect()
        })
        .collect()
}
