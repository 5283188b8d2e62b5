//! Shafts: an object hidden from the cell one occluder at a time, the cell
//! and the object's box cut in halves until every part of the segments
//! between them is blocked by a single convex occluder.
//!
//! The Depth Maps fuse occluders on planes parallel to the cell's faces:
//! a wall at right angles to the plane covers only a line of it, so the
//! furniture of the room across a corridor, hidden from a room by its
//! walls and the partitions beyond them *together*, stays kept. Here the
//! fusion comes from cutting the segments instead (strong occlusion, after
//! Cohen-Or et al. 1998, with the subdivision of papers/001's occludee
//! test): for a part `A` of the cell and a part `B` of the object's box,
//! every segment from `A` to `B` is blocked when some convex occluder `O`
//! holds, inside it, every point where those segments cross a plane `P`
//! that has `A` strictly on one side and `B` strictly on the other. Those
//! crossings fill `conv(A u B) n P`, the convex hull of the crossings of
//! the 64 segments between the boxes' corners (a point of `conv(A u B)` on
//! `P` lies on a segment from a point of `A` to a point of `B`, and that
//! segment's crossing moves projectively, convexity kept, with its ends):
//! so the 64 corner crossings inside `O` suffice.
//!
//! Why a segment crossing `P` inside `O` cannot see `B`'s object:
//! - `O` a closed convex solid: the segment passes through `O`'s inside;
//!   when its start `a` is outside `O` it enters `O` before the crossing,
//!   and when its end `b` is outside it leaves `O` after the crossing:
//!   either way it meets `O`'s (watertight) surface strictly between `a`
//!   and `b`. So one of the two boxes must be apart from `O`'s box (by the
//!   tracer's rounding), and the crossings must lie inside `O` by that
//!   rounding plus its convexity tolerance. For a convex solid no common
//!   plane is needed: each segment may pass through it anywhere. The
//!   segments from `A` meeting a convex set `O'` (here `O` shrunk by the
//!   margin) end in a convex set (for two ends `x1`, `x2` whose segments
//!   from `a` meet `O'` at `y1`, `y2`, the segment from `a` to a point
//!   between them crosses `[y1, y2]`, inside `O'`), and likewise in `a`
//!   for a fixed end: so when the 64 segments between the boxes' corners
//!   each meet `O'`, every segment from `A` to `B` does
//!   ([`segments_through`]).
//! - `O` a planar convex polygon: `P` is its plane and the crossing is on
//!   it, inside it by the rounding plus the polygon's flatness tolerance,
//!   over the smallest sine of a segment's angle to the plane: a grazing
//!   ray moved by the tracer's rounding, or a slightly bent polygon,
//!   crosses far from `P`'s point along the plane (a review found rays
//!   at a thousandth of a radian past a triangle's edge that the rounding
//!   alone, not divided, had hidden).
//! - the cuts of a sliceable solid likewise: the rectangle of the
//!   crossings grown by the rounding over that sine.
//! - `O` of the object itself is no proof (a hit on it is the object
//!   seen), so an object's own occluders are skipped.
//!
//! The cuts of a sliceable solid are at several depths across its box:
//! a segment crossing a joint between two abutting walls at the middle of
//! the wall crosses one or the other nearer a face.
//! A shaft no occluder blocks is cut: the longer of the two boxes at its
//! middle (an object's box along its tree of triangle clusters, whose
//! boxes are tighter), each half a shaft of its own, until a depth or a
//! budget of tests runs out: then the object is kept.
//!
//! Before it is cut, a shaft may go through a *portal*. A sliceable solid
//! whose cut holds every crossing but those in a hole (a wall's door, the
//! gap beside a box) blocks every segment crossing outside the hole's
//! bounding rectangle `H` (the crossings within the rounding of a loop
//! count as in the hole); every other segment passes through the flat box
//! `H` on the cut's plane, so what is left is the segments from the cell's
//! part `F` through `H` to `B`. Those are searched as a shaft from `H` to
//! `B` that remembers `F`: at a later plane a segment crosses inside the
//! rectangle of every pair of the three boxes it passes through in turn
//! on the plane's two sides (`H` and `B`, `F` and `B`, `F` and `H`), and,
//! when `H` lies between `F` and the plane, inside the corners' bound of
//! the lines from `F` through `H` carried on to the plane (the crossing
//! is linear in the ends' coordinates across the plane's axis and monotone
//! in them along it); their intersection bounds it, and an empty
//! intersection means no segment is left. Any of `F`, `H`, `B` apart from
//! a solid puts a point of the segment outside it, and the crossing lies
//! between the segment's ends, so the solid's surface is hit before `B`.
//! Two walls with doors that do not line up then hide what is behind
//! both in a handful of shafts, where halving needed hundreds (a shaft
//! straddling a door's edge is blocked by neither wall alone). A portal's
//! search is capped at two shafts, paid out of the object's budget.

use std::cmp::Ordering;

use glam::{DVec2, DVec3};

use super::oracle_clusters::Cluster;
use super::oracle_occluders::{Occluder, SlicedSolid};
use super::oracle_project::{Frame, corners};
use super::oracle_slice::slice_segments;
use super::oracle_terrain::Terrain;
use crate::geom::{Aabb, BoxNode, BoxTree};

/// How many segments from the cell to an object's surface look for a
/// witness that it is seen before its shafts are tried (a guide: a seen
/// object would use up its budget of shafts for nothing).
pub const WITNESSES: usize = 16;

/// The most occluders met by the segment between two parts' centres that
/// are tried for one shaft, nearest the cell's part first (a long segment
/// across a city's terrain meets thousands of its triangles).
const MET: usize = 64;

/// The most shafts one portal's search may test (taken from the object's
/// budget): the shaft from the portal, and one more portal beyond it. On
/// the offices 2 kept fewer objects than 1, 3 or 8 (52.8 against 53.6,
/// 53.2 and 53.1 a room cell), in less time: a failed portal's shafts
/// are not there for the cuts.
const PORTAL_SHAFTS: usize = 2;
/// A portal is followed when it holds at most this share of the area of
/// the crossings' rectangle on its cut.
const PORTAL_SHARE: f64 = 0.75;

/// Where, across a solid's box along each axis, its cuts lie (the
/// middle first).
const DEPTHS: [f64; 3] = [0.5, 0.15, 0.85];

/// A polygon's plane `(n, c)` (`n . p = c`, `n` a unit vector) and the
/// half-planes of its edges within it (`m . p <= e`, `m` outward and
/// unit); for a convex solid, its ellipsoids ([`Balls`]).
#[derive(Clone, Debug, Default)]
struct Blocker {
    planes: Vec<(DVec3, f64)>,
    edges: Vec<(DVec3, f64)>,
    /// A polygon's flatness tolerance (how far its corners may lie off its
    /// plane); 0 for a solid.
    flatness: f64,
    /// A convex solid's ellipsoids, for quick answers before its planes.
    balls: Option<Balls>,
}

/// Two ellipsoids about a point `centre` inside a convex solid, their
/// axes along x, y and z with the half-widths of its box (`1 / inv`): in
/// the coordinates `(x - centre) * inv`, where they are balls, every
/// corner lies within `outer` of the origin, and a point within `k` lies
/// inside every face plane (`n . x <= e`) by at least `(k - r) hmin`
/// for `r` its distance from the origin (`hmin`, the least `|n / inv|`),
/// so by the margin `m` when `r <= k - m / hmin`.
#[derive(Clone, Copy, Debug)]
struct Balls {
    centre: DVec3,
    inv: DVec3,
    k: f64,
    hmin: f64,
    outer: f64,
}

/// The share of a length, in the balls' coordinates, by which f64 may
/// have rounded a distance computed from it (some 10^-15 in truth).
const ROUNDING: f64 = 1e-12;

impl Balls {
    /// The distance, in the balls' coordinates, from the origin to the
    /// segment `p -> p + d`, and a bound on its rounding.
    fn distance(&self, p: DVec3, d: DVec3) -> (f64, f64) {
        let (p, d) = ((p - self.centre) * self.inv, d * self.inv);
        let dd = d.length_squared();
        let t = if dd > 0.0 {
            (-p.dot(d) / dd).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let rounding = ROUNDING * (1.0 + p.length() + d.length());
        ((p + d * t).length(), rounding)
    }

    /// Whether a segment at [`Balls::distance`] `(r, rounding)` misses the
    /// solid.
    fn outside(&self, (r, rounding): (f64, f64)) -> bool {
        r - rounding > self.outer
    }

    /// Whether a segment at [`Balls::distance`] `(r, rounding)` has a
    /// point inside every plane by `margin`.
    fn inside(&self, (r, rounding): (f64, f64), margin: f64) -> bool {
        r + rounding < self.k - margin / self.hmin
    }
}

/// The shaft tests' view of the occluders, built once per scene.
pub struct Shafts {
    /// Per occluder (those given to [`Shafts::new`], which each search
    /// must hold in the same order: solids' hints count on from them).
    blockers: Vec<Blocker>,
    tree: SegmentTree,
    /// The solids with cuts: the sliceable solids, then the convex shells.
    cut_solids: Vec<CutSolid>,
    /// Per solid with cuts, its cuts by axis-aligned planes.
    cuts: Vec<Vec<Cut>>,
    solid_tree: SegmentTree,
}

/// What the cut tests need of a solid with cuts: a sliceable solid (whose
/// cuts are where its triangles cross a plane), or a convex shell (whose
/// cuts are its shrunk polytope's cross-sections, convex polygons: a
/// segment crossing one passes through the polytope, which the shell's
/// argument covers as it does for the polytope as a solid).
#[derive(Clone, Copy, Debug)]
struct CutSolid {
    object: u32,
    /// Its box: for a shell, the box of its polygons, which holds the
    /// polytope before it was shrunk.
    min: DVec3,
    max: DVec3,
    open_bottom: Option<f64>,
    /// For a shell, the largest cell slack it may be used from.
    shell_slack: Option<f64>,
    /// For a shell, its occluder (which blocks as the convex solid it is;
    /// its cuts give portals).
    shell: Option<u32>,
}

/// A [`BoxTree::for_segments`] made four wide for [`along_until`]: each
/// node holds the boxes of up to four children (the binary tree's nodes
/// of largest area opened until four are left), in f32 lanes that one
/// pass tests together, relative to the centre of the whole and grown by
/// [`SegmentTree::GROW`] of its size (many times the f32 rounding of a
/// point in it).
struct SegmentTree {
    nodes: Vec<WideNode>,
    centre: DVec3,
}

/// A node of a [`SegmentTree`]: per lane (child), its box's lower and
/// upper bounds along each axis, and the child (a node's index, or an
/// object where `leaves` has its bit).
#[derive(Clone, Copy, Debug)]
struct WideNode {
    min: [[f32; 4]; 3],
    max: [[f32; 4]; 3],
    child: [u32; 4],
    count: u8,
    leaves: u8,
}

impl SegmentTree {
    /// The growth of the boxes, relative to the whole's half size.
    const GROW: f64 = 64.0 * f32::EPSILON as f64;

    fn new(boxes: &[Aabb]) -> Self {
        let tree = BoxTree::for_segments(boxes);
        let mut nodes = Vec::new();
        let Some(root) = tree.nodes().first() else {
            return Self {
                nodes,
                centre: DVec3::ZERO,
            };
        };
        let (lo, hi) = (root.bounds().min.as_dvec3(), root.bounds().max.as_dvec3());
        let centre = 0.5 * (lo + hi);
        let pad = Self::GROW * (0.5 * (hi - lo)).max_element() + f64::from(f32::MIN_POSITIVE);
        Self::widen(tree.nodes(), 0, (centre, pad), &mut nodes);
        Self { nodes, centre }
    }

    /// The root of `binary`'s node `k` made wide, appended to `wide`
    /// (children after their parent), its boxes relative to `centre` and
    /// grown by `pad`; returns its index.
    fn widen(
        binary: &[BoxNode],
        k: u32,
        (centre, pad): (DVec3, f64),
        wide: &mut Vec<WideNode>,
    ) -> u32 {
        let mut lanes: Vec<u32> = match binary[k as usize] {
            BoxNode::Object { .. } => vec![k],
            BoxNode::Inner { children, .. } => children.to_vec(),
        };
        while lanes.len() < 4 {
            let area = |c: u32| {
                let s = binary[c as usize].bounds().size();
                s.x * s.y + s.y * s.z + s.z * s.x
            };
            let open = lanes
                .iter()
                .enumerate()
                .filter_map(|(i, &c)| match binary[c as usize] {
                    BoxNode::Inner { children, .. } => Some((i, area(c), children)),
                    BoxNode::Object { .. } => None,
                })
                .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
            let Some((i, _, children)) = open else { break };
            lanes.splice(i..=i, children);
        }
        let me = wide.len() as u32;
        wide.push(WideNode {
            min: [[f32::INFINITY; 4]; 3],
            max: [[f32::NEG_INFINITY; 4]; 3],
            child: [0; 4],
            count: lanes.len() as u8,
            leaves: 0,
        });
        for (lane, &c) in lanes.iter().enumerate() {
            let node = &binary[c as usize];
            let b = node.bounds();
            let child = match *node {
                BoxNode::Object { object, .. } => {
                    wide[me as usize].leaves |= 1 << lane;
                    object
                }
                BoxNode::Inner { .. } => Self::widen(binary, c, (centre, pad), wide),
            };
            let w = &mut wide[me as usize];
            w.child[lane] = child;
            let (lo, hi) = (
                b.min.as_dvec3() - centre - pad,
                b.max.as_dvec3() - centre + pad,
            );
            for axis in 0..3 {
                // Rounded outwards, so the grown box holds the box.
                w.min[axis][lane] = (lo[axis] as f32).next_down();
                w.max[axis][lane] = (hi[axis] as f32).next_up();
            }
        }
        me
    }
}

/// A sliceable solid's cut by the plane `p[axis] = at`: closed loops of
/// segments in the plane's `(u, v)` (the other two axes in turn), and
/// their bounding rectangle.
#[derive(Clone, Debug)]
struct Cut {
    axis: usize,
    at: f64,
    segments: Vec<[DVec2; 2]>,
    lo: DVec2,
    hi: DVec2,
}

/// A part of an object's box: a box, and the cluster it is, if any.
#[derive(Clone, Copy, Debug)]
struct Part {
    min: DVec3,
    max: DVec3,
    cluster: Option<u32>,
}

/// What one object's search needs.
pub struct Search<'a> {
    /// The occluders (as the oracle holds them, and as [`Shafts::new`]
    /// was given them).
    pub occluders: &'a [Occluder],
    /// Objects whose occluders and solids are not used (proved hidden from
    /// a parent cell, so `check`'s top-down walk matches the maps').
    pub skip: &'a (dyn Fn(u32) -> bool + Sync),
    /// The tracer's rounding at the cell's scale.
    pub slack: f64,
    /// The most shafts tested for one object.
    pub budget: usize,
    /// The most cuts along one path.
    pub depth: usize,
    /// The terrains the cell may use ([`Terrain::usable`] from it): a
    /// segment from the cell that passes below one's surface over its
    /// rectangle is blocked.
    pub terrains: &'a [&'a Terrain],
}

impl Shafts {
    /// The blocking planes of every occluder and a hierarchy of their
    /// boxes.
    pub fn new(occluders: &[Occluder], solids: &[SlicedSolid]) -> Self {
        let blockers = occluders.iter().map(blocker).collect();
        let boxes: Vec<Aabb> = occluders.iter().map(|o| outward(o.min, o.max)).collect();
        let mut cut_solids: Vec<CutSolid> = solids
            .iter()
            .map(|s| CutSolid {
                object: s.object,
                min: s.min,
                max: s.max,
                open_bottom: s.open_bottom,
                shell_slack: None,
                shell: None,
            })
            .collect();
        let mut cuts: Vec<Vec<Cut>> = solids.iter().map(solid_cuts).collect();
        for (i, o) in occluders.iter().enumerate() {
            if o.shell_slack.is_some() {
                cut_solids.push(CutSolid {
                    object: o.object,
                    min: o.min,
                    max: o.max,
                    open_bottom: None,
                    shell_slack: o.shell_slack,
                    shell: Some(i as u32),
                });
                cuts.push(shell_cuts(o));
            }
        }
        let solid_boxes: Vec<Aabb> = cut_solids.iter().map(|s| outward(s.min, s.max)).collect();
        Self {
            blockers,
            tree: SegmentTree::new(&boxes),
            cut_solids,
            cuts,
            solid_tree: SegmentTree::new(&solid_boxes),
        }
    }

    /// Whether every segment from the cell `[cmin, cmax]` to object
    /// `object`'s box `[qmin, qmax]` (its clusters `clusters`, root first,
    /// may be empty) is blocked, shaft by shaft, by occluders of other
    /// objects.
    pub fn hidden(
        &self,
        search: &Search,
        object: u32,
        clusters: &[Cluster],
        cell: (DVec3, DVec3),
        qmin: DVec3,
        qmax: DVec3,
    ) -> bool {
        let b = Part {
            min: qmin,
            max: qmax,
            cluster: (!clusters.is_empty()).then_some(0),
        };
        debug_assert_eq!(search.occluders.len(), self.blockers.len());
        let mut budget = search.budget;
        let mut hint = None;
        self.shaft(
            search,
            object,
            clusters,
            (cell, None),
            b,
            0,
            &mut budget,
            &mut hint,
        )
    }

    /// Whether every segment from the part `a.0` (of the cell, or a
    /// portal every segment passes through) to the part `b` of the object
    /// is blocked; `a.1` is the part of the cell those segments start from
    /// when `a.0` is a portal.
    #[allow(clippy::too_many_arguments)]
    fn shaft(
        &self,
        search: &Search,
        object: u32,
        clusters: &[Cluster],
        (a, from): ((DVec3, DVec3), Option<(DVec3, DVec3)>),
        b: Part,
        depth: usize,
        budget: &mut usize,
        hint: &mut Option<usize>,
    ) -> bool {
        if *budget == 0 {
            return false;
        }
        *budget -= 1;
        let (bmin, bmax) = (b.min, b.max);
        // A part meeting the cell is seen from where it is.
        if bmin.cmple(a.1).all() && bmax.cmpge(a.0).all() {
            return false;
        }
        if let Some(k) = *hint {
            let blocked = match k.checked_sub(search.occluders.len()) {
                None => self.blocks(search, k, a, (bmin, bmax)),
                Some(solid) => self.solid_blocks(search, solid, (a, from), (bmin, bmax)),
            };
            if blocked {
                return true;
            }
        }
        // An occluder blocking every segment blocks the one between the
        // boxes' centres: only those meeting it are tried. None: that
        // segment is in some part of every cut, which nothing can block.
        let (p, q) = (0.5 * (a.0 + a.1), 0.5 * (bmin + bmax));
        let mut any = false;
        let tried = *hint;
        let mut met = 0;
        let mut occluder = |t: u32| {
            let k = t as usize;
            let o = &search.occluders[k];
            if o.object == object
                || (search.skip)(o.object)
                || !o.usable(search.slack)
                || !meets(o, self.blockers[k].balls, p, q)
            {
                return false;
            }
            any = true;
            met += 1;
            if met > MET {
                return true;
            }
            Some(k) != tried && self.blocks(search, k, a, (bmin, bmax))
        };
        let mut found = None;
        if along_until(&self.tree, p, q, &mut |t| {
            let hit = occluder(t);
            if hit {
                found = Some(t as usize);
            }
            hit
        }) && met <= MET
        {
            *hint = found;
            return true;
        }
        // Sliceable solids (closed, or open only at the bottom, not
        // convex) along the same segment, by their cuts.
        let offset = search.occluders.len();
        let mut solid_found = None;
        // The solids met, in the walk's order, for the portal's search
        // below (which would walk the same segment again).
        let mut met_solids = MetSolids::default();
        if along_until(&self.solid_tree, p, q, &mut |k| {
            let k = k as usize;
            let Some(solid) = self.cut_solids.get(k) else {
                return false;
            };
            if solid.object == object || (search.skip)(solid.object) || !solid.usable(search) {
                return false;
            }
            met_solids.push(k);
            any = true;
            let hit =
                Some(offset + k) != tried && self.solid_blocks(search, k, (a, from), (bmin, bmax));
            if hit {
                solid_found = Some(offset + k);
            }
            hit
        }) {
            *hint = solid_found;
            return true;
        }
        // The terrains, by their cuts on planes between the parts.
        if !search.terrains.is_empty() {
            if terrain_blocks(search, from.unwrap_or(a), (bmin, bmax)) {
                return true;
            }
            any = true;
        }
        if !any || depth >= search.depth {
            return false;
        }
        // A solid that blocks the segments crossing its cut but for those
        // through a hole (a door in a wall, the gap beside a box): the
        // rest go on from the hole, a portal.
        if let Some(portal) =
            self.portal(search, object, (a, from), (bmin, bmax), (p, q), &met_solids)
        {
            // Followed only a shaft or two deep: a wall beyond the portal
            // blocks it at once or not at all, and a failed portal is paid
            // for out of the shafts that cutting would have used.
            let mut sub = (*budget).min(PORTAL_SHAFTS);
            let before = sub;
            let ok = self.shaft(
                search,
                object,
                clusters,
                (portal, Some(from.unwrap_or(a))),
                b,
                depth + 1,
                &mut sub,
                hint,
            );
            *budget -= before - sub;
            if ok {
                return true;
            }
        }
        // Cut the box and side that spread the crossings most: a side's
        // length times the sine of its angle to the shaft's axis.
        let (asize, bsize) = (a.1 - a.0, bmax - bmin);
        let d = (0.5 * (bmin + bmax - a.0 - a.1)).normalize_or_zero();
        let across = DVec3::ONE - d * d;
        let spread = |size: DVec3| {
            let s = size * across.max(DVec3::ZERO).map(f64::sqrt);
            (s.max_element(), longest(s))
        };
        let ((aspread, aaxis), (bspread, baxis)) = (spread(asize), spread(bsize));
        if aspread >= bspread {
            let axis = aaxis;
            let mid = 0.5 * (a.0[axis] + a.1[axis]);
            let (mut lo, mut hi) = (a.1, a.0);
            lo[axis] = mid;
            hi[axis] = mid;
            self.shaft(
                search,
                object,
                clusters,
                ((a.0, lo), from),
                b,
                depth + 1,
                budget,
                hint,
            ) && self.shaft(
                search,
                object,
                clusters,
                ((hi, a.1), from),
                b,
                depth + 1,
                budget,
                hint,
            )
        } else {
            let halves = match b.cluster.and_then(|k| clusters[k as usize].children) {
                Some(children) => children.map(|k| {
                    let c = &clusters[k as usize];
                    Part {
                        min: c.min,
                        max: c.max,
                        cluster: Some(k),
                    }
                }),
                None => {
                    // A leaf cluster (all its triangles inside its box) or
                    // a box: halves of the box.
                    let axis = baxis;
                    let mid = 0.5 * (bmin[axis] + bmax[axis]);
                    let (mut lo, mut hi) = (bmax, bmin);
                    lo[axis] = mid;
                    hi[axis] = mid;
                    [
                        Part {
                            min: bmin,
                            max: lo,
                            cluster: None,
                        },
                        Part {
                            min: hi,
                            max: bmax,
                            cluster: None,
                        },
                    ]
                }
            };
            halves.iter().all(|&h| {
                self.shaft(
                    search,
                    object,
                    clusters,
                    (a, from),
                    h,
                    depth + 1,
                    budget,
                    hint,
                )
            })
        }
    }

    /// Whether solid `k` (of those with cuts) blocks every segment from
    /// box `a.0` to box `b` (through box `a.1` first, when `a.0` is a
    /// portal): a shell as the convex solid it is (a segment from the
    /// portal on is one from `a.0` to `b`, and its cuts' test is one of
    /// the segments' points inside it), a sliceable solid by its cuts.
    fn solid_blocks(
        &self,
        search: &Search,
        k: usize,
        a: ((DVec3, DVec3), Option<(DVec3, DVec3)>),
        b: (DVec3, DVec3),
    ) -> bool {
        match self.cut_solids[k].shell {
            Some(o) => self.blocks(search, o as usize, a.0, b),
            None => self.cuts_block(search, k, a, b),
        }
    }

    /// Whether a cut of sliceable solid `k` blocks every segment from box
    /// `a.0` to box `b` (through box `a.1` first, when `a.0` is a portal):
    /// the plane separates them, the rectangle of the crossings (of the 64
    /// corner segments: the crossing coordinates are monotone in each
    /// end's) lies inside the cut's loops by the slack (no loop segment
    /// comes near it, its centre inside by the even-odd rule), one end is
    /// apart from the solid, and, for a solid open at the bottom, both
    /// boxes lie above its floor (a segment between points above it cannot
    /// pass through the missing floor).
    fn cuts_block(
        &self,
        search: &Search,
        k: usize,
        a: ((DVec3, DVec3), Option<(DVec3, DVec3)>),
        b: (DVec3, DVec3),
    ) -> bool {
        if !self.may_block(search, k, a, b) {
            return false;
        }
        let centres = (0.5 * (a.0.0 + a.0.1), 0.5 * (b.0 + b.1));
        self.cuts[k].iter().any(|cut| {
            // From the cell (not through a portal) every crossing lies in
            // one rectangle, which holds the centres' crossing: one far
            // outside the cut's bounds rules the cut out at once.
            (a.1.is_some() || !crosses_apart(cut, centres, search.slack))
                && crossings(cut, a, b, search.slack).is_some_and(|rect| cut_blocks(cut, rect))
        })
    }

    /// What a cut of solid `k` needs besides its plane: one end (or the
    /// portal) apart from the solid, and every part above the floor of a
    /// solid open at the bottom.
    fn may_block(
        &self,
        search: &Search,
        k: usize,
        (a, from): ((DVec3, DVec3), Option<(DVec3, DVec3)>),
        b: (DVec3, DVec3),
    ) -> bool {
        let solid = &self.cut_solids[k];
        let slack = search.slack;
        let parts = [Some(a), Some(b), from];
        if let Some(floor) = solid.open_bottom
            && parts.iter().flatten().any(|p| p.0.z <= floor + slack)
        {
            return false;
        }
        let pad = DVec3::splat(slack);
        let apart = |(lo, hi): (DVec3, DVec3)| {
            hi.cmplt(solid.min - pad).any() || lo.cmpgt(solid.max + pad).any()
        };
        parts.iter().flatten().any(|&p| apart(p))
    }

    /// The smallest portal a solid along the segment `p -> q` (between the
    /// parts' centres) leaves: a flat box on one of its cuts holding every
    /// crossing of a segment from `a` to `b` that the cut does not block,
    /// when it is at most [`PORTAL_SHARE`] of the crossings' rectangle.
    fn portal(
        &self,
        search: &Search,
        object: u32,
        a: ((DVec3, DVec3), Option<(DVec3, DVec3)>),
        b: (DVec3, DVec3),
        (p, q): (DVec3, DVec3),
        met: &MetSolids,
    ) -> Option<(DVec3, DVec3)> {
        let mut best: Option<(f64, (DVec3, DVec3))> = None;
        let mut visit = |k: usize| {
            let Some(solid) = self.cut_solids.get(k) else {
                return;
            };
            if solid.object == object
                || (search.skip)(solid.object)
                || !solid.usable(search)
                || !self.may_block(search, k, a, b)
            {
                return;
            }
            for cut in &self.cuts[k] {
                // The portal must lie strictly between the part and `b`.
                if !separates(cut, a.0, b, search.slack) {
                    continue;
                }
                let Some((lo, hi, grow)) = crossings(cut, a, b, search.slack) else {
                    continue;
                };
                let Some((hlo, hhi)) = hole(cut, lo, hi, grow) else {
                    continue;
                };
                let (whole, left) = ((hi - lo).element_product(), (hhi - hlo).element_product());
                let share = if whole > 0.0 { left / whole } else { 1.0 };
                if share <= PORTAL_SHARE && best.is_none_or(|(s, _)| share < s) {
                    let (u, v) = ((cut.axis + 1) % 3, (cut.axis + 2) % 3);
                    let (mut min, mut max) = (DVec3::ZERO, DVec3::ZERO);
                    (min[cut.axis], max[cut.axis]) = (cut.at, cut.at);
                    (min[u], min[v], max[u], max[v]) = (hlo.x, hlo.y, hhi.x, hhi.y);
                    best = Some((share, (min, max)));
                }
            }
        };
        match met.list() {
            Some(list) => list.iter().for_each(|&k| visit(k as usize)),
            None => {
                along_until(&self.solid_tree, p, q, &mut |k| {
                    visit(k as usize);
                    false
                });
            }
        }
        best.map(|(_, portal)| portal)
    }

    /// Whether occluder `k` blocks every segment from box `a` to box `b`.
    fn blocks(&self, search: &Search, k: usize, a: (DVec3, DVec3), b: (DVec3, DVec3)) -> bool {
        let o = &search.occluders[k];
        let slack = search.slack;
        let pad = DVec3::splat(slack);
        let apart =
            |(lo, hi): (DVec3, DVec3)| hi.cmplt(o.min - pad).any() || lo.cmpgt(o.max + pad).any();
        if o.solid {
            return (apart(a) || apart(b))
                && segments_through(
                    o,
                    self.blockers[k].balls,
                    a,
                    b,
                    slack + 16.0 * o.tolerance(),
                );
        }
        let blocker = &self.blockers[k];
        blocker
            .planes
            .iter()
            .any(|&(n, c)| crossings_inside(blocker, n, c, a, b, slack))
    }
}

/// The solids a shaft's walk met (their indices in the walk's order), up
/// to [`MetSolids::CAP`]; past that, `list` says to walk again.
#[derive(Default)]
struct MetSolids {
    ids: [u32; MetSolids::CAP],
    count: usize,
}

impl MetSolids {
    const CAP: usize = 32;

    fn push(&mut self, k: usize) {
        if self.count < Self::CAP {
            self.ids[self.count] = k as u32;
        }
        self.count += 1;
    }

    /// The solids met, or `None` when there were more than the cap.
    fn list(&self) -> Option<&[u32]> {
        (self.count <= Self::CAP).then(|| &self.ids[..self.count])
    }
}

/// Visits the items of `tree` whose boxes the segment `p -> q` meets,
/// nearest to `p` first (by where the segment enters their boxes, among
/// a node's children), until `visit` returns true; returns whether it
/// did. A guide for the shafts: the boxes are tested in f32, grown by
/// more than its rounding for segments within the tree's box (a box
/// that the segment only grazes may be missed from far outside it).
fn along_until(tree: &SegmentTree, p: DVec3, q: DVec3, visit: &mut dyn FnMut(u32) -> bool) -> bool {
    if tree.nodes.is_empty() {
        return false;
    }
    // Along an axis the segment does not move on, a large finite inverse
    // (not an infinite one, which times a zero distance is no number)
    // puts the whole segment in or out of the slab.
    const HUGE: f32 = 1e30;
    let d = q - p;
    let origin = (p - tree.centre).as_vec3().to_array();
    let inv = [0, 1, 2].map(|k| {
        let i = (1.0 / d[k]) as f32;
        if i.is_finite() {
            i.clamp(-HUGE, HUGE)
        } else {
            HUGE
        }
    });
    // Nodes, and objects (`true`), the nearest on top; the thread's
    // stack is reused (a walk per test of a shaft: allocating one each
    // time cost more than the walk's arithmetic).
    thread_local! {
        static STACK: std::cell::Cell<Vec<(u32, bool)>> = const { std::cell::Cell::new(Vec::new()) };
    }
    let mut stack = STACK.take();
    stack.clear();
    stack.push((0, false));
    let mut found = false;
    while let Some((k, leaf)) = stack.pop() {
        if leaf {
            if visit(k) {
                found = true;
                break;
            }
            continue;
        }
        let node = &tree.nodes[k as usize];
        let mut t0 = [0.0f32; 4];
        let mut t1 = [1.0f32; 4];
        for axis in 0..3 {
            for lane in 0..4 {
                let u = (node.min[axis][lane] - origin[axis]) * inv[axis];
                let v = (node.max[axis][lane] - origin[axis]) * inv[axis];
                t0[lane] = t0[lane].max(u.min(v));
                t1[lane] = t1[lane].min(u.max(v));
            }
        }
        // The lanes met, farthest first, so the nearest is popped first.
        let mut met = [(0.0f32, 0usize); 4];
        let mut n = 0;
        for lane in 0..node.count as usize {
            if t0[lane] <= t1[lane] {
                let mut i = n;
                while i > 0 && met[i - 1].0 < t0[lane] {
                    met[i] = met[i - 1];
                    i -= 1;
                }
                met[i] = (t0[lane], lane);
                n += 1;
            }
        }
        for &(_, lane) in &met[..n] {
            let leaf = node.leaves & (1 << lane) != 0;
            stack.push((node.child[lane], leaf));
        }
    }
    STACK.set(stack);
    found
}

/// The 64 pairs of a box's corners with another's ([`corners`] order):
/// the eight pairs of like corners first, then the others.
const CORNER_PAIRS: [(usize, usize); 64] = {
    let mut out = [(0, 0); 64];
    let mut k = 0;
    while k < 8 {
        out[k] = (k, k);
        k += 1;
    }
    let mut i = 0;
    while i < 8 {
        let mut j = 0;
        while j < 8 {
            if i != j {
                out[k] = (i, j);
                k += 1;
            }
            j += 1;
        }
        i += 1;
    }
    out
};

/// Whether the plane `n . p = c` of a polygon (`blocker`) separates boxes
/// `a` and `b` (by more than `slack`) and every crossing of a segment
/// between their corners lies inside the polygon.
fn crossings_inside(
    blocker: &Blocker,
    n: DVec3,
    c: f64,
    a: (DVec3, DVec3),
    b: (DVec3, DVec3),
    slack: f64,
) -> bool {
    let range = |(lo, hi): (DVec3, DVec3)| {
        let (x, y) = (n * lo, n * hi);
        let (mn, mx) = (x.min(y), x.max(y));
        (mn.x + mn.y + mn.z, mx.x + mx.y + mx.z)
    };
    let ((alo, ahi), (blo, bhi)) = (range(a), range(b));
    let separated = (ahi < c - slack && blo > c + slack) || (bhi < c - slack && alo > c + slack);
    if !separated {
        return false;
    }
    let (ca, cb) = (corners(a.0, a.1), corners(b.0, b.1));
    let (sa, sb) = (ca.map(|p| n.dot(p) - c), cb.map(|q| n.dot(q) - c));
    let half_planes = &blocker.edges;
    let all_inside = |margin: f64| {
        CORNER_PAIRS.iter().all(|&(i, j)| {
            let (p, q, sp, sq) = (ca[i], cb[j], sa[i], sb[j]);
            let x = p + (q - p) * (sp / (sp - sq));
            half_planes.iter().all(|&(m, e)| m.dot(x) <= e - margin)
        })
    };
    // Most tries fail: a first pass without the margin (which is never
    // negative, so `e - margin <= e` and this pass is passed by every
    // crossing the real test passes) turns them away before the margin's
    // 64 square roots are paid for. Its pairs of like corners come first:
    // a crossing is a weighted mean of its two ends, so those tend to be
    // the farthest out, and a failing try ends sooner (San Francisco's
    // tries that fail took 5.8 pairs on average in the plain order).
    if !all_inside(0.0) {
        return false;
    }
    // The margin: the tracer's rounding moves a ray by up to the slack
    // across its line, and a bent polygon's triangles lie up to its
    // flatness off the plane; along the plane either moves the crossing by
    // that over the sine of the ray's angle to it (at its smallest over
    // the shaft at a corner pair: the share of a direction along the
    // normal is quasi-concave over the box of directions `B - A`).
    all_inside((slack + blocker.flatness) / min_sine(n, &ca, &cb))
}

/// Whether every segment from box `a` to box `b` passes through the
/// inside of convex solid `o` by `margin` (a point of it inside every
/// face plane by that much).
fn segments_through(
    o: &Occluder,
    balls: Option<Balls>,
    a: (DVec3, DVec3),
    b: (DVec3, DVec3),
    margin: f64,
) -> bool {
    // The interval of `t` inside every plane by a hair more than the
    // margin: its points, rounded, are inside by the margin (a 2^-20 share
    // of the margin, which is at least the tracer's f32 rounding of the
    // coordinates, is still thousands of times f64's rounding of a plane
    // distance).
    let inside = margin * (1.0 + 1.0 / 1_048_576.0);
    let (ca, cb) = (corners(a.0, a.1), corners(b.0, b.1));
    // The segments between like corners first: the outermost, so the
    // likeliest to miss.
    CORNER_PAIRS.iter().all(|&(i, j)| {
        let (p, q) = (ca[i], cb[j]);
        let d = q - p;
        if let Some(balls) = balls {
            // Outside the outer ball: the segment misses the solid.
            // Near enough the centre: its nearest point to it is
            // inside every plane by the margin.
            let r = balls.distance(p, d);
            if balls.outside(r) {
                return false;
            }
            if balls.inside(r, margin) {
                return true;
            }
        }
        clips_inside(&o.planes, p, d, inside)
    })
}

/// Whether the segment `p -> p + d` has a point inside every plane
/// `n . x <= e` of `planes` by `margin` (the segment clipped by each in
/// turn).
fn clips_inside(planes: &[(DVec3, f64)], p: DVec3, d: DVec3, margin: f64) -> bool {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for &(n, e) in planes {
        let (sp, sd) = (n.dot(p) - (e - margin), n.dot(d));
        if sd == 0.0 {
            if sp > 0.0 {
                return false;
            }
        } else if sd > 0.0 {
            t1 = t1.min(-sp / sd);
        } else {
            t0 = t0.max(-sp / sd);
        }
        // (No number, from a coordinate that is none: no proof.)
        if !matches!(t0.partial_cmp(&t1), Some(Ordering::Less | Ordering::Equal)) {
            return false;
        }
    }
    true
}

/// The smallest sine of the angle between the plane of normal `n` (a unit
/// vector) and a segment from a corner of `ca` to one of `cb`.
fn min_sine(n: DVec3, ca: &[DVec3; 8], cb: &[DVec3; 8]) -> f64 {
    let mut sine = f64::INFINITY;
    for &p in ca {
        for &q in cb {
            let d = q - p;
            sine = sine.min(n.dot(d).abs() / d.length());
        }
    }
    sine
}

/// [`min_sine`] for the plane across `axis` and boxes `a` and `b` that it
/// separates, in constant time. The directions `b - a` fill a box whose
/// corners are differences of the boxes' corners, and the sine
/// `|d[axis]| / |d|` is smallest at the one nearest the plane across the
/// axis and farthest from it along the other two: the same corner pair
/// the loop over all 64 finds, with the same arithmetic, so the same value.
fn axis_min_sine(axis: usize, a: (DVec3, DVec3), b: (DVec3, DVec3)) -> f64 {
    let mut d = DVec3::ZERO;
    for i in 0..3 {
        let (low, high) = (b.0[i] - a.1[i], b.1[i] - a.0[i]);
        d[i] = if i == axis {
            if low > 0.0 { low } else { high }
        } else if low.abs() >= high.abs() {
            low
        } else {
            high
        };
    }
    let mut n = DVec3::ZERO;
    n[axis] = 1.0;
    n.dot(d).abs() / d.length()
}

/// Whether the segment `p -> q` meets occluder `o` (a solid's inside, a
/// polygon's plane inside its corners' hull): a guide, not a proof.
fn meets(o: &Occluder, balls: Option<Balls>, p: DVec3, q: DVec3) -> bool {
    let d = q - p;
    if let Some(balls) = balls {
        let r = balls.distance(p, d);
        if balls.outside(r) {
            return false;
        }
        if balls.inside(r, 0.0) {
            return true;
        }
    }
    if o.solid {
        return clips_inside(&o.planes, p, d, 0.0);
    }
    if o.points.len() < 3 {
        return false;
    }
    let (a, b, c) = (o.points[0], o.points[1], o.points[2]);
    let n = (b - a).cross(c - a);
    let (sp, sq) = (n.dot(p - a), n.dot(q - a));
    if sp * sq > 0.0 || sp == sq {
        return false;
    }
    let x = p + d * (sp / (sp - sq));
    // Inside the hull: the same side of every edge.
    let k = o.points.len();
    let (mut left, mut right) = (true, true);
    for i in 0..k {
        let (u, v) = (o.points[i], o.points[(i + 1) % k]);
        let side = (v - u).cross(x - u).dot(n);
        left &= side >= 0.0;
        right &= side <= 0.0;
        if !left && !right {
            return false;
        }
    }
    true
}

/// The rectangle on `cut`'s plane (its `(u, v)`) holding every crossing of
/// a segment from box `a.0` to box `b` (that passes through box `a.1` first,
/// when given), and how far the tracer's rounding moves a crossing along
/// the plane (the slack over the sine of the segment's angle to it);
/// `None` when the plane does not separate the boxes. A rectangle with
/// `lo > hi` on some axis holds no crossing: no segment passes through
/// both `a.0` and `a.1`.
fn crossings(
    cut: &Cut,
    (a, from): ((DVec3, DVec3), Option<(DVec3, DVec3)>),
    b: (DVec3, DVec3),
    slack: f64,
) -> Option<(DVec2, DVec2, f64)> {
    let k = cut.axis;
    let c = cut.at;
    let separated = |x: (DVec3, DVec3), y: (DVec3, DVec3)| separates(cut, x, y, slack);
    // Every segment crosses the plane once, inside the rectangle of each
    // pair of boxes it passes through in turn on the plane's two sides
    // (`a` and `b`, `a.1` and `b`, `a.1` and `a`); its direction lies in
    // each pair's cone, so the larger of their smallest sines bounds its
    // angle.
    //
    // And when `a` is a portal lying wholly between `a.1` and the plane
    // (along its axis), a segment's line runs from a point `p` of `a.1`
    // through one `h` of `a` on to the plane: its crossing `p + (h - p) t`
    // (`t >= 1`) is linear in `h`'s and `p`'s coordinates across the axis
    // and monotone in each along it, so the corners' crossings bound
    // these too.
    let mut rect: Option<(DVec2, DVec2)> = None;
    let mut sine: f64 = 0.0;
    let beyond = |from: (DVec3, DVec3)| {
        (from.1[k] < a.0[k] && a.1[k] < c) || (from.0[k] > a.1[k] && a.0[k] > c)
    };
    let mut pairs = [(a, b); 4];
    let mut count = 0;
    if separated(a, b) {
        count += 1;
        if let Some(f) = from.filter(|&f| beyond(f)) {
            pairs[count] = (f, a);
            count += 1;
        }
    }
    if let Some(f) = from {
        if separated(f, b) {
            pairs[count] = (f, b);
            count += 1;
        }
        if separated(f, a) {
            pairs[count] = (f, a);
            count += 1;
        }
    }
    for &(p0, q0) in &pairs[..count] {
        let (lo, hi) = pair_rect(k, c, p0, q0);
        rect = Some(match rect {
            None => (lo, hi),
            Some((l, h)) => (l.max(lo), h.min(hi)),
        });
        sine = sine.max(axis_min_sine(k, p0, q0));
    }
    let (lo, hi) = rect?;
    Some((lo, hi, slack / sine))
}

/// The rectangle, in the plane `p[k] = c`'s `(u, v)` (the other two axes
/// in turn), of the crossings of the segments between the corners of
/// boxes `a` and `b` that it separates. A crossing is `p + (q - p) t` for
/// corners `p` and `q`, with `t` from their coordinates along `k` alone,
/// so its coordinate along `u` depends on four of their six: the 16 ways
/// to choose those give the bounds over all 64 pairs. For the two along
/// `u`, the crossing is monotone in `t` (rounding is monotone), so its
/// least and greatest are at the least and the greatest of the four `t`:
/// the same arithmetic, so the same bounds to the bit.
fn pair_rect(k: usize, c: f64, a: (DVec3, DVec3), b: (DVec3, DVec3)) -> (DVec2, DVec2) {
    let ts = [
        (a.0[k], b.0[k]),
        (a.0[k], b.1[k]),
        (a.1[k], b.0[k]),
        (a.1[k], b.1[k]),
    ]
    .map(|(pk, qk)| (c - pk) / (qk - pk));
    // `pw + (qw - pw) t` is monotone in `t` (rounding is), so over the
    // four `t` it is least and greatest at the least and the greatest;
    // with `qw == pw` it is `pw` whatever `t` (even an infinite one,
    // which only an overflow of `c - pk` could make: then `0 t` would be
    // no number, and the rectangle too small).
    let (t0, t1) = (
        ts[0].min(ts[1]).min(ts[2].min(ts[3])),
        ts[0].max(ts[1]).max(ts[2].max(ts[3])),
    );
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for (i, w) in [(k + 1) % 3, (k + 2) % 3].into_iter().enumerate() {
        for pw in [a.0[w], a.1[w]] {
            for qw in [b.0[w], b.1[w]] {
                let d = qw - pw;
                let (x0, x1) = if d == 0.0 {
                    (pw, pw)
                } else if d > 0.0 {
                    (pw + d * t0, pw + d * t1)
                } else {
                    (pw + d * t1, pw + d * t0)
                };
                lo[i] = lo[i].min(x0);
                hi[i] = hi[i].max(x1);
            }
        }
    }
    (lo, hi)
}

/// Whether the segment `p -> q` crosses `cut`'s plane outside the cut's
/// bounding rectangle by more than `slack` (far beyond the rounding of
/// the arithmetic); false when it does not cross it.
fn crosses_apart(cut: &Cut, (p, q): (DVec3, DVec3), slack: f64) -> bool {
    let (k, c) = (cut.axis, cut.at);
    if (p[k] - c) * (q[k] - c) >= 0.0 {
        return false;
    }
    let x = p + (q - p) * ((c - p[k]) / (q[k] - p[k]));
    let x = DVec2::new(x[(k + 1) % 3], x[(k + 2) % 3]);
    x.cmplt(cut.lo - slack).any() || x.cmpgt(cut.hi + slack).any()
}

/// Whether `cut`'s plane has box `x` strictly on one side and box `y` on
/// the other (by more than `slack`).
fn separates(cut: &Cut, x: (DVec3, DVec3), y: (DVec3, DVec3), slack: f64) -> bool {
    let (k, c) = (cut.axis, cut.at);
    (x.1[k] < c - slack && y.0[k] > c + slack) || (y.1[k] < c - slack && x.0[k] > c + slack)
}

/// Whether `cut` blocks every segment whose crossing (before rounding)
/// lies in `[lo, hi]`, the rounding moving it by up to `grow`. A rectangle
/// empty by more than the rounding holds no crossing (one empty by less
/// could be an artefact of the corners' arithmetic, and is not trusted).
fn cut_blocks(cut: &Cut, (lo, hi, grow): (DVec2, DVec2, f64)) -> bool {
    let (lo, hi) = (lo - grow, hi + grow);
    lo.cmpgt(hi).any() || rect_inside(cut, lo, hi) == Some(true)
}

/// Whether the rectangle `[lo, hi]` lies inside `cut`'s loops (`Some(true)`),
/// outside them (`Some(false)`), or meets a loop segment (`None`).
fn rect_inside(cut: &Cut, lo: DVec2, hi: DVec2) -> Option<bool> {
    if lo.cmplt(cut.lo).any() || hi.cmpgt(cut.hi).any() {
        let apart = hi.cmplt(cut.lo).any() || lo.cmpgt(cut.hi).any();
        return apart.then_some(false);
    }
    // No loop segment meets the rectangle.
    for &[p, q] in &cut.segments {
        if p.x.max(q.x) < lo.x || p.x.min(q.x) > hi.x || p.y.max(q.y) < lo.y || p.y.min(q.y) > hi.y
        {
            continue;
        }
        if clip_to_rect(p, q, lo, hi).is_some() {
            return None;
        }
    }
    // Wholly inside or wholly outside: the centre decides (even-odd).
    Some(inside_loops(cut, 0.5 * (lo + hi)))
}

/// Whether point `m` of `cut`'s plane lies inside its loops (even-odd).
fn inside_loops(cut: &Cut, m: DVec2) -> bool {
    let mut inside = false;
    for &[p, q] in &cut.segments {
        if (p.y > m.y) != (q.y > m.y) {
            let x = p.x + (m.y - p.y) * (q.x - p.x) / (q.y - p.y);
            if x > m.x {
                inside = !inside;
            }
        }
    }
    inside
}

/// Where in the crossings' rectangle `[lo, hi]` a segment may pass `cut`
/// unblocked, the rounding moving its crossing by up to `grow`: within
/// `grow` of a loop segment (their pieces in the rectangle grown by
/// `grow`) or outside the loops (a union of polygons whose corners are
/// such pieces' ends or the rectangle's corners outside the loops), so the
/// bounding rectangle of those pieces and corners, grown by `grow` and
/// clipped to the rectangle. `None` when that is all of it, or nothing
/// (the whole rectangle inside, which the callers' test finds first).
fn hole(cut: &Cut, lo: DVec2, hi: DVec2, grow: f64) -> Option<(DVec2, DVec2)> {
    if lo.cmpgt(hi).any() {
        return None;
    }
    let (glo, ghi) = (lo - grow, hi + grow);
    // Apart from the loops' bounds: all of it outside them (what the rest
    // would find, by walking every loop segment).
    if ghi.cmplt(cut.lo).any() || glo.cmpgt(cut.hi).any() {
        return None;
    }
    let (mut hlo, mut hhi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for &[p, q] in &cut.segments {
        if p.x.max(q.x) < glo.x
            || p.x.min(q.x) > ghi.x
            || p.y.max(q.y) < glo.y
            || p.y.min(q.y) > ghi.y
        {
            continue;
        }
        if let Some((s, e)) = clip_to_rect(p, q, glo, ghi) {
            hlo = hlo.min(s).min(e);
            hhi = hhi.max(s).max(e);
        }
    }
    for corner in [lo, DVec2::new(hi.x, lo.y), DVec2::new(lo.x, hi.y), hi] {
        if !inside_loops(cut, corner) {
            hlo = hlo.min(corner);
            hhi = hhi.max(corner);
        }
    }
    if hlo.cmpgt(hhi).any() {
        return None;
    }
    let (hlo, hhi) = ((hlo - grow).max(lo), (hhi + grow).min(hi));
    if hlo.cmpgt(hhi).any() {
        return None;
    }
    (hlo != lo || hhi != hi).then_some((hlo, hhi))
}

/// The part of the segment `p -> q` inside the closed rectangle
/// `[lo, hi]`, if any.
pub(super) fn clip_to_rect(p: DVec2, q: DVec2, lo: DVec2, hi: DVec2) -> Option<(DVec2, DVec2)> {
    let d = q - p;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for axis in 0..2 {
        if d[axis] == 0.0 {
            if p[axis] < lo[axis] || p[axis] > hi[axis] {
                return None;
            }
            continue;
        }
        let (s, e) = (
            (lo[axis] - p[axis]) / d[axis],
            (hi[axis] - p[axis]) / d[axis],
        );
        t0 = t0.max(s.min(e));
        t1 = t1.min(s.max(e));
        if t0 > t1 {
            return None;
        }
    }
    Some((p + d * t0, p + d * t1))
}

impl Cut {
    /// The cut at `p[axis] = at` whose loops are `segments`, with their
    /// bounding rectangle.
    fn new(axis: usize, at: f64, segments: Vec<[DVec2; 2]>) -> Self {
        let (lo, hi) = segments
            .iter()
            .flatten()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        Self {
            axis,
            at,
            segments,
            lo,
            hi,
        }
    }
}

impl CutSolid {
    /// Whether it may be used from the search's cell (a shell only up to
    /// the slack its margins were sized for).
    fn usable(&self, search: &Search) -> bool {
        self.shell_slack.is_none_or(|s| search.slack <= s)
    }
}

/// A convex shell's cuts: along each axis, at the middle and near both
/// sides of its box, its shrunk polytope's cross-section (one loop of
/// segments around a convex polygon; none where the plane misses it).
fn shell_cuts(shell: &Occluder) -> Vec<Cut> {
    let mut out = Vec::new();
    let (min, max) = (shell.min, shell.max);
    let centre = 0.5 * (min + max);
    let size = (max - min).length();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for f in DEPTHS {
            let at = min[axis] + f * (max[axis] - min[axis]);
            let mut n = DVec3::ZERO;
            n[axis] = 1.0;
            let section = super::oracle_occluders::section(&shell.planes, (n, at), centre, size);
            if section.len() < 3 {
                continue;
            }
            let points: Vec<DVec2> = section.iter().map(|p| DVec2::new(p[u], p[v])).collect();
            let segments: Vec<[DVec2; 2]> = (0..points.len())
                .map(|i| [points[i], points[(i + 1) % points.len()]])
                .collect();
            out.push(Cut::new(axis, at, segments));
        }
    }
    out
}

/// Whether a terrain blocks every segment from the part `a` of the cell
/// to the box `b`: on one of seven upright planes between them (along x
/// or y, where they are apart), every crossing (within the rectangle of
/// the crossings of the boxes' 64 corner pairs, exact for boxes) lies
/// over the terrain's rectangle and below its surface by the margin, and
/// the cell lies above the surface ([`Terrain::usable`]): such a segment
/// passes from above the surface to below it over the rectangle before
/// the plane, so it hits the terrain there (`oracle_terrain.rs`). From a
/// portal, the segments still start in the cell part (`a` here).
fn terrain_blocks(search: &Search, a: (DVec3, DVec3), b: (DVec3, DVec3)) -> bool {
    let slack = search.slack;
    for axis in 0..2 {
        let (lo, hi) = if a.1[axis] + slack < b.0[axis] - slack {
            (a.1[axis], b.0[axis])
        } else if b.1[axis] + slack < a.0[axis] - slack {
            (b.1[axis], a.0[axis])
        } else {
            continue;
        };
        // `pair_rect`'s coordinates are the other two axes in turn: the
        // one across, and z.
        let (u, z) = if axis == 0 { (0, 1) } else { (1, 0) };
        for f in 1..8 {
            let c = lo + (hi - lo) * f as f64 / 8.0;
            let (rlo, rhi) = pair_rect(axis, c, a, b);
            if search
                .terrains
                .iter()
                .any(|t| t.upright_below(axis, c, (rlo[u], rhi[u]), rhi[z], slack))
            {
                return true;
            }
        }
    }
    false
}

/// A sliceable solid's cuts: along each axis, at the middle and near both
/// sides (those that close).
fn solid_cuts(solid: &SlicedSolid) -> Vec<Cut> {
    let mut out = Vec::new();
    for axis in 0..3 {
        let frame = Frame {
            axis,
            positive: true,
        };
        for f in DEPTHS {
            let at = solid.min[axis] + f * (solid.max[axis] - solid.min[axis]);
            let Some(segments) = slice_segments(solid, frame, at) else {
                continue;
            };
            out.push(Cut::new(axis, at, segments));
        }
    }
    out
}

/// The index of the longest side.
fn longest(size: DVec3) -> usize {
    if size.x >= size.y && size.x >= size.z {
        0
    } else if size.y >= size.z {
        1
    } else {
        2
    }
}

/// The f32 box holding `[min, max]`, rounded outwards.
fn outward(min: DVec3, max: DVec3) -> Aabb {
    Aabb::new(
        min.as_vec3().map(f32::next_down),
        max.as_vec3().map(f32::next_up),
    )
}

/// An occluder's blocking planes (and a polygon's edges).
fn blocker(o: &Occluder) -> Blocker {
    if o.solid {
        // A solid is tested segment by segment against its face planes
        // ([`segments_through`]), its balls first.
        return Blocker {
            balls: balls(o),
            ..Blocker::default()
        };
    }
    let p = &o.points;
    if p.len() < 3 {
        return Blocker::default();
    }
    // Newell's normal: the polygon's points run counter-clockwise around it.
    let mut n = DVec3::ZERO;
    for i in 0..p.len() {
        let (u, v) = (p[i], p[(i + 1) % p.len()]);
        n += DVec3::new(
            (u.y - v.y) * (u.z + v.z),
            (u.z - v.z) * (u.x + v.x),
            (u.x - v.x) * (u.y + v.y),
        );
    }
    let Some(n) = n.try_normalize() else {
        return Blocker::default();
    };
    let c = p.iter().map(|&x| n.dot(x)).sum::<f64>() / p.len() as f64;
    let flatness = p.iter().map(|&x| (n.dot(x) - c).abs()).fold(0.0, f64::max) + o.tolerance();
    let mut edges = Vec::with_capacity(p.len());
    for i in 0..p.len() {
        let (u, v) = (p[i], p[(i + 1) % p.len()]);
        let Some(m) = (v - u).cross(n).try_normalize() else {
            continue;
        };
        edges.push((m, m.dot(u)));
    }
    Blocker {
        planes: vec![(n, c)],
        edges,
        flatness,
        balls: None,
    }
}

/// A convex solid's ellipsoids ([`Balls`]) about the mean of its
/// corners; `None` for a solid without planes or of no width along an
/// axis.
fn balls(o: &Occluder) -> Option<Balls> {
    if o.points.is_empty() || o.planes.is_empty() {
        return None;
    }
    let centre = o.points.iter().fold(DVec3::ZERO, |a, &p| a + p) / o.points.len() as f64;
    let half = 0.5 * (o.max - o.min);
    if !half.is_finite() || half.cmple(DVec3::ZERO).any() {
        return None;
    }
    let inv = half.recip();
    let outer = o
        .points
        .iter()
        .map(|&p| ((p - centre) * inv).length())
        .fold(0.0, f64::max);
    // A plane `n . x <= e` is, in the balls' coordinates `y`,
    // `(n / inv) . y <= e - n . centre`: the ball of radius `k` lies inside
    // it by `(e - n . centre) - k |n / inv|`. Each plane's gap is taken
    // less a bound on its rounding (of the coordinates' size, not the
    // gap's: a solid far from the origin loses digits in `n . centre`
    // even where the product is small), and `hmin` a hair smaller, so
    // that the accept errs on the side of the planes.
    let size = centre.abs().element_sum();
    let (mut k, mut hmin) = (f64::INFINITY, f64::INFINITY);
    for &(n, e) in &o.planes {
        let h = (n * half).length();
        let gap = (e - n.dot(centre)) - ROUNDING * (e.abs() + size);
        k = k.min(gap / h);
        hmin = hmin.min(h);
    }
    (outer.is_finite() && k.is_finite() && hmin > 0.0).then_some(Balls {
        centre,
        inv,
        k,
        hmin: hmin * (1.0 - ROUNDING),
        outer,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    const CELL: (DVec3, DVec3) = (DVec3::ZERO, DVec3::new(1.0, 1.0, 1.0));

    /// An L of two walls around the cell's corner at (2, 3): one along y
    /// at x in [2, 2.2], one along x at y in [3, 3.2], both tall; `gap`
    /// opens the corner between them.
    fn corner(object: u32, gap: f64) -> Vec<Occluder> {
        vec![
            Occluder::test_box(
                object,
                DVec3::new(2.0, -10.0, -10.0),
                DVec3::new(2.2, 3.0 - gap, 10.0),
            ),
            Occluder::test_box(
                object,
                DVec3::new(-10.0, 3.0, -10.0),
                DVec3::new(2.2, 3.2, 10.0),
            ),
        ]
    }

    fn search<'a>(occluders: &'a [Occluder], skip: &'a (dyn Fn(u32) -> bool + Sync)) -> Search<'a> {
        Search {
            occluders,
            skip,
            slack: 1e-5,
            budget: 1_000_000,
            depth: 40,
            terrains: &[],
        }
    }

    /// Whether the segment `p -> q` meets the inside of box `o`.
    fn meets(o: &Occluder, p: DVec3, q: DVec3) -> bool {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for axis in 0..3 {
            let d = q[axis] - p[axis];
            if d == 0.0 {
                if p[axis] <= o.min[axis] || p[axis] >= o.max[axis] {
                    return false;
                }
                continue;
            }
            let (a, b) = ((o.min[axis] - p[axis]) / d, (o.max[axis] - p[axis]) / d);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        t0 < t1
    }

    /// The share of 20,000 random segments from the cell to the box
    /// `[qmin, qmax]` that no occluder blocks.
    fn open_share(occluders: &[Occluder], qmin: DVec3, qmax: DVec3) -> f64 {
        let mut rng = Pcg64::seed_from_u64(7);
        let mut point = |lo: DVec3, hi: DVec3| {
            lo + (hi - lo) * DVec3::new(rng.random(), rng.random(), rng.random())
        };
        let open = (0..20_000)
            .filter(|_| {
                let (p, q) = (point(CELL.0, CELL.1), point(qmin, qmax));
                !occluders.iter().any(|o| meets(o, p, q))
            })
            .count();
        open as f64 / 20_000.0
    }

    /// A shell's cuts are its shrunk polytope's cross-sections: convex,
    /// closed, inside every one of its planes, and in the planes named.
    #[test]
    fn a_shells_cuts_are_its_cross_sections() {
        use crate::scene::procedural::{SceneKind, generate};
        let grove = generate(SceneKind::Grove, 1, 1);
        let found = super::super::oracle_occluders::extract(&grove);
        let shell = found
            .occluders
            .iter()
            .find(|o| o.shell_slack.is_some())
            .expect("a shell");
        let cuts = shell_cuts(shell);
        assert_eq!(cuts.len(), 9);
        for cut in &cuts {
            let (k, u, v) = (cut.axis, (cut.axis + 1) % 3, (cut.axis + 2) % 3);
            assert!(cut.segments.len() >= 3);
            for (i, &[p, q]) in cut.segments.iter().enumerate() {
                // Closed: each segment ends where the next starts.
                assert_eq!(q, cut.segments[(i + 1) % cut.segments.len()][0]);
                let mut x = DVec3::ZERO;
                (x[k], x[u], x[v]) = (cut.at, p.x, p.y);
                assert!(shell.planes.iter().all(|&(n, d)| n.dot(x) <= d + 1e-9));
            }
            // The middle of the section is inside the loops.
            assert!(inside_loops(cut, 0.5 * (cut.lo + cut.hi)));
        }
    }

    #[test]
    fn the_sine_in_constant_time_is_the_loops_to_the_bit() {
        let mut rng = Pcg64::seed_from_u64(5);
        let boxes = |rng: &mut Pcg64| {
            let lo = DVec3::new(
                rng.random_range(-50.0..50.0),
                rng.random_range(-50.0..50.0),
                rng.random_range(-50.0..50.0),
            );
            let size = DVec3::new(
                rng.random_range(0.0..8.0),
                rng.random_range(0.0..8.0),
                rng.random_range(0.0..8.0),
            );
            (lo, lo + size)
        };
        let mut tried = 0;
        while tried < 20_000 {
            let (a, b) = (boxes(&mut rng), boxes(&mut rng));
            for axis in 0..3 {
                if a.1[axis] >= b.0[axis] && b.1[axis] >= a.0[axis] {
                    continue;
                }
                let mut n = DVec3::ZERO;
                n[axis] = 1.0;
                let looped = min_sine(n, &corners(a.0, a.1), &corners(b.0, b.1));
                assert_eq!(axis_min_sine(axis, a, b).to_bits(), looped.to_bits());
                tried += 1;
            }
        }
    }

    #[test]
    fn the_crossings_rectangle_from_16_pairs_is_the_64s_to_the_bit() {
        let mut rng = Pcg64::seed_from_u64(6);
        let mut tried = 0;
        while tried < 20_000 {
            let mut corner = || DVec3::from_array([0; 3].map(|_| rng.random_range(-30.0..30.0)));
            let (a, b) = ((corner(), corner()), (corner(), corner()));
            let (a, b) = ((a.0.min(a.1), a.0.max(a.1)), (b.0.min(b.1), b.0.max(b.1)));
            let k = tried % 3;
            if a.1[k] >= b.0[k] && b.1[k] >= a.0[k] {
                continue;
            }
            let c = if a.1[k] < b.0[k] {
                0.5 * (a.1[k] + b.0[k])
            } else {
                0.5 * (b.1[k] + a.0[k])
            };
            let (u, v) = ((k + 1) % 3, (k + 2) % 3);
            let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
            for p in corners(a.0, a.1) {
                for q in corners(b.0, b.1) {
                    let x = p + (q - p) * ((c - p[k]) / (q[k] - p[k]));
                    lo = lo.min(DVec2::new(x[u], x[v]));
                    hi = hi.max(DVec2::new(x[u], x[v]));
                }
            }
            let (l, h) = pair_rect(k, c, a, b);
            assert_eq!(
                [l.x, l.y, h.x, h.y].map(f64::to_bits),
                [lo.x, lo.y, hi.x, hi.y].map(f64::to_bits)
            );
            tried += 1;
        }
    }

    #[test]
    fn two_walls_at_right_angles_hide_what_neither_hides_alone() {
        let walls = corner(1, 0.0);
        let (qmin, qmax) = (DVec3::new(3.0, 4.0, 0.0), DVec3::new(4.0, 5.0, 1.0));
        // Rays: every segment is blocked, some by one wall, some by the
        // other.
        assert_eq!(open_share(&walls, qmin, qmax), 0.0);
        for w in 0..2 {
            assert!(open_share(&walls[w..=w], qmin, qmax) > 0.01);
        }
        let no = |_: u32| false;
        let shafts = Shafts::new(&walls, &[]);
        assert!(shafts.hidden(&search(&walls, &no), 0, &[], CELL, qmin, qmax));
        // Neither wall alone.
        for w in 0..2 {
            let one = &walls[w..=w];
            let shafts = Shafts::new(one, &[]);
            assert!(!shafts.hidden(&search(one, &no), 0, &[], CELL, qmin, qmax));
        }
        // The walls' own object is not hidden by them, and skipped
        // occluders prove nothing.
        assert!(!shafts.hidden(&search(&walls, &no), 1, &[], CELL, qmin, qmax));
        let all = |_: u32| true;
        assert!(!shafts.hidden(&search(&walls, &all), 0, &[], CELL, qmin, qmax));
    }

    #[test]
    fn a_gap_at_the_corner_is_seen_through() {
        let walls = corner(1, 0.5);
        let (qmin, qmax) = (DVec3::new(4.0, 4.0, 0.0), DVec3::new(5.0, 5.0, 1.0));
        assert!(open_share(&walls, qmin, qmax) > 0.0);
        let no = |_: u32| false;
        let shafts = Shafts::new(&walls, &[]);
        assert!(!shafts.hidden(&search(&walls, &no), 0, &[], CELL, qmin, qmax));
    }

    #[test]
    fn abutting_boxes_hide_across_their_joint() {
        // One wall in two boxes meeting at y = 0.5, in front of the cell;
        // an object behind it, seen at a slant across the joint (a segment
        // crossing the joint in the wall's middle crosses one box or the
        // other nearer a face; one lying in the joint's plane, which a
        // view straight through would hold, no single box blocks).
        let walls = vec![
            Occluder::test_box(1, DVec3::new(2.0, -10.0, -10.0), DVec3::new(2.2, 0.5, 10.0)),
            Occluder::test_box(2, DVec3::new(2.0, 0.5, -10.0), DVec3::new(2.2, 10.0, 10.0)),
        ];
        let (qmin, qmax) = (DVec3::new(4.0, 3.0, 0.2), DVec3::new(4.5, 4.0, 0.8));
        assert_eq!(open_share(&walls, qmin, qmax), 0.0);
        let no = |_: u32| false;
        let shafts = Shafts::new(&walls, &[]);
        assert!(shafts.hidden(&search(&walls, &no), 0, &[], CELL, qmin, qmax));
    }

    #[test]
    fn a_solid_around_both_ends_proves_nothing() {
        // The cell and the object both inside one solid: no surface
        // between them.
        let around = vec![Occluder::test_box(
            1,
            DVec3::splat(-1.0),
            DVec3::splat(10.0),
        )];
        let (qmin, qmax) = (DVec3::new(4.0, 0.0, 0.0), DVec3::new(5.0, 1.0, 1.0));
        let no = |_: u32| false;
        let shafts = Shafts::new(&around, &[]);
        assert!(!shafts.hidden(&search(&around, &no), 0, &[], CELL, qmin, qmax));
        // The cell inside, the object beyond it: the segments leave it.
        let (qmin, qmax) = (DVec3::new(12.0, 0.0, 0.0), DVec3::new(13.0, 1.0, 1.0));
        assert!(shafts.hidden(&search(&around, &no), 0, &[], CELL, qmin, qmax));
    }

    /// A convex solid given by its corners and outward face planes.
    fn convex(object: u32, points: Vec<DVec3>, planes: Vec<(DVec3, f64)>) -> Occluder {
        let mut o = Occluder::test_box(object, DVec3::ZERO, DVec3::ONE);
        (o.min, o.max) = points
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        o.points = points;
        o.planes = planes;
        o
    }

    /// A prism along z (z in [-5, 5]) over a rhombus long in x: (2, 0.5),
    /// (5, -0.2), (8, 0.5), (5, 1.2).
    fn rhombus_prism() -> Occluder {
        let footprint = [
            DVec2::new(2.0, 0.5),
            DVec2::new(5.0, -0.2),
            DVec2::new(8.0, 0.5),
            DVec2::new(5.0, 1.2),
        ];
        let mut points = Vec::new();
        let mut planes = Vec::new();
        for i in 0..4 {
            let (u, v) = (footprint[i], footprint[(i + 1) % 4]);
            points.push(u.extend(-5.0));
            points.push(u.extend(5.0));
            // Counter-clockwise around the footprint: outward is to the
            // right of the edge.
            let n = DVec3::new(v.y - u.y, u.x - v.x, 0.0).normalize();
            planes.push((n, n.dot(u.extend(0.0))));
        }
        planes.push((DVec3::Z, 5.0));
        planes.push((-DVec3::Z, 5.0));
        convex(1, points, planes)
    }

    /// Segments from the unit cell to a box beyond the rhombus prism pass
    /// through it at different depths (those along y = 0 near x = 5 only,
    /// those along a diagonal anywhere between): no one plane holds all
    /// their crossings inside it, but each passes through it, so one shaft
    /// suffices. Checked with segments between random points.
    #[test]
    fn a_convex_solid_blocks_segments_that_cross_it_at_different_depths() {
        let prism = vec![rhombus_prism()];
        let no = |_: u32| false;
        let shafts = Shafts::new(&prism, &[]);
        let one = Search {
            budget: 1,
            depth: 0,
            ..search(&prism, &no)
        };
        let (qmin, qmax) = (DVec3::new(9.5, 0.0, 0.0), DVec3::new(10.0, 1.0, 1.0));
        assert!(shafts.hidden(&one, 0, &[], CELL, qmin, qmax));
        // What the shaft claims, by segments: each meets the rhombus.
        let mut rng = Pcg64::seed_from_u64(11);
        let inside = |x: DVec3| prism[0].planes.iter().all(|&(n, e)| n.dot(x) <= e);
        for _ in 0..2_000 {
            let p = DVec3::new(rng.random(), rng.random(), rng.random());
            let q = qmin + (qmax - qmin) * DVec3::new(rng.random(), rng.random(), rng.random());
            assert!(
                (0..=1_000).any(|i| inside(p + (q - p) * (i as f64 / 1_000.0))),
                "{p} -> {q} misses the prism"
            );
        }
        // Beside it, or reaching in front of it: not hidden.
        for (qmin, qmax) in [
            (DVec3::new(9.5, 2.0, 0.0), DVec3::new(10.0, 3.0, 1.0)),
            (DVec3::new(1.5, 0.0, 0.0), DVec3::new(10.0, 1.0, 1.0)),
        ] {
            assert!(!shafts.hidden(&search(&prism, &no), 0, &[], CELL, qmin, qmax));
        }
    }

    /// The segment test's ellipsoids only shortcut its planes: random
    /// convex solids (boxes turned at random, with their corners, near
    /// the origin and 10^5 from it) and boxes on either side give the
    /// same answers with and without them,
    /// and whenever the answer is yes, segments between random points of
    /// the boxes pass inside every plane by the margin.
    #[test]
    fn the_ellipsoids_answer_as_the_planes_do() {
        let mut rng = Pcg64::seed_from_u64(12);
        let (mut yes, mut quick) = (0, 0);
        for trial in 0..3_000 {
            // Half of them far from the origin, where `n . centre` loses
            // digits.
            let far = if trial % 2 == 0 {
                DVec3::ZERO
            } else {
                DVec3::new(1e5, -5e4, 2e4)
            };
            // A box of half-sizes `h` turned by a random rotation about
            // `c`.
            let c = far
                + DVec3::new(5.0, 0.0, 0.0)
                + DVec3::new(rng.random(), rng.random(), rng.random()) * 2.0
                - DVec3::ONE;
            let h = DVec3::new(rng.random(), rng.random(), rng.random()) * 2.0 + DVec3::splat(0.3);
            let r = glam::DQuat::from_euler(
                glam::EulerRot::XYZ,
                rng.random::<f64>() * 6.3,
                rng.random::<f64>() * 6.3,
                rng.random::<f64>() * 6.3,
            );
            let axes = [r * DVec3::X, r * DVec3::Y, r * DVec3::Z];
            let mut planes = Vec::new();
            for (i, &n) in axes.iter().enumerate() {
                planes.push((n, n.dot(c) + h[i]));
                planes.push((-n, -n.dot(c) + h[i]));
            }
            let points: Vec<DVec3> = (0..8)
                .map(|k| {
                    (0..3).fold(c, |x, i| {
                        x + axes[i] * h[i] * if k >> i & 1 == 1 { 1.0 } else { -1.0 }
                    })
                })
                .collect();
            let o = convex(1, points, planes);
            let part = |rng: &mut Pcg64, x: f64| {
                let lo = far
                    + DVec3::new(x, -2.0, -2.0)
                    + DVec3::new(rng.random(), rng.random(), rng.random()) * 3.0;
                (
                    lo,
                    lo + DVec3::new(rng.random(), rng.random(), rng.random()) * 0.8,
                )
            };
            let (a, b) = (part(&mut rng, -1.0), part(&mut rng, 9.0));
            let margin = 0.05;
            let with = segments_through(&o, balls(&o), a, b, margin);
            let without = segments_through(&o, None, a, b, margin);
            assert_eq!(with, without, "{a:?} {b:?} {o:?}");
            let ball = balls(&o).expect("a box has its ellipsoids");
            if with {
                yes += 1;
                let (ca, cb) = (corners(a.0, a.1), corners(b.0, b.1));
                if ca.iter().all(|&p| {
                    cb.iter()
                        .all(|&q| ball.inside(ball.distance(p, q - p), margin))
                }) {
                    quick += 1;
                }
                for _ in 0..200 {
                    let p =
                        a.0 + (a.1 - a.0) * DVec3::new(rng.random(), rng.random(), rng.random());
                    let q =
                        b.0 + (b.1 - b.0) * DVec3::new(rng.random(), rng.random(), rng.random());
                    let deepest = (0..=2_000)
                        .map(|i| {
                            let x = p + (q - p) * (i as f64 / 2_000.0);
                            o.planes
                                .iter()
                                .map(|&(n, e)| e - n.dot(x))
                                .fold(f64::INFINITY, f64::min)
                        })
                        .fold(f64::NEG_INFINITY, f64::max);
                    // (The sampling along the segment may miss the best
                    // point by a step's share of a plane distance.)
                    assert!(deepest >= margin - 0.01, "{p} -> {q}: {deepest}");
                }
            }
        }
        // Both kinds of answers, and the ellipsoids alone giving some.
        assert!(yes > 30 && yes < 2_970, "{yes} of 3,000 blocked");
        assert!(quick > 0, "no answer from the ellipsoids alone");
    }

    #[test]
    fn a_polygon_blocks_only_what_is_wholly_behind_it() {
        // A square at x = 2, y and z in [-3, 4], as a polygon occluder.
        let mut o = Occluder::test_box(1, DVec3::new(2.0, -3.0, -3.0), DVec3::new(2.0, 4.0, 4.0));
        o.solid = false;
        o.planes.clear();
        o.points = vec![
            DVec3::new(2.0, -3.0, -3.0),
            DVec3::new(2.0, 4.0, -3.0),
            DVec3::new(2.0, 4.0, 4.0),
            DVec3::new(2.0, -3.0, 4.0),
        ];
        let polygon = vec![o];
        let no = |_: u32| false;
        let shafts = Shafts::new(&polygon, &[]);
        let s = search(&polygon, &no);
        assert!(shafts.hidden(
            &s,
            0,
            &[],
            CELL,
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::splat(1.0) + DVec3::X * 2.5
        ));
        // Reaching through the plane, or past the square's edge.
        assert!(!shafts.hidden(
            &s,
            0,
            &[],
            CELL,
            DVec3::new(1.5, 0.0, 0.0),
            DVec3::new(3.0, 1.0, 1.0)
        ));
        assert!(!shafts.hidden(
            &s,
            0,
            &[],
            CELL,
            DVec3::new(3.0, 6.0, 0.0),
            DVec3::new(4.0, 7.0, 1.0)
        ));
    }

    /// A floorless L-shaped prism (one mesh: a sliceable solid, not
    /// convex; footprint (0,0) (3,0) (3,1) (1,1) (1,3) (0,3), height 2)
    /// and a small box beyond its outer corner.
    fn l_prism_scene() -> crate::scene::Scene {
        use crate::scene::procedural::shapes::push_box;
        use crate::scene::{SceneBuilder, SceneFormat};
        use glam::Vec3;
        let f = [
            (0.0, 0.0),
            (3.0, 0.0),
            (3.0, 1.0),
            (1.0, 1.0),
            (1.0, 3.0),
            (0.0, 3.0),
        ];
        let p = |k: usize, z: f32| Vec3::new(f[k % 6].0, f[k % 6].1, z);
        let r = |x: f32, y: f32| Vec3::new(x, y, 2.0);
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("l");
        for k in 0..6 {
            b.push_triangle([p(k, 0.0), p(k + 1, 0.0), p(k + 1, 2.0)])
                .unwrap();
            b.push_triangle([p(k, 0.0), p(k + 1, 2.0), p(k, 2.0)])
                .unwrap();
        }
        for t in [
            [r(1.0, 1.0), r(1.0, 3.0), r(0.0, 3.0)],
            [r(1.0, 1.0), r(0.0, 3.0), r(0.0, 0.0)],
            [r(1.0, 1.0), r(0.0, 0.0), r(3.0, 0.0)],
            [r(1.0, 1.0), r(3.0, 0.0), r(3.0, 1.0)],
        ] {
            b.push_triangle(t).unwrap();
        }
        b.begin_object("box");
        let mut tris = Vec::new();
        push_box(
            &mut tris,
            Vec3::new(-2.0, -2.0, 0.5),
            Vec3::new(-1.5, -1.5, 1.0),
        );
        for t in tris {
            b.push_triangle(t).unwrap();
        }
        b.finish(std::path::Path::new("l")).unwrap()
    }

    #[test]
    fn a_concave_solid_hides_behind_its_corner_by_its_cuts() {
        use crate::oracle::oracle_occluders::extract;
        use crate::trace::{Ray, Tracer};
        let scene = l_prism_scene();
        let found = extract(&scene);
        // The L (and the closed box).
        assert_eq!(found.solids.len(), 2);
        assert_eq!(found.solids[0].open_bottom, Some(0.0));
        assert_eq!(found.solids[0].object, 0);
        // The cell in the L's notch, above the missing floor.
        let cell = (DVec3::new(2.0, 2.0, 0.5), DVec3::new(2.5, 2.5, 1.0));
        let (qmin, qmax) = (DVec3::new(-2.0, -2.0, 0.5), DVec3::new(-1.5, -1.5, 1.0));
        // Rays: every segment from the cell to the box hits the L first.
        let tracer = Tracer::new(&scene);
        let mut rng = Pcg64::seed_from_u64(3);
        let rays: Vec<Ray> = (0..20_000)
            .map(|_| {
                let u = DVec3::new(rng.random(), rng.random(), rng.random());
                let a = cell.0 + (cell.1 - cell.0) * u;
                Ray::segment(a.as_vec3(), scene.sample_surface(1, &mut rng))
            })
            .collect();
        assert!(
            tracer
                .closest_hits(&rays)
                .iter()
                .all(|h| h.is_some_and(|h| h.object == 0))
        );
        let no = |_: u32| false;
        let with_cuts = Search {
            ..search(&found.occluders, &no)
        };
        let shafts = Shafts::new(&found.occluders, &found.solids);
        assert!(shafts.hidden(&with_cuts, 1, &[], cell, qmin, qmax));
        // Its faces alone (convex polygons) leave the segments through the
        // outer corner's edge, which lies on two of them.
        let faces = Shafts::new(&found.occluders, &[]);
        assert!(!faces.hidden(&search(&found.occluders, &no), 1, &[], cell, qmin, qmax));
        // Below the missing floor the cuts prove nothing.
        let low = (DVec3::new(2.0, 2.0, -1.0), DVec3::new(2.5, 2.5, 1.0));
        assert!(!shafts.hidden(&with_cuts, 1, &[], low, qmin, qmax));
        // Nor for the L itself.
        assert!(!shafts.hidden(&with_cuts, 0, &[], cell, qmin, qmax));
    }

    /// Two walls across x, each one solid of four boxes around a door
    /// (1 x 1 m, the first at y in [0, 1], the second at y in `[door,
    /// door + 1]`), and a box behind the second.
    fn doors_scene(door: f32) -> crate::scene::Scene {
        use crate::scene::procedural::shapes::push_box;
        use crate::scene::{SceneBuilder, SceneFormat};
        use glam::Vec3;
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        for (x, y) in [(2.0, 0.0), (4.0, door)] {
            b.begin_object(format!("wall_{x}"));
            let mut tris = Vec::new();
            let (x0, x1) = (x, x + 0.2);
            push_box(
                &mut tris,
                Vec3::new(x0, -10.0, -10.0),
                Vec3::new(x1, y, 10.0),
            );
            push_box(
                &mut tris,
                Vec3::new(x0, y + 1.0, -10.0),
                Vec3::new(x1, 10.0, 10.0),
            );
            push_box(
                &mut tris,
                Vec3::new(x0, y, -10.0),
                Vec3::new(x1, y + 1.0, 0.0),
            );
            push_box(
                &mut tris,
                Vec3::new(x0, y, 1.0),
                Vec3::new(x1, y + 1.0, 10.0),
            );
            for t in tris {
                b.push_triangle(t).unwrap();
            }
        }
        b.begin_object("box");
        let mut tris = Vec::new();
        push_box(
            &mut tris,
            Vec3::new(6.0, 2.0, 0.0),
            Vec3::new(6.5, 5.0, 1.0),
        );
        for t in tris {
            b.push_triangle(t).unwrap();
        }
        b.finish(std::path::Path::new("doors")).unwrap()
    }

    /// How many of 20,000 segments from the cell to object `object`'s
    /// surface hit it first.
    fn seen_by_segments(scene: &crate::scene::Scene, object: u32) -> usize {
        use crate::trace::{Ray, Tracer};
        let tracer = Tracer::new(scene);
        let mut rng = Pcg64::seed_from_u64(5);
        let rays: Vec<Ray> = (0..20_000)
            .map(|_| {
                let u = DVec3::new(rng.random(), rng.random(), rng.random());
                let a = CELL.0 + (CELL.1 - CELL.0) * u;
                Ray::segment(a.as_vec3(), scene.sample_surface(object as usize, &mut rng))
            })
            .collect();
        tracer
            .closest_hits(&rays)
            .iter()
            .filter(|h| h.is_some_and(|h| h.object == object))
            .count()
    }

    #[test]
    fn a_door_is_a_portal_to_the_wall_behind_it() {
        use crate::oracle::oracle_occluders::extract;
        // From the cell, a line through the first door is too flat to pass
        // the second (slope dy/dx at most 1 against at least 1.1): the
        // box is hidden by the two walls together, the first blocking
        // what misses its door, the second what passes it.
        let scene = doors_scene(3.0);
        let found = extract(&scene);
        assert_eq!(found.solids.len(), 3);
        assert_eq!(seen_by_segments(&scene, 2), 0);
        let (qmin, qmax) = (DVec3::new(6.0, 2.0, 0.0), DVec3::new(6.5, 5.0, 1.0));
        let no = |_: u32| false;
        let shafts = Shafts::new(&found.occluders, &found.solids);
        let tight = Search {
            budget: 64,
            depth: 16,
            ..search(&found.occluders, &no)
        };
        assert!(shafts.hidden(&tight, 2, &[], CELL, qmin, qmax));
        // Either wall alone leaves segments open: neither hides it.
        for w in 0..2 {
            let one = |o: u32| o != w;
            let alone = Search {
                skip: &one,
                ..tight
            };
            assert!(!shafts.hidden(&alone, 2, &[], CELL, qmin, qmax));
        }
        // The second door in line with the first: seen through both.
        let scene = doors_scene(1.0);
        let found = extract(&scene);
        assert!(seen_by_segments(&scene, 2) > 0);
        let shafts = Shafts::new(&found.occluders, &found.solids);
        let open = Search {
            ..search(&found.occluders, &no)
        };
        assert!(!shafts.hidden(&open, 2, &[], CELL, qmin, qmax));
    }

    /// A ridge of ground (a height field of 2 m squares, 6 m high along
    /// y = 30) blocks the shafts from a cell on its near side to a box
    /// behind it below its line of sight, and not to one high above it;
    /// segments between the blocked parts do pass below the surface.
    #[test]
    fn a_terrain_blocks_shafts_below_its_surface() {
        use glam::Vec3;
        let height = |x: f32, y: f32| 6.0 * (-(y - 30.0).powi(2) / 20.0).exp() + 0.01 * x;
        let at = |i: usize, j: usize| {
            let (x, y) = (2.0 * i as f32, 2.0 * j as f32);
            Vec3::new(x, y, height(x, y))
        };
        let mut tris = Vec::new();
        for j in 0..30 {
            for i in 0..30 {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        let terrain = Terrain::detect(0, &tris).expect("a terrain");
        let cell = (DVec3::new(27.0, 10.0, 1.0), DVec3::new(29.0, 12.0, 2.5));
        let no = |_: u32| false;
        let terrains = [&terrain];
        let with = Search {
            terrains: &terrains,
            ..search(&[], &no)
        };
        assert!(terrain.usable(cell.0, cell.1, with.slack));
        let low = (DVec3::new(30.0, 44.0, 0.0), DVec3::new(32.0, 46.0, 2.5));
        let high = (DVec3::new(30.0, 44.0, 20.0), DVec3::new(32.0, 46.0, 22.0));
        assert!(terrain_blocks(&with, cell, low));
        assert!(!terrain_blocks(&with, cell, high));
        // Beside the cell (apart along x only, over the flat ground): no.
        let beside = (DVec3::new(40.0, 10.0, 0.5), DVec3::new(42.0, 12.0, 2.0));
        assert!(!terrain_blocks(&with, cell, beside));
        // Segments between the blocked boxes go below the surface: the
        // piecewise-linear height under points along them, by brute force.
        let under = |p: DVec3| {
            tris.iter()
                .find_map(|t| {
                    let [a, b, c] = t.map(|v| v.as_dvec3());
                    let (e, f, q) = ((b - a).truncate(), (c - a).truncate(), (p - a).truncate());
                    let d = e.perp_dot(f);
                    let (u, v) = (q.perp_dot(f) / d, e.perp_dot(q) / d);
                    (u >= 0.0 && v >= 0.0 && u + v <= 1.0)
                        .then_some(a.z + u * (b.z - a.z) + v * (c.z - a.z))
                })
                .expect("over the ground")
        };
        let mut rng = Pcg64::seed_from_u64(46);
        for _ in 0..200 {
            let pick = |(lo, hi): (DVec3, DVec3), rng: &mut Pcg64| {
                lo + (hi - lo) * DVec3::new(rng.random(), rng.random(), rng.random())
            };
            let (p, q) = (pick(cell, &mut rng), pick(low, &mut rng));
            assert!(p.z > under(p));
            assert!((1..100).any(|k| {
                let x = p + (q - p) * (k as f64 / 100.0);
                x.z < under(x)
            }));
        }
    }
}
