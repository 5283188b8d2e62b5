//! One node of the recursive build: the cache of cell rays, the set, the
//! decision to split, the recursion (module docs of [`super`]).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::builder_leaf::TracedSample;
use super::{BuildParams, BuildStats, builder_edges, builder_leaf, builder_split, mix};
use crate::bitset::ObjectSet;
use crate::geom::cell::{Cell, DIMS, PHI, THETA, grid_value};
use crate::geom::trig;
use crate::sample::{cell_point, cell_ray};
use crate::scene::Scene;
use crate::trace::{Hit, Ray, Tracer};
use crate::tree::{LeafRecord, Node, Split};

/// What every node of a build shares.
pub(super) struct Ctx<'a> {
    pub scene: &'a Scene,
    pub tracer: &'a Tracer,
    pub params: &'a BuildParams,
    /// The smallest child extent per dimension.
    pub min_width: [f32; DIMS],
    /// Triangles per object.
    pub triangles: Vec<u64>,
    /// Per object, the objects near it (`super::neighbours`): a leaf
    /// retests a dropped object only near one its rays hit.
    pub neighbours: Vec<Vec<u32>>,
    /// The objects flagged always visible: in every set.
    pub always_visible: Vec<usize>,
    pub root_measure: f64,
    /// Misses in a row an internal node needs before an object is
    /// invisible (see [`BuildParams::internal_miss_factor`]).
    pub internal_min_misses: u32,
    /// The SPRT's verdict on a run of misses, and its length
    /// ([`crate::sprt::SprtParams::misses_decision`]).
    pub misses_decision: (u32, crate::sprt::Decision),
    /// Finished measure, in units of 2^-40 of the root's.
    pub done: AtomicU64,
    /// Nodes made so far (the root included), against
    /// [`BuildParams::max_nodes`].
    pub nodes: AtomicU64,
    /// Set when a split was refused for the node budget: the build fails.
    pub over_budget: AtomicBool,
    pub progress: &'a (dyn Fn(f64) + Sync),
    /// Where the rays traced go, when they are recorded
    /// ([`super::record_rays`]); once it is full no cell is split.
    pub record: Option<&'a crate::raylog::RayLog>,
}

impl Ctx<'_> {
    /// Traces `rays` in parallel, timing it: the closest hits.
    pub fn trace_hits(&self, rays: &[Ray], stats: &mut BuildStats) -> Vec<Option<Hit>> {
        if let Some(log) = self.record {
            log.push(rays);
        }
        let start = Instant::now();
        let hits = self.tracer.closest_hits(rays);
        stats.trace_seconds += start.elapsed().as_secs_f64();
        hits
    }

    /// Traces `rays` in parallel, timing it: the objects hit.
    pub fn trace(&self, rays: &[Ray], stats: &mut BuildStats) -> Vec<Option<u32>> {
        let hits = self.trace_hits(rays, stats);
        hits.into_iter().map(|h| h.map(|h| h.object)).collect()
    }

    /// Traces object samples in parallel, timing it: the object each ray,
    /// aimed at object `targets[i]`, meets first (the target included
    /// where it does not occlude:
    /// [`crate::trace::Tracer::closest_hit_towards`]).
    pub fn trace_towards(
        &self,
        rays: &[Ray],
        targets: &[u32],
        stats: &mut BuildStats,
    ) -> Vec<Option<u32>> {
        if let Some(log) = self.record {
            log.push(rays);
        }
        let start = Instant::now();
        let mut hits = vec![None; rays.len()];
        self.tracer
            .closest_hits_towards_into(rays, targets, &mut hits);
        stats.trace_seconds += start.elapsed().as_secs_f64();
        hits.into_iter().map(|h| h.map(|h| h.object)).collect()
    }

    fn finished(&self, cell: &Cell) {
        let units = (cell.measure() / self.root_measure * (1u64 << 40) as f64) as u64;
        let done = self.done.fetch_add(units, Ordering::Relaxed) + units;
        (self.progress)(done as f64 / (1u64 << 40) as f64);
    }

    fn set_triangles(&self, set: &ObjectSet) -> u64 {
        set.iter().map(|o| self.triangles[o]).sum()
    }
}

/// A cached cell ray: its 5D point, the object its closest hit is on and
/// the triangle it hit (`u32::MAX` for none).
#[derive(Clone, Copy, Debug)]
pub(super) struct CachedRay {
    pub p: [f32; DIMS],
    pub hit: Option<u32>,
    pub triangle: u32,
}

/// Where a node stands in the recursion.
#[derive(Clone, Copy, Debug)]
pub(super) struct NodeState {
    depth: u32,
    /// Forced angular cuts still to make below a final spatial cell
    /// (`spatial_only`), or `None` while splits are still chosen by E.
    angular_left: Option<u32>,
    /// The fewest misses behind an ancestor's rejection (`u32::MAX` when
    /// none was rejected), for the leaves' records.
    fewest_dropped: u32,
}

impl NodeState {
    /// The state of a root of the fixed top's subtrees, at `depth`
    /// ([`super::BuildParams::top_levels`]; 0 for the one root).
    pub const fn top(depth: u32) -> NodeState {
        NodeState {
            depth,
            angular_left: None,
            fewest_dropped: u32::MAX,
        }
    }
}

/// A built subtree, before flattening into preorder.
pub(super) enum Built {
    Leaf(ObjectSet, LeafRecord),
    Split {
        dim: u8,
        code: u32,
        set: ObjectSet,
        children: Box<[Built; 2]>,
    },
}

impl Built {
    fn set(&self) -> &ObjectSet {
        match self {
            Built::Leaf(s, _) | Built::Split { set: s, .. } => s,
        }
    }

    /// Appends the subtree to `nodes` in preorder, and its leaves' records
    /// to `records`.
    pub fn flatten_into(self, nodes: &mut Vec<Node>, records: &mut Vec<LeafRecord>) {
        match self {
            Built::Leaf(set, record) => {
                nodes.push(Node { split: None, set });
                records.push(record);
            }
            Built::Split {
                dim,
                code,
                set,
                children,
            } => {
                let me = nodes.len();
                nodes.push(Node { split: None, set });
                let [below, above] = *children;
                below.flatten_into(nodes, records);
                let above_index = nodes.len() as u32;
                above.flatten_into(nodes, records);
                nodes[me].split = Some(Split {
                    dim,
                    code,
                    above: above_index,
                });
            }
        }
    }
}

/// Builds the subtree of `cell`, whose candidates are `candidates`, whose
/// ancestors' tests called `dropped` invisible (a leaf retests them), whose
/// cache so far is `cache` (rays inherited from the parent) and whose
/// ancestors' object samples that fall in it are `samples`.
#[allow(clippy::too_many_arguments)]
pub(super) fn build_node(
    ctx: &Ctx,
    cell: Cell,
    state: NodeState,
    seed: u64,
    candidates: &ObjectSet,
    dropped: &ObjectSet,
    mut cache: Vec<CachedRay>,
    samples: Vec<TracedSample>,
    stats: &mut BuildStats,
) -> Built {
    let params = ctx.params;
    top_up_cache(ctx, &cell, seed, &mut cache, stats);
    let mut proven = ObjectSet::new(candidates.capacity());
    for r in &cache {
        if let Some(o) = r.hit {
            proven.insert(o as usize);
        }
    }
    // The ancestors' object samples are rays of this cell: their hits are
    // proofs, and their owners' misses count in the owners' tests here.
    let mut credit = vec![
        0u32;
        if samples.is_empty() {
            0
        } else {
            candidates.capacity()
        }
    ];
    for s in &samples {
        match s.hit() {
            Some(o) if o == s.owner => {}
            _ => credit[s.owner as usize] += 1,
        }
        if let Some(o) = s.hit() {
            proven.insert(o as usize);
        }
    }
    // Decide the split first: an internal node's set needs more evidence
    // than a leaf's. "Visible triangles" are the candidates' (the parent's
    // set): the best estimate before this cell's own set is known.
    let split = match state.angular_left {
        Some(0) => None,
        Some(left) => Some(forced_angular_split(&cell, params, left)),
        None => {
            let chosen = if state.depth >= params.max_depth
                || ctx.set_triangles(candidates) < params.min_visible_triangles
            {
                None
            } else {
                builder_split::best_split(ctx, &cell, &cache)
            };
            match chosen {
                Some(c) => Some((c.dim, c.code)),
                None if params.spatial_only && params.angular_leaves > 1 => {
                    let levels = params.angular_leaves.trailing_zeros();
                    Some(forced_angular_split(&cell, params, levels))
                }
                None => None,
            }
        }
    };
    let min_misses = if split.is_some() {
        ctx.internal_min_misses
    } else {
        0
    };
    // The node budget. Whether it is exceeded does not depend on the
    // schedule: while no split is refused, the nodes made are those of the
    // whole tree, so a refusal happens exactly when that tree has more
    // nodes than the budget (and the build then fails).
    // A recording build that has its rays ends: no more splits.
    let split = split.filter(|_| !ctx.record.is_some_and(|log| log.is_full()));
    let split = split.filter(|_| {
        let made = ctx.nodes.fetch_add(2, Ordering::Relaxed) + 2;
        let within = made <= params.max_nodes;
        if !within {
            ctx.over_budget.store(true, Ordering::Relaxed);
        }
        within
    });
    // The objects near those the cell's rays hit: where a small visible
    // part of an object hidden elsewhere would be. An internal node asks
    // more evidence before it drops one of them (every cell below inherits
    // the verdict), and a leaf retests those an ancestor dropped. Objects
    // far from every hit (in another apartment of a block) are neither:
    // that bounds the work.
    let mut near = ObjectSet::new(candidates.capacity());
    if (split.is_some() && params.internal_miss_factor > 1)
        || (split.is_none() && params.retest_rays > 0 && !dropped.is_empty())
    {
        for o in proven.iter() {
            for &n in &ctx.neighbours[o] {
                near.insert(n as usize);
            }
        }
    }
    let mut retest = ObjectSet::new(candidates.capacity());
    if split.is_none() && params.retest_rays > 0 {
        retest.union_with(&near);
        retest.intersect_with(dropped);
    }
    let retest = &retest;
    let tests = builder_leaf::Tests {
        candidates,
        retest,
        proven,
        min_misses,
        near: &near,
        credit: &credit,
        keep_samples: split.is_some() && params.inherit_samples,
    };
    let mut decided = builder_leaf::visible_set(ctx, &cell, tests, seed, stats);
    let own_samples = std::mem::take(&mut decided.samples);
    let (mut set, rejected) = (decided.set, decided.rejected);
    if split.is_none() {
        builder_edges::edge_rays(ctx, &cell, seed, &cache, &mut set, stats);
    }
    let Some((dim, code)) = split else {
        ctx.finished(&cell);
        let record = leaf_record(
            &set,
            dropped,
            state.fewest_dropped,
            &rejected,
            decided.fewest_misses,
            decided.undecided,
        );
        return Built::Leaf(set, record);
    };
    // What the children's leaves retest: what was dropped above or here,
    // less what this cell's rays proved.
    let mut child_dropped = dropped.clone();
    child_dropped.union_with(&rejected);
    child_dropped.subtract(&set);

    let value = grid_value(cell.lo[dim], cell.hi[dim], code, params.grid_bits);
    let (below_cell, above_cell) = cell.split(dim, value);
    let (below_cache, above_cache): (Vec<_>, Vec<_>) =
        cache.into_iter().partition(|r| r.p[dim] < value);
    let (below_samples, above_samples) =
        builder_leaf::hand_down(&cell, samples, own_samples, &set, dim, value);
    let child_state = NodeState {
        depth: state.depth + 1,
        angular_left: match state.angular_left {
            Some(left) => Some(left - 1),
            None if dim >= THETA && params.spatial_only => {
                Some(params.angular_leaves.trailing_zeros() - 1)
            }
            None => None,
        },
        fewest_dropped: if rejected.is_empty() {
            state.fewest_dropped
        } else {
            state.fewest_dropped.min(decided.fewest_misses)
        },
    };
    let mut below_stats = BuildStats::default();
    let mut above_stats = BuildStats::default();
    let (below, above) = rayon::join(
        || {
            build_node(
                ctx,
                below_cell,
                child_state,
                mix(seed, 1),
                &set,
                &child_dropped,
                below_cache,
                below_samples,
                &mut below_stats,
            )
        },
        || {
            build_node(
                ctx,
                above_cell,
                child_state,
                mix(seed, 2),
                &set,
                &child_dropped,
                above_cache,
                above_samples,
                &mut above_stats,
            )
        },
    );
    stats.add(&below_stats);
    stats.add(&above_stats);
    let mut union = below.set().clone();
    union.union_with(above.set());
    Built::Split {
        dim: dim as u8,
        code,
        set: union,
        children: Box::new([below, above]),
    }
}

/// The record of a leaf whose set is `set`, whose ancestors dropped
/// `dropped` (the fewest misses behind one: `fewest_dropped`), and whose
/// own test rejected `rejected` (fewest misses `fewest_own`) and kept
/// `undecided` without a decision.
fn leaf_record(
    set: &ObjectSet,
    dropped: &ObjectSet,
    fewest_dropped: u32,
    rejected: &ObjectSet,
    fewest_own: u32,
    undecided: u32,
) -> LeafRecord {
    let mut from_above = dropped.clone();
    from_above.subtract(set);
    let mut own = rejected.clone();
    own.subtract(set);
    own.subtract(&from_above);
    let mut fewest = u32::MAX;
    if !from_above.is_empty() {
        fewest = fewest.min(fewest_dropped);
    }
    if !own.is_empty() {
        fewest = fewest.min(fewest_own);
    }
    let count = (from_above.count() + own.count()) as u32;
    LeafRecord {
        rejected: count,
        fewest_rays: if count == 0 { 0 } else { fewest },
        undecided,
    }
}

/// The forced cut that makes angular leaves, `left` cuts before the
/// leaves: theta and phi alternate from the first cut (theta), theta at its
/// midpoint, phi at the midpoint of cos phi (equal solid angle), both on
/// the grid.
fn forced_angular_split(cell: &Cell, params: &BuildParams, left: u32) -> (usize, u32) {
    let q = params.grid_bits;
    let half = 1u32 << (q - 1);
    let levels = params.angular_leaves.trailing_zeros();
    // Level 0 (the first cut) is theta, then phi, then theta...
    let level = levels - left;
    if level.is_multiple_of(2) {
        return (THETA, half);
    }
    let (lo, hi) = (cell.lo[PHI], cell.hi[PHI]);
    let (_, [c0, c1]) = trig::sin_cos([lo, hi]);
    let mid = trig::acos((c0 + c1) * 0.5);
    let code = (((mid - lo) / (hi - lo)) * (1u32 << q) as f32).round() as u32;
    (PHI, code.clamp(1, (1 << q) - 1))
}

/// Adds new uniform cell rays to `cache` until it holds
/// `params.cache_rays`, and traces them.
fn top_up_cache(
    ctx: &Ctx,
    cell: &Cell,
    seed: u64,
    cache: &mut Vec<CachedRay>,
    stats: &mut BuildStats,
) {
    let want = ctx.params.cache_rays as usize;
    if cache.len() >= want {
        return;
    }
    let mut rng = Pcg64::seed_from_u64(mix(seed, u64::MAX));
    let points: Vec<[f32; DIMS]> = (cache.len()..want)
        .map(|_| cell_point(cell, &mut rng))
        .collect();
    let rays: Vec<Ray> = points.iter().map(cell_ray).collect();
    let hits = ctx.trace_hits(&rays, stats);
    stats.cell_rays += rays.len() as u64;
    cache.extend(points.into_iter().zip(hits).map(|(p, hit)| CachedRay {
        p,
        hit: hit.map(|h| h.object),
        triangle: hit.map_or(u32::MAX, |h| h.triangle),
    }));
}
