//! A cell's visible set (papers/003 sec. 5): the candidates proven visible
//! by the cell's cached rays, plus those the SPRT does not reject.
//!
//! Each undecided candidate gets object samples ([`AdaptiveSampler`]:
//! origin first or target first, whichever is rejected less) from its own
//! random stream, in rounds: every round draws a batch per undecided
//! object (4, doubling up to 256), traces all of them in one parallel
//! batch, then goes through each object's outcomes in order. Any ray's
//! closest hit proves that object visible, whoever's sample it was, so
//! objects proven by others stop early. Until its first hit an object has
//! seen only misses, and what the SPRT says after r misses in a row is
//! fixed by its parameters, so it is computed once
//! ([`crate::sprt::SprtParams::misses_decision`]) and the rounds count
//! misses. A candidate is decided:
//! - invisible by geometry, before any ray, when no direction of the cell
//!   reaches its bounding box ([`reachable`]);
//! - visible as soon as a ray hits it;
//! - invisible when the SPRT's odds fall below B and, in an internal node,
//!   after at least `internal_miss_factor` times the misses the SPRT needs
//!   on its own (an object dropped there is lost to the whole subtree);
//! - visible when the SPRT reaches its cap, or when its samples are
//!   almost all rejected ([`AdaptiveSampler::hopeless`], or more than
//!   `rejection_budget` rejected): conservative.
//!
//! The result does not depend on thread count: streams are seeded by
//! (node seed, object) and the rounds are processed in object order.

use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::builder_node::Ctx;
use super::{BuildStats, mix};
use crate::bitset::ObjectSet;
use crate::geom::cell::Cell;
use crate::sample::{AdaptiveSampler, reachable};
use crate::sprt::Decision;
use crate::trace::Ray;

/// One candidate under test.
struct Pending {
    object: usize,
    /// Rays taken that did not hit it.
    misses: u32,
    rng: Pcg64,
    sampler: AdaptiveSampler,
    rejected: u32,
    done: bool,
}

/// The visible set of `cell`: `proven` (objects hit by its cached rays)
/// plus the candidates the SPRT keeps. An object is declared invisible
/// only after at least `min_misses` rays (internal nodes ask for more
/// evidence than the SPRT's own).
pub(super) fn visible_set(
    ctx: &Ctx,
    cell: &Cell,
    candidates: &ObjectSet,
    proven: ObjectSet,
    seed: u64,
    min_misses: u32,
    stats: &mut BuildStats,
) -> ObjectSet {
    let params = ctx.params;
    let mut set = proven;
    stats.decisions.proven_by_hit += set.count() as u64;
    let mut pending: Vec<Pending> = Vec::new();
    for o in candidates.iter() {
        if set.contains(o) {
            continue;
        }
        if !reachable(cell, &ctx.scene.objects()[o].bounds) {
            stats.decisions.geometry_invisible += 1;
            continue;
        }
        pending.push(Pending {
            object: o,
            misses: 0,
            rng: Pcg64::seed_from_u64(mix(seed, o as u64)),
            sampler: AdaptiveSampler::new(cell),
            rejected: 0,
            done: false,
        });
    }

    let mut batch = 4u32;
    let mut rays: Vec<Ray> = Vec::new();
    let mut owner: Vec<u32> = Vec::new();
    while !pending.is_empty() {
        rays.clear();
        owner.clear();
        for (k, p) in pending.iter_mut().enumerate() {
            let mut drawn = 0;
            while drawn < batch {
                match p.sampler.draw(ctx.scene, cell, p.object, &mut p.rng) {
                    Some(r) => {
                        rays.push(r);
                        owner.push(k as u32);
                        drawn += 1;
                    }
                    None => {
                        p.rejected += 1;
                        stats.rejected += 1;
                        if p.rejected > params.rejection_budget || p.sampler.hopeless() {
                            break;
                        }
                    }
                }
            }
        }
        let hits = ctx.trace(&rays, stats);
        stats.object_rays += rays.len() as u64;
        // Proofs first: whatever any ray hit is visible.
        for h in hits.iter().flatten() {
            set.insert(*h as usize);
        }
        let mut next = 0;
        for (k, p) in pending.iter_mut().enumerate() {
            // This object's outcomes are a contiguous run of the batch.
            while next < owner.len() && owner[next] as usize == k {
                let hit = hits[next] == Some(p.object as u32);
                next += 1;
                if p.done {
                    continue;
                }
                if hit {
                    stats.decisions.proven_by_hit += 1;
                    p.done = true;
                    continue;
                }
                p.misses += 1;
                let (stop, decision) = ctx.misses_decision;
                match decision {
                    _ if p.misses < stop => {}
                    Decision::Invisible if p.misses < min_misses => {}
                    Decision::Undecided => unreachable!("the test always ends"),
                    Decision::Invisible => {
                        stats.decisions.sprt_invisible += 1;
                        p.done = true;
                    }
                    Decision::Visible | Decision::CapReached => {
                        stats.decisions.cap_reached += 1;
                        set.insert(p.object);
                        p.done = true;
                    }
                }
            }
            if p.done {
                continue;
            }
            if set.contains(p.object) {
                // Proven by another object's ray.
                stats.decisions.proven_by_hit += 1;
                p.done = true;
            } else if p.rejected > params.rejection_budget || p.sampler.hopeless() {
                stats.decisions.rejection_kept += 1;
                set.insert(p.object);
                p.done = true;
            }
        }
        pending.retain(|p| !p.done);
        batch = (batch * 2).min(256);
    }
    set
}
