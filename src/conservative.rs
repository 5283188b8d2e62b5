//! The conservative bake: a spatial k-d tree of view cells, each leaf
//! holding the extended-projection oracle's set for its box (papers/001
//! sec. 6, "Adaptive preprocess").
//!
//! Starting from the view box, each cell runs the [`Oracle`] with the
//! objects its parent proved hidden taken as hidden (the paper: "occlusion
//! culling is only performed on the remaining visible objects"). A cell
//! whose set holds more than [`BakeParams::triangle_budget`] triangles is
//! cut in two, down to [`BakeParams::max_depth`] and
//! [`BakeParams::min_cell_fraction`]; the paper's criterion is this
//! polygon budget; optionally a cell is not cut either where some levels
//! in a row proved nothing more hidden ([`BakeParams::stall_levels`]).
//! The cut is at the middle of a side (on the tree's split
//! grid): with [`BakeParams::try_cuts`], the side whose halves' oracle
//! sets hold the fewest triangles together (the halves' sets are kept for
//! the children), else the longest. Cells are never cut in direction: a leaf holds every
//! object that some ray from its box may hit first, whatever the
//! direction, and `Pvs::query_view` culls that to the view's frustum.
//!
//! The result is a [`VisTree`] like the sampled builder's, written in the
//! same `.v5d` format with `method=conservative` among its parameters
//! ([`METHOD_KEY`]), and answered by the same [`Pvs`](crate::query::Pvs)
//! API. Its sets are supersets of what any ray from the cell sees, so a
//! view answered from it loses no pixel: the oracle is conservative
//! (`notes/oracle.md` says why, step by step), and a cell's set only drops
//! objects that the cell's oracle or an ancestor's proved hidden from a box
//! holding it.
//!
//! Invariants: the tree validates ([`VisTree::validate`]): an internal
//! node's set is the union of its children's (each child's oracle set is
//! a subset of its parent's, since the parent's hidden objects stay
//! hidden); the oracle is deterministic and the two halves of a cell are
//! baked independently, so the tree is the same for any thread count.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use crate::bitset::ObjectSet;
use crate::builder::FLAT_THICKNESS;
use crate::geom::Aabb;
use crate::geom::cell::{Cell, grid_value};
use crate::oracle::Oracle;
use crate::scene::Scene;
use crate::tree::{MAX_GRID_BITS, Node, Split, VisTree};

pub use crate::codec::{METHOD_CONSERVATIVE, METHOD_KEY};

/// Settings of a conservative bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeParams {
    /// Cut a cell whose set holds more triangles than this (papers/001's
    /// polygon budget); `None` takes [`BakeParams::default_budget`] of the
    /// scene.
    pub triangle_budget: Option<u64>,
    /// The deepest a leaf may be.
    pub max_depth: u32,
    /// The smallest cell side, as a fraction of the root's extent along it.
    pub min_cell_fraction: f32,
    /// Split values lie on a 2^q grid of the node's range; the bake cuts
    /// at middles only, so 1 (the default) codes them.
    pub grid_bits: u32,
    /// The positions to bake for, local coordinates (default: the scene's
    /// bounding box).
    pub view_box: Option<Aabb>,
    /// Grow the view box by this fraction of its diagonal on every side.
    pub view_grow: f32,
    /// The most nodes the tree may have.
    pub max_nodes: u64,
    /// Try the middle of every side and cut where the two halves' sets
    /// hold the fewest triangles together (the oracle runs on the halves
    /// of every cut tried); `false` (the default) cuts the longest side.
    /// On the office, trying took answers from 22.6 to 20.9 objects a
    /// view for 2.4-3x the time, where one more level of longest-side cuts
    /// gave 20.6 for 1.7x (`notes/oracle.md`).
    pub try_cuts: bool,
    /// Stop cutting where this many levels in a row proved nothing more
    /// hidden (a cell's set equal to its parent's, that one's to its
    /// parent's, ...); 0 (the default) never stops early. Big cells of
    /// open scenes, from which the oracle proves nothing, are then not cut
    /// to the depth limit for nothing (San Francisco: 15 cells instead of
    /// 2,047, the same answers); but in buildings the top levels often
    /// prove nothing and deeper ones do (the duplex: 9.5x the objects
    /// seen with 3, 8.2x without), so it is off unless asked for.
    pub stall_levels: u32,
}

impl Default for BakeParams {
    fn default() -> Self {
        Self {
            triangle_budget: None,
            max_depth: 10,
            min_cell_fraction: 1.0 / 64.0,
            grid_bits: 1,
            view_box: None,
            view_grow: 0.0,
            max_nodes: 1 << 24,
            try_cuts: false,
            stall_levels: 0,
        }
    }
}

/// Why a bake could not run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BakeError {
    /// A setting is outside its domain.
    #[error("invalid bake setting: {name} must be {expected}, not {value}")]
    Parameter {
        /// The setting (as [`BakeParams`] names it).
        name: &'static str,
        /// What it must be.
        expected: &'static str,
        /// What it was.
        value: String,
    },
    /// The tree could have more nodes than [`BakeParams::max_nodes`]
    /// (checked before the bake from the depth limit and the smallest
    /// cell).
    #[error(
        "the tree could have more than {max_nodes} nodes (its depth limit and smallest cell \
         allow it, and each node costs an oracle run): raise the node budget (--max-nodes) if \
         the machine has the memory and time, or coarsen the tree (a smaller --max-depth, a \
         larger --min-cell)"
    )]
    TooManyNodes {
        /// The budget.
        max_nodes: u64,
    },
}

impl BakeParams {
    /// The triangle budget used when none is given: a hundredth of the
    /// scene's triangles, and at least 500 (the sampled builder's "split
    /// only if at least 500 polygons are visible").
    pub fn default_budget(scene: &Scene) -> u64 {
        (scene.triangles().len() as u64 / 100).max(500)
    }

    /// The budget for `scene`.
    pub fn budget(&self, scene: &Scene) -> u64 {
        self.triangle_budget
            .unwrap_or_else(|| Self::default_budget(scene))
    }

    /// Checks the settings; the error names the bad one.
    pub fn validate(&self) -> Result<(), BakeError> {
        let bad = |name, expected, value: &dyn std::fmt::Display| BakeError::Parameter {
            name,
            expected,
            value: value.to_string(),
        };
        if self.max_depth > crate::tree::MAX_DEPTH {
            return Err(bad("max_depth", "at most 64", &self.max_depth));
        }
        if !(self.min_cell_fraction >= 1e-6 && self.min_cell_fraction < 0.5) {
            return Err(bad(
                "min_cell_fraction",
                "in [1e-6, 0.5)",
                &self.min_cell_fraction,
            ));
        }
        if !(1..=MAX_GRID_BITS).contains(&self.grid_bits) {
            return Err(bad("grid_bits", "in 1..=16", &self.grid_bits));
        }
        if !(self.view_grow.is_finite() && (0.0..=100.0).contains(&self.view_grow)) {
            return Err(bad("view_grow", "in [0, 100]", &self.view_grow));
        }
        if let Some(b) = self.view_box
            && !(b.min.is_finite() && b.max.is_finite() && b.min.cmple(b.max).all())
        {
            return Err(bad(
                "view_box",
                "finite with min <= max",
                &format!("{:?} .. {:?}", b.min.to_array(), b.max.to_array()),
            ));
        }
        if let Some(b) = self.view_box
            && crate::builder::root_of(b, self.view_grow).is_none()
        {
            return Err(bad(
                "view_box",
                crate::builder::ROOT_FITS,
                &format!("{:?} .. {:?}", b.min.to_array(), b.max.to_array()),
            ));
        }
        if self.max_nodes == 0 {
            return Err(bad("max_nodes", "at least 1", &self.max_nodes));
        }
        Ok(())
    }

    /// The root box for `scene`: the view box (or the scene's bounds),
    /// grown, and thickened where flat, as the sampled builder does.
    pub fn root_box(&self, scene: &Scene) -> Aabb {
        let b = self.view_box.unwrap_or(scene.bounds());
        let b = b.expanded(self.view_grow * b.diagonal());
        b.thickened(FLAT_THICKNESS * b.diagonal())
    }

    /// The parameters as `key=value` lines, as stored in `.v5d` files:
    /// [`METHOD_KEY`]`=`[`METHOD_CONSERVATIVE`] first, then the bake's and
    /// `oracle`'s settings and rasteriser (the view box in world
    /// coordinates).
    pub fn to_text(&self, oracle: &Oracle) -> String {
        let scene = oracle.scene();
        let rasteriser = oracle.rasteriser().name();
        let oracle = oracle.params();
        let b = self.root_box(scene);
        let frame = scene.frame();
        let lines = [
            format!("{METHOD_KEY}={METHOD_CONSERVATIVE}"),
            format!("vis5d={}", env!("CARGO_PKG_VERSION")),
            format!(
                "view_box={},{}",
                frame.world_text(b.min),
                frame.world_text(b.max)
            ),
            format!("triangle_budget={}", self.budget(scene)),
            format!("max_depth={}", self.max_depth),
            format!("min_cell_fraction={}", self.min_cell_fraction),
            format!("grid_bits={}", self.grid_bits),
            format!("try_cuts={}", self.try_cuts),
            format!("stall_levels={}", self.stall_levels),
            format!("oracle_rasteriser={rasteriser}"),
            format!("oracle_resolution={}", oracle.resolution),
            format!("oracle_extension={}", oracle.extension),
            format!("oracle_planes_per_face={}", oracle.planes_per_face),
            format!("oracle_sweep_planes={}", oracle.sweep_planes),
            format!("oracle_sweep_patches={}", oracle.sweep_patches),
            format!("oracle_sweep_extension={}", oracle.sweep_extension),
            format!("oracle_occludee_depth={}", oracle.occludee_depth),
            format!("oracle_max_occluders={}", oracle.max_occluders),
            format!("oracle_plane_candidates={}", oracle.plane_candidates),
            format!("oracle_placement_occluders={}", oracle.placement_occluders),
            format!(
                "oracle_placement_resolution={}",
                oracle.placement_resolution
            ),
            format!("oracle_shaft_budget={}", oracle.shaft_budget),
            format!("oracle_shaft_depth={}", oracle.shaft_depth),
            format!("oracle_seal_voxels={}", oracle.seal_voxels),
        ];
        // Settings added since: written only where they differ from what
        // files without them were baked with, so that those keep their
        // bytes.
        let mut text = lines.join("\n") + "\n";
        if oracle.sweep_reach != 1 {
            text += &format!("oracle_sweep_reach={}\n", oracle.sweep_reach);
        }
        text
    }
}

/// What a bake did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BakeStats {
    /// Cells the oracle ran on: every node of the tree, and the halves of
    /// the cuts tried and not taken.
    pub cells: u64,
    /// Cells cut because their set was over the budget.
    pub split: u64,
    /// Leaves over the budget, kept whole by the depth limit, the smallest
    /// cell, `stall_levels` or the node budget.
    pub over_budget_leaves: u64,
    /// Oracle time summed over the cells (all threads).
    pub oracle_time: Duration,
    /// Wall-clock time of the bake.
    pub seconds: f64,
}

/// A baked subtree, before it is laid out in preorder.
struct Baked {
    set: ObjectSet,
    split: Option<(Split, Box<Baked>, Box<Baked>)>,
}

impl Baked {
    fn flatten_into(self, nodes: &mut Vec<Node>) {
        match self.split {
            None => nodes.push(Node {
                split: None,
                set: self.set,
            }),
            Some((split, below, above)) => {
                let at = nodes.len();
                nodes.push(Node {
                    split: Some(split),
                    set: self.set,
                });
                below.flatten_into(nodes);
                let above_index = nodes.len() as u32;
                if let Some(s) = nodes[at].split.as_mut() {
                    s.above = above_index;
                }
                above.flatten_into(nodes);
            }
        }
    }
}

struct Ctx<'a> {
    oracle: &'a Oracle<'a>,
    triangles: Vec<u64>,
    budget: u64,
    params: &'a BakeParams,
    /// How many times a side may be halved: its halves stay at least
    /// `min_cell_fraction` of the root's side.
    halvings: u32,
    root_measure: f64,
    nodes: AtomicU64,
    too_many: AtomicBool,
    cells: AtomicU64,
    split: AtomicU64,
    over_budget: AtomicU64,
    oracle_nanos: AtomicU64,
    /// Measure of the finished leaves, as a share of the root's.
    done: Mutex<f64>,
    progress: &'a (dyn Fn(f64) + Sync),
}

/// Bakes the conservative tree of `oracle`'s scene, calling `progress`
/// with the share of the view box finished (0 to 1).
pub fn bake(
    oracle: &Oracle,
    params: &BakeParams,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<(VisTree, BakeStats), BakeError> {
    params.validate()?;
    let start = Instant::now();
    let scene = oracle.scene();
    let root = params.root_box(scene);
    if !(root.min.is_finite() && root.max.is_finite() && (root.max - root.min).is_finite()) {
        return Err(BakeError::Parameter {
            name: "view_box",
            expected: crate::builder::ROOT_FITS,
            value: format!("{:?} .. {:?}", root.min.to_array(), root.max.to_array()),
        });
    }
    // Every node costs an oracle run: refuse, before the first, a tree
    // that could outgrow the node budget (the depth limit and the smallest
    // cell bound it), rather than fail hours later.
    let halvings = (1.0 / f64::from(params.min_cell_fraction)).log2().floor() as u32;
    let most_leaves_log2 = params.max_depth.min(3 * halvings);
    let most_nodes = if most_leaves_log2 >= 63 {
        u64::MAX
    } else {
        (2u64 << most_leaves_log2) - 1
    };
    if most_nodes > params.max_nodes {
        return Err(BakeError::TooManyNodes {
            max_nodes: params.max_nodes,
        });
    }
    let ctx = Ctx {
        oracle,
        triangles: scene
            .objects()
            .iter()
            .map(|o| o.triangle_count() as u64)
            .collect(),
        budget: params.budget(scene),
        params,
        halvings,
        root_measure: Cell::all_directions(root).measure(),
        nodes: AtomicU64::new(1),
        too_many: AtomicBool::new(false),
        cells: AtomicU64::new(0),
        split: AtomicU64::new(0),
        over_budget: AtomicU64::new(0),
        oracle_nanos: AtomicU64::new(0),
        done: Mutex::new(0.0),
        progress,
    };
    let baked = bake_cell(&ctx, Cell::all_directions(root), 0, None, None, 0, [0; 3]);
    if ctx.too_many.load(Ordering::Relaxed) {
        return Err(BakeError::TooManyNodes {
            max_nodes: params.max_nodes,
        });
    }
    let mut nodes = Vec::new();
    baked.flatten_into(&mut nodes);
    let tree = VisTree::from_parts(
        Cell::all_directions(root),
        params.grid_bits,
        scene.objects().len(),
        nodes,
    );
    let stats = BakeStats {
        cells: ctx.cells.load(Ordering::Relaxed),
        split: ctx.split.load(Ordering::Relaxed),
        over_budget_leaves: ctx.over_budget.load(Ordering::Relaxed),
        oracle_time: Duration::from_nanos(ctx.oracle_nanos.load(Ordering::Relaxed)),
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok((tree, stats))
}

/// The oracle's set for `cell`, nested in `parent`'s: the parent's hidden
/// objects are taken as hidden (the oracle skips them), and the result is
/// intersected with the parent's set so that the nesting is exact.
fn oracle_set(ctx: &Ctx, cell: &Cell, parent: Option<&ObjectSet>) -> ObjectSet {
    let hidden = parent.map(|p| {
        let mut h = ObjectSet::full(p.capacity());
        h.subtract(p);
        h
    });
    let t = Instant::now();
    let mut set = ctx.oracle.cell(&cell.space(), hidden.as_ref()).visible;
    ctx.oracle_nanos
        .fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
    ctx.cells.fetch_add(1, Ordering::Relaxed);
    if let Some(p) = parent {
        set.intersect_with(p);
    }
    set
}

/// [`oracle_set`] of several cells with the same parent: on the GPU in one
/// batch ([`Oracle::cells`]: every cell's maps in one submission), on the
/// CPU one cell at a time in parallel (a batch would only hold more maps
/// in memory at once). The same sets either way.
fn oracle_sets(ctx: &Ctx, cells: &[Cell], parent: Option<&ObjectSet>) -> Vec<ObjectSet> {
    use rayon::prelude::*;
    if !ctx.oracle.rasteriser().is_gpu() {
        return cells
            .par_iter()
            .map(|c| oracle_set(ctx, c, parent))
            .collect();
    }
    let hidden = parent.map(|p| {
        let mut h = ObjectSet::full(p.capacity());
        h.subtract(p);
        h
    });
    let batch: Vec<(Aabb, Option<&ObjectSet>)> =
        cells.iter().map(|c| (c.space(), hidden.as_ref())).collect();
    let reports = ctx.oracle.cells(&batch);
    // Each cell's own time (its share of the submission included), as
    // one cell at a time counts it.
    let nanos: u128 = reports.iter().map(|r| r.times.total().as_nanos()).sum();
    ctx.oracle_nanos.fetch_add(nanos as u64, Ordering::Relaxed);
    ctx.cells.fetch_add(cells.len() as u64, Ordering::Relaxed);
    reports
        .into_iter()
        .map(|r| {
            let mut set = r.visible;
            if let Some(p) = parent {
                set.intersect_with(p);
            }
            set
        })
        .collect()
}

/// Bakes `cell`, whose set is `known` when a tried cut already ran the
/// oracle on it; `stalled` levels above it in a row proved nothing more
/// hidden, and its sides were halved `halvings` times.
fn bake_cell(
    ctx: &Ctx,
    cell: Cell,
    depth: u32,
    parent: Option<&ObjectSet>,
    known: Option<ObjectSet>,
    stalled: u32,
    halvings: [u32; 3],
) -> Baked {
    let set = known.unwrap_or_else(|| oracle_set(ctx, &cell, parent));
    let stalled = if parent == Some(&set) { stalled + 1 } else { 0 };
    let stalls = ctx.params.stall_levels > 0 && stalled >= ctx.params.stall_levels;
    let tris = |s: &ObjectSet| -> u64 { s.iter().map(|o| ctx.triangles[o]).sum() };
    let over = tris(&set) > ctx.budget;
    let leaf = |set: ObjectSet| {
        if over {
            ctx.over_budget.fetch_add(1, Ordering::Relaxed);
        }
        // Reported under the lock, so that the share only grows.
        let mut done = ctx.done.lock().unwrap_or_else(|p| p.into_inner());
        *done += cell.measure() / ctx.root_measure;
        (ctx.progress)(done.min(1.0));
        Baked { set, split: None }
    };
    // The cuts: the middle of each side halved fewer times than the
    // smallest cell allows (a cell too thin for the grid in f32 is kept
    // whole), longest side first.
    let q = ctx.params.grid_bits;
    let code = 1u32 << (q - 1);
    let mut cuts: Vec<(usize, f32)> = if over && depth < ctx.params.max_depth && !stalls {
        (0..3)
            .filter(|&d| cell.width(d) > 0.0 && halvings[d] < ctx.halvings)
            .map(|d| (d, grid_value(cell.lo[d], cell.hi[d], code, q)))
            .filter(|&(d, v)| v > cell.lo[d] && v < cell.hi[d])
            .collect()
    } else {
        Vec::new()
    };
    cuts.sort_by(|a, b| {
        cell.width(b.0)
            .total_cmp(&cell.width(a.0))
            .then(a.0.cmp(&b.0))
    });
    if cuts.is_empty() {
        return leaf(set);
    }
    if ctx.too_many.load(Ordering::Relaxed)
        || ctx.nodes.fetch_add(2, Ordering::Relaxed) + 2 > ctx.params.max_nodes
    {
        ctx.too_many.store(true, Ordering::Relaxed);
        return leaf(set);
    }
    ctx.split.fetch_add(1, Ordering::Relaxed);
    // The cut: the longest side's, or, when the cuts are tried, the one
    // whose halves hold the fewest triangles together (the halves are
    // equal in size, so this is the expected set of a random eye; the
    // longest side wins a tie).
    let tried = if ctx.params.try_cuts { cuts.len() } else { 1 };
    let tried_halves: Vec<Cell> = cuts[..tried]
        .iter()
        .flat_map(|&(d, v)| {
            let (below, above) = cell.split(d, v);
            [below, above]
        })
        .collect();
    let mut sets = oracle_sets(ctx, &tried_halves, Some(&set)).into_iter();
    let (dim, value, halves) = cuts[..tried]
        .iter()
        .map(|&(d, v)| {
            let (b, a) = (sets.next(), sets.next());
            let (b, a) = (b.expect("a set per half"), a.expect("a set per half"));
            (tris(&b) + tris(&a), d, v, b, a)
        })
        .reduce(|x, y| if y.0 < x.0 { y } else { x })
        .map(|best| (best.1, best.2, Some((best.3, best.4))))
        .expect("at least one cut");
    let (below, above) = cell.split(dim, value);
    let mut cut = halvings;
    cut[dim] += 1;
    let (known_below, known_above) = match halves {
        Some((b, a)) => (Some(b), Some(a)),
        None => (None, None),
    };
    let (b, a) = rayon::join(
        || bake_cell(ctx, below, depth + 1, Some(&set), known_below, stalled, cut),
        || bake_cell(ctx, above, depth + 1, Some(&set), known_above, stalled, cut),
    );
    // The union of the children's sets: a subset of this cell's oracle set,
    // and what a range query over the cell answers anyway.
    let mut union = b.set.clone();
    union.union_with(&a.set);
    Baked {
        set: union,
        split: Some((
            Split {
                dim: dim as u8,
                code,
                above: 0,
            },
            Box::new(b),
            Box::new(a),
        )),
    }
}
