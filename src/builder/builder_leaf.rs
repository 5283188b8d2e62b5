//! A cell's visible set (papers/003 sec. 5): the candidates proven visible
//! by the cell's cached rays, plus those the SPRT does not reject.
//!
//! Each undecided candidate gets object samples ([`AdaptiveSampler`]:
//! origin first or aimed target first, whichever is rejected less) from
//! its own random stream, in rounds: every round draws a batch per undecided
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
//!   for an object near one the cell's rays hit, after at least
//!   `internal_miss_factor` times the misses the SPRT needs
//!   on its own (an object dropped there is lost to the whole subtree);
//! - visible when the SPRT reaches its cap, or when its samples are
//!   almost all rejected ([`AdaptiveSampler::hopeless`], or more than
//!   `rejection_budget` rejected): conservative.
//!
//! A leaf also *retests* the objects an ancestor called invisible that lie
//! near an object its cached rays hit
//! ([`BuildParams::retest_rays`](super::BuildParams::retest_rays) samples
//! each, from a stream of their own): an object seen from a small part of
//! a big cell falls under the SPRT's threshold there, but in the leaf that
//! holds that part its visible fraction is large. A retest hit puts it in
//! the leaf's set (and, through the unions, its ancestors'); a retest that
//! only misses, or whose samples are almost all rejected, leaves it out
//! (the ancestor's full test stands).
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
    /// Retested (an ancestor's test dropped it), not a candidate.
    retest: bool,
    /// Rays taken that did not hit it.
    misses: u32,
    /// The fewest misses before it may be called invisible.
    min_misses: u32,
    rng: Pcg64,
    sampler: AdaptiveSampler,
    rejected: u32,
    done: bool,
}

/// The stream family of retest samples (apart from the candidates' own).
const RETEST_STREAM: u64 = 0x7265_7465_7374;

/// What a cell tests.
pub(super) struct Tests<'a> {
    /// The candidates (the parent's set; every object at the root).
    pub candidates: &'a ObjectSet,
    /// Objects an ancestor called invisible, to retest (empty but in
    /// leaves).
    pub retest: &'a ObjectSet,
    /// Objects hit by the cell's cached rays.
    pub proven: ObjectSet,
    /// An object is declared invisible only after at least this many rays
    /// (internal nodes ask for more evidence than the SPRT's own).
    pub min_misses: u32,
    /// The objects near one the cell's rays hit: `min_misses` applies to
    /// these only (the others need the SPRT's own misses).
    pub near: &'a ObjectSet,
}

/// What a cell's tests decided.
pub(super) struct Decided {
    /// `proven` plus the candidates the SPRT keeps plus the retested
    /// objects a ray hits.
    pub set: ObjectSet,
    /// The candidates the SPRT called invisible (for the leaves below to
    /// retest).
    pub rejected: ObjectSet,
    /// The fewest misses behind one of those (`u32::MAX` when none).
    pub fewest_misses: u32,
    /// Candidates kept without a decision (rejected samples, ray cap).
    pub undecided: u32,
}

/// Tests the candidates and retests of `cell` (see the module docs).
pub(super) fn visible_set(
    ctx: &Ctx,
    cell: &Cell,
    tests: Tests<'_>,
    seed: u64,
    stats: &mut BuildStats,
) -> Decided {
    let mut d = Decided {
        set: tests.proven,
        rejected: ObjectSet::new(tests.candidates.capacity()),
        fewest_misses: u32::MAX,
        undecided: 0,
    };
    stats.decisions.proven_by_hit += d.set.count() as u64;
    // The candidates first, exactly as without retests; then the retests,
    // which can then only add objects (a retest ray that proved a
    // candidate early would stop that candidate's samples, and a later one
    // of them might have proven a third object).
    let retest_seed = mix(seed, RETEST_STREAM);
    for (objects, retest) in [(tests.candidates, false), (tests.retest, true)] {
        let mut pending: Vec<Pending> = Vec::new();
        for o in objects.iter() {
            if d.set.contains(o) {
                continue;
            }
            if !reachable(cell, &ctx.scene.objects()[o].bounds) {
                if !retest {
                    stats.decisions.geometry_invisible += 1;
                }
                continue;
            }
            if retest {
                stats.decisions.retested += 1;
            }
            pending.push(Pending {
                object: o,
                retest,
                misses: 0,
                min_misses: if tests.near.contains(o) {
                    tests.min_misses
                } else {
                    0
                },
                rng: Pcg64::seed_from_u64(mix(if retest { retest_seed } else { seed }, o as u64)),
                sampler: AdaptiveSampler::new(cell),
                rejected: 0,
                done: false,
            });
        }
        run(ctx, cell, pending, &mut d, stats);
    }
    // An object the SPRT dropped may have been hit by a later ray.
    d.rejected.subtract(&d.set);
    d
}

/// Samples every object of `pending` until it is decided, in rounds (see
/// the module docs), adding to `d.set` what rays prove and to
/// `d.rejected` the candidates the SPRT calls invisible.
fn run(ctx: &Ctx, cell: &Cell, mut pending: Vec<Pending>, d: &mut Decided, stats: &mut BuildStats) {
    let set = &mut d.set;
    let params = ctx.params;
    // Retests nearly all end in their whole budget of misses: one round.
    let retests = pending.first().is_some_and(|p| p.retest);
    let mut batch = if retests {
        params.retest_rays.max(4)
    } else {
        4u32
    };
    let mut rays: Vec<Ray> = Vec::new();
    let mut owner: Vec<u32> = Vec::new();
    while !pending.is_empty() {
        rays.clear();
        owner.clear();
        for (k, p) in pending.iter_mut().enumerate() {
            let mut drawn = 0;
            // A retest needs no more than its budget.
            let want = if p.retest {
                batch.min(params.retest_rays.saturating_sub(p.misses))
            } else {
                batch
            };
            while drawn < want {
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
                    if p.retest {
                        stats.decisions.retest_found += 1;
                    } else {
                        stats.decisions.proven_by_hit += 1;
                    }
                    p.done = true;
                    continue;
                }
                p.misses += 1;
                if p.retest {
                    // The ancestor's full test stands unless a retest ray
                    // hits.
                    p.done = p.misses >= params.retest_rays;
                    continue;
                }
                let (stop, decision) = ctx.misses_decision;
                match decision {
                    _ if p.misses < stop => {}
                    Decision::Invisible if p.misses < p.min_misses => {}
                    Decision::Undecided => unreachable!("the test always ends"),
                    Decision::Invisible => {
                        stats.decisions.sprt_invisible += 1;
                        d.rejected.insert(p.object);
                        d.fewest_misses = d.fewest_misses.min(p.misses);
                        p.done = true;
                    }
                    Decision::Visible | Decision::CapReached => {
                        stats.decisions.cap_reached += 1;
                        d.undecided += 1;
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
                if p.retest {
                    stats.decisions.retest_found += 1;
                } else {
                    stats.decisions.proven_by_hit += 1;
                }
                p.done = true;
            } else if p.retest && (p.rejected > params.rejection_budget || p.sampler.hopeless()) {
                // Out of this leaf's directions, nearly: the ancestor's
                // test stands.
                p.done = true;
            } else if p.rejected > params.rejection_budget || p.sampler.hopeless() {
                stats.decisions.rejection_kept += 1;
                d.undecided += 1;
                set.insert(p.object);
                p.done = true;
            }
        }
        pending.retain(|p| !p.done);
        batch = (batch * 2).min(256);
    }
}
