//! Cross-checking a built tree against the oracle (`vis5d check`).
//!
//! For the leaves of a tree (all, or a seeded sample), the oracle runs on
//! the leaf's spatial box, with the hidden set of the nearest ancestor
//! whose spatial box differs (so a tree's spatial hierarchy is walked top
//! down and each box computed once). Its set is restricted to the leaf's
//! angular box conservatively: an object stays when some direction from
//! the box to the object's bounding box lies in the leaf's directions.
//! Then, per leaf:
//!
//! - **violations**: objects a ray of the leaf hits first although the
//!   oracle calls them hidden. Two sources: the leaf's own ground-truth
//!   rays (uniform rays of the 5D leaf cell), and a burst of rays aimed at
//!   each object the sampled set holds but the oracle hid. A violation
//!   means the oracle is wrong; there must be none.
//! - **suspects**: objects the oracle keeps and the sampled set lacks. A
//!   burst of rays aimed at each (the builder's own samplers, drawn from
//!   the leaf to points on the object) either hits it first somewhere (a
//!   *confirmed miss* of the sampler, with the visible fraction found) or
//!   not (not found: probably hidden, the oracle being conservative).
//! - the sizes of the oracle's set (before and after the angular
//!   restriction), the sampled set and the ground-truth set.
//!
//! Ray work is parallel over leaves; every leaf has its own seeded random
//! stream, so the report does not depend on the thread count.

use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::Oracle;
use crate::bitset::ObjectSet;
use crate::geom::Aabb;
use crate::geom::cell::{Cell, direction_bounds, directions_meet};
use crate::sample::{AdaptiveSampler, cell_point, cell_ray};
use crate::trace::{Ray, Tracer};
use crate::tree::VisTree;

/// Settings of a check.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckParams {
    /// Check this many leaves, picked at random; `None`: all.
    pub sample: Option<usize>,
    /// Draws aimed at each suspect (and at each object the oracle hid but
    /// the leaf keeps).
    pub burst: u32,
    /// Uniform rays of each leaf cell for its ground-truth set.
    pub truth_rays: u32,
    /// Seed of the leaf sample and the rays.
    pub seed: u64,
}

impl Default for CheckParams {
    fn default() -> Self {
        Self {
            sample: None,
            burst: 1000,
            truth_rays: 4096,
            seed: 1,
        }
    }
}

/// An object that a ray hits first although the oracle hid it.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    /// The object.
    pub object: u32,
    /// A ray of the leaf that hits it first.
    pub ray: Ray,
}

/// An object the oracle keeps and the leaf's set lacks, after its burst.
#[derive(Clone, Debug, PartialEq)]
pub struct Suspect {
    /// The object.
    pub object: u32,
    /// Accepted draws aimed at it.
    pub rays: u32,
    /// How many of them hit it first (0: not found).
    pub hits: u32,
}

impl Suspect {
    /// Whether a ray proved it visible: a miss of the sampler.
    pub fn confirmed(&self) -> bool {
        self.hits > 0
    }

    /// The share of the aimed rays that reached it (its visible fraction
    /// as the builder's SPRT measures it).
    pub fn visible_fraction(&self) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            self.hits as f64 / self.rays as f64
        }
    }
}

/// The check of one leaf.
#[derive(Clone, Debug)]
pub struct LeafCheck {
    /// The leaf's node index in the tree.
    pub node: usize,
    /// The leaf's cell.
    pub cell: Cell,
    /// The oracle's set for the leaf's spatial box, all directions.
    pub oracle_all: usize,
    /// The oracle's set restricted to the leaf's directions.
    pub oracle: usize,
    /// The leaf's sampled set.
    pub sampled: usize,
    /// Objects the leaf's ground-truth rays hit.
    pub truth: usize,
    /// Objects in the sampled set that the oracle hid and no aimed ray hit
    /// (the sampler keeps what may be hidden: allowed, not tight).
    pub sampled_only: usize,
    /// Violations (must be none).
    pub violations: Vec<Violation>,
    /// Suspects, resolved.
    pub suspects: Vec<Suspect>,
}

/// The whole check.
#[derive(Clone, Debug)]
pub struct CheckReport {
    /// Leaves in the tree.
    pub tree_leaves: usize,
    /// The leaves checked, in tree order.
    pub leaves: Vec<LeafCheck>,
    /// Spatial boxes the oracle ran on (the leaves' and their ancestors').
    pub oracle_cells: usize,
    /// Time in the oracle.
    pub oracle_time: Duration,
    /// Time casting rays.
    pub ray_time: Duration,
}

impl CheckReport {
    /// All violations, with their leaf.
    pub fn violations(&self) -> impl Iterator<Item = (&LeafCheck, &Violation)> {
        self.leaves
            .iter()
            .flat_map(|l| l.violations.iter().map(move |v| (l, v)))
    }
}

/// Checks `tree` (built for the oracle's scene) against the oracle, calling
/// `progress(done, total)` after each oracle cell and each leaf's rays.
pub fn check_tree(
    oracle: &Oracle,
    tracer: &Tracer,
    tree: &VisTree,
    params: &CheckParams,
    cell_oracle: &mut dyn FnMut(&Aabb, Option<&ObjectSet>) -> ObjectSet,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> CheckReport {
    let leaves = tree.leaves();
    let mut chosen: Vec<usize> = (0..leaves.len()).collect();
    if let Some(n) = params.sample
        && n < leaves.len()
    {
        // A seeded partial Fisher-Yates shuffle, then tree order.
        let mut rng = Pcg64::seed_from_u64(params.seed);
        for i in 0..n {
            let j = rng.random_range(i..chosen.len());
            chosen.swap(i, j);
        }
        chosen.truncate(n);
        chosen.sort_unstable();
    }
    let selected: Vec<usize> = chosen.iter().map(|&i| leaves[i].node).collect();
    // The oracle, top down over the spatial boxes on the selected paths.
    let start = Instant::now();
    let nodes = tree.nodes();
    let mut needed = vec![false; nodes.len()];
    for &n in &selected {
        needed[n] = true;
    }
    mark_needed(tree, 0, &mut needed);
    let mut results: Vec<ObjectSet> = Vec::new();
    let mut leaf_result = vec![usize::MAX; nodes.len()];
    let total_boxes = count_boxes(tree, &needed);
    let mut stack: Vec<Pending> = vec![(0, tree.root_cell(), None)];
    while let Some((i, cell, parent)) = stack.pop() {
        if !needed[i] {
            continue;
        }
        let space = cell.space();
        let here = match parent {
            Some((p, parent_space)) if parent_space == space => p,
            _ => {
                let hidden = parent.map(|(p, _)| {
                    let mut h = ObjectSet::full(results[p].capacity());
                    h.subtract(&results[p]);
                    h
                });
                results.push(cell_oracle(&space, hidden.as_ref()));
                progress("oracle", results.len(), total_boxes);
                results.len() - 1
            }
        };
        match nodes[i].split {
            None => leaf_result[i] = here,
            Some(s) => {
                let (below, above) = cell.split(s.dim as usize, tree.split_value(&cell, &s));
                stack.push((s.above as usize, above, Some((here, space))));
                stack.push((i + 1, below, Some((here, space))));
            }
        }
    }
    let oracle_time = start.elapsed();
    // Rays, in parallel over leaves.
    let start = Instant::now();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let checks: Vec<LeafCheck> = chosen
        .par_iter()
        .map(|&k| {
            let leaf = &leaves[k];
            let set = &results[leaf_result[leaf.node]];
            let out = check_leaf(
                oracle,
                tracer,
                &leaf.cell,
                leaf.node,
                &nodes[leaf.node].set,
                set,
                params,
            );
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress("rays", d, chosen.len());
            out
        })
        .collect();
    CheckReport {
        tree_leaves: leaves.len(),
        leaves: checks,
        oracle_cells: results.len(),
        oracle_time,
        ray_time: start.elapsed(),
    }
}

/// A node to visit: its index, its cell, and the result index and spatial
/// box of the nearest ancestor that ran the oracle.
type Pending = (usize, Cell, Option<(usize, Aabb)>);

/// Marks every node with a needed leaf below it.
fn mark_needed(tree: &VisTree, i: usize, needed: &mut [bool]) -> bool {
    let n = match tree.nodes()[i].split {
        None => needed[i],
        Some(s) => {
            let a = mark_needed(tree, i + 1, needed);
            let b = mark_needed(tree, s.above as usize, needed);
            a || b
        }
    };
    needed[i] = n;
    n
}

fn count_boxes(tree: &VisTree, needed: &[bool]) -> usize {
    let mut count = 0;
    let mut stack = vec![(0usize, tree.root_cell(), None::<Aabb>)];
    while let Some((i, cell, parent)) = stack.pop() {
        if !needed[i] {
            continue;
        }
        let space = cell.space();
        if parent != Some(space) {
            count += 1;
        }
        if let Some(s) = tree.nodes()[i].split {
            let (below, above) = cell.split(s.dim as usize, tree.split_value(&cell, &s));
            stack.push((s.above as usize, above, Some(space)));
            stack.push((i + 1, below, Some(space)));
        }
    }
    count
}

fn check_leaf(
    oracle: &Oracle,
    tracer: &Tracer,
    cell: &Cell,
    node: usize,
    sampled: &ObjectSet,
    oracle_all: &ObjectSet,
    params: &CheckParams,
) -> LeafCheck {
    let scene = oracle.scene();
    let space = cell.space();
    let mut rng =
        Pcg64::seed_from_u64(params.seed ^ (node as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
    // The oracle's set, restricted to the leaf's directions.
    let mut restricted = ObjectSet::new(oracle_all.capacity());
    for o in oracle_all.iter() {
        if directions_meet(cell, direction_bounds(&space, &scene.objects()[o].bounds)) {
            restricted.insert(o);
        }
    }
    let mut violations: Vec<Violation> = Vec::new();
    // Ground truth: uniform rays of the leaf.
    let rays: Vec<Ray> = (0..params.truth_rays)
        .map(|_| cell_ray(&cell_point(cell, &mut rng)))
        .collect();
    let mut truth = ObjectSet::new(oracle_all.capacity());
    let mut seen = Vec::new();
    for ray in &rays {
        tracer.seen_along(ray, &mut seen);
        for &o in &seen {
            if truth.insert(o as usize) && !restricted.contains(o as usize) {
                violations.push(Violation {
                    object: o,
                    ray: *ray,
                });
            }
        }
    }
    // Aimed bursts: at what the leaf keeps and the oracle hid (a hit is a
    // violation), and at the suspects (a hit is a confirmed miss).
    let mut sampled_only = 0;
    let mut suspects = Vec::new();
    for o in 0..oracle_all.capacity() {
        let (kept, in_oracle) = (sampled.contains(o), restricted.contains(o));
        if kept == in_oracle {
            continue;
        }
        if kept && violations.iter().any(|v| v.object as usize == o) {
            continue;
        }
        if scene.objects()[o].is_empty() {
            // No surface to aim at, and no ray ever sees it: kept, it is
            // drawn for nothing; hidden, it is right.
            if kept {
                sampled_only += 1;
            }
            continue;
        }
        let (rays, hits, witness) = burst(scene, tracer, cell, o, params.burst, &mut rng);
        if kept {
            match witness {
                Some(ray) => violations.push(Violation {
                    object: o as u32,
                    ray,
                }),
                None => sampled_only += 1,
            }
        } else {
            suspects.push(Suspect {
                object: o as u32,
                rays,
                hits,
            });
        }
    }
    LeafCheck {
        node,
        cell: *cell,
        oracle_all: oracle_all.count(),
        oracle: restricted.count(),
        sampled: sampled.count(),
        truth: truth.count(),
        sampled_only,
        violations,
        suspects,
    }
}

/// Up to `draws` draws of rays from the cell aimed at points of object
/// `o`: (accepted rays, rays that hit `o` first, a witness).
fn burst(
    scene: &crate::scene::Scene,
    tracer: &Tracer,
    cell: &Cell,
    o: usize,
    draws: u32,
    rng: &mut Pcg64,
) -> (u32, u32, Option<Ray>) {
    let mut sampler = AdaptiveSampler::new(cell);
    let rays: Vec<Ray> = (0..draws)
        .filter_map(|_| sampler.draw(scene, cell, o, rng))
        .collect();
    let mut hits = 0;
    let mut witness = None;
    let mut found = vec![None; rays.len()];
    tracer.closest_hits_towards_into(&rays, &vec![o as u32; rays.len()], &mut found);
    for (ray, hit) in rays.iter().zip(found) {
        if hit.is_some_and(|h| h.object as usize == o) {
            hits += 1;
            witness.get_or_insert(*ray);
        }
    }
    (rays.len() as u32, hits, witness)
}
