//! Sealed rooms: what no segment from the cell can reach through the free
//! space between the closed solids.
//!
//! Projections prove an object hidden when some plane's fused occluders
//! cover it from the whole cell. A room closed by walls, slabs and doors
//! that are separate solids is often not proved that way: seen from a
//! cell 3 m wide, a wall standing on the gap between two slabs leaves the
//! gap open on every plane, and what lies above a ceiling straddles every
//! plane placed there. Connectivity proves it instead.
//!
//! **The argument.** Let `S` be the closed solids (`oracle_occluders.rs`:
//! closed modulo two, or open only at the bottom, with the virtual floor
//! counted for points above it). A ray from a viewpoint `p` that first hits
//! an object at `q` hits nothing before `q`; the tracer is two-sided and
//! watertight, so the segment crosses no solid's surface before `q` but
//! within its rounding of either end. If `p` is outside every solid, every
//! point of the segment but those near its ends is outside every closed
//! solid. Cover the scene's box with a rectilinear grid of voxels and call
//! a voxel *blocked* when its closed box lies in the union of the closed
//! solids. Then no such point lies in a blocked voxel, and the segment runs
//! through a chain of free voxels, each sharing a point (a face, an edge
//! or a corner: 26 neighbours) with the next, from one meeting the cell to
//! one meeting the object. So an object whose surface meets no free voxel
//! connected to the cell is hidden from every viewpoint of the cell
//! outside the solids. From a viewpoint inside (or on) a solid, a ray sees
//! only what lies within that solid before it leaves it: the objects with
//! a point in (or within the pad of) a solid that the cell meets are kept;
//! and a ray leaving a solid open at the bottom through its floor, which
//! the tracer does not see, goes on in the free space under the floor, so
//! the components of the voxels just under it are reached as well.
//!
//! The rounding near the ends is covered by a pad of twice the tracer's
//! slack ([`super::tracer_slack`]): the cell, the solids it meets and the
//! voxels an object reaches are all grown by it, and objects whose boxes
//! come within two pads of the cell are kept. A segment lying exactly in a
//! face shared by two solids (a wall's bottom on a slab's top) meets
//! neither's inside and is not seen by the tracer's triangle tests, but it
//! runs between blocked voxels; such rays are a set of measure zero (a
//! ray's direction exactly in the plane of a face), so they are left out
//! of the argument, as they are of every check with random rays.
//!
//! **Blocked voxels.** The grid's planes are the axis-aligned planes of
//! the solids' faces (a wall's two sides, a slab's top and bottom, every
//! floorless solid's floor), so that thin walls and the faces two solids
//! share fall on voxel boundaries, with a uniform fill between them. A
//! voxel is blocked when it lies in one solid: no triangle *of that solid*
//! meets its *open* box (exactly on the box's own axes, with a margin on
//! the other separating axes, so that a doubtful case counts as meeting)
//! and a point of it is inside the solid, by the parity of a line along x
//! through its row (a row whose line passes near an edge, or runs nearly
//! parallel to a triangle, is not used). An open box that meets no
//! surface of a solid lies wholly inside it or wholly outside, so the
//! closed box lies in the closed solid. A voxel that surfaces meet in one
//! plane only, exactly (Shewchuk's predicate on the solids' vertices: two
//! walls mitred at a corner share a slanted face), is blocked when the
//! open pieces on either side each have a point inside one of those
//! solids. The free voxels are then labelled by 26-connected components
//! once per scene; a cell costs a look-up of the components its voxels
//! belong to.
//!
//! Solids open at the bottom: a segment from above a floor never passes
//! it into the solid (the solid lies above its floor), but one from below
//! can, unseen; so a cell whose padded box reaches down to the highest
//! floor gets no proof here. A floorless solid whose faces all lie in its
//! floor (a flat polygon) has no inside and is left out (its height does
//! not count), as is one whose floor the budget dropped from the grid's
//! planes (its floor would cut voxels). The grid's box and the scene's
//! are always planes, whatever the budget. A cell whose tracer slack
//! exceeds the grid's (far outside the scene) gets no proof either.
//! `tests/it/oracle.rs` keeps two reviews' counterexamples (a cell inside
//! a raised shell open at the bottom, an attic under a bottomless roof, a
//! slit of 2^-30 between two parts of a wall that a tolerance took for one
//! plane, the grid's top planes dropped by a small budget).

use std::ops::Range;

use glam::DVec3;
use rayon::prelude::*;

use super::oracle_occluders::SlicedSolid;
use crate::bitset::ObjectSet;
use crate::geom::{Aabb, BoxTree};
use crate::scene::Scene;

/// A voxel inside the union of the closed solids.
const BLOCKED: u32 = u32::MAX;

/// Fractions of a voxel's sides at which points are taken: off the
/// simple fractions, where the projection of a face's diagonal often runs.
const OFF_Y: f64 = std::f64::consts::SQRT_2 - 1.0;
const OFF_Z: f64 = std::f64::consts::FRAC_1_PI;

/// The most voxels the uniform fill puts along the scene's longest side.
const FILL: f64 = 96.0;

/// The free space of a scene, in connected components, built at the first
/// cell that can use it (a scene whose cells all lie below a floorless
/// solid's floor never pays for it).
pub(crate) struct Sealed {
    /// The most voxels.
    budget: usize,
    /// Twice the tracer's slack over the grid's box.
    pad: f64,
    /// The highest floor of a solid open at the bottom that has an inside
    /// (minus infinity when none): cells reaching down to it get no proof.
    floor: f64,
    /// The grid, once built.
    grid: std::sync::OnceLock<Grid>,
}

/// The voxels of the free space and their components.
struct Grid {
    /// Per axis, the grid's planes, strictly increasing.
    planes: [Vec<f64>; 3],
    /// Voxels per axis.
    dims: [usize; 3],
    /// Per axis, the coordinate of each voxel's row point: the middle
    /// along x, fractions sqrt 2 - 1 and 1 / pi of the side along y and z
    /// ([`Grid::inside_voxels`]).
    samples: [Vec<f64>; 3],
    /// Per voxel (x fastest), its component or [`BLOCKED`].
    label: Vec<u32>,
    /// Per object, the components whose voxels (grown by the pad) its
    /// surface meets, sorted.
    reach: Vec<Vec<u32>>,
    /// Per solid, whether it blocks: not flat (a floorless solid whose
    /// faces all lie in its floor has no inside), and its floor, if it is
    /// open at the bottom, one of the grid's planes (no voxel straddles
    /// it). The others are left out, as if they were not solids.
    blocker: Vec<bool>,
    /// Per solid, the objects with a point within the pad of it, found
    /// when a cell first meets the solid.
    near: Vec<std::sync::OnceLock<Vec<u32>>>,
    /// Twice the tracer's slack over the grid's box.
    pad: f64,
    /// A margin for the separating-axis tests.
    scale: f64,
    /// Free components.
    components: usize,
    /// Blocked voxels.
    blocked: usize,
}

/// The grid of the free space between the closed solids ([`crate::oracle::Oracle::sealed_counts`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SealedCounts {
    /// Voxels of the grid.
    pub voxels: usize,
    /// Voxels inside the solids.
    pub blocked: usize,
    /// Connected components of the free voxels.
    pub components: usize,
}

/// The grid's box (the scene's, grown by a margin) and its pad.
fn grid_box(scene: &Scene) -> Option<(DVec3, DVec3, f64)> {
    let b = scene.bounds();
    let (smin, smax) = (b.min.as_dvec3(), b.max.as_dvec3());
    if !(smin.is_finite() && smax.is_finite() && smin.cmple(smax).all()) {
        return None;
    }
    let extent = (smax - smin).max_element().max(1e-6);
    let margin = DVec3::splat(0.02 * extent);
    let (lo, hi) = (smin - margin, smax + margin);
    Some((lo, hi, 2.0 * super::tracer_slack(scene, lo, hi)))
}

impl Sealed {
    /// The free space of the scene's solids, over a grid of at most about
    /// `budget` voxels (built when first needed); `None` without solids,
    /// with a budget of 0 or a scene without a finite box.
    pub(crate) fn new(scene: &Scene, solids: &[SlicedSolid], budget: usize) -> Option<Self> {
        if budget == 0 || solids.is_empty() {
            return None;
        }
        let (_, _, pad) = grid_box(scene)?;
        let floor = solids
            .iter()
            .filter_map(|s| s.open_bottom.filter(|&f| s.max.z > f))
            .fold(f64::NEG_INFINITY, f64::max);
        Some(Self {
            budget,
            pad,
            floor,
            grid: std::sync::OnceLock::new(),
        })
    }

    /// What the grid holds (all zero until a cell needed it).
    pub(crate) fn counts(&self) -> SealedCounts {
        self.grid.get().map(Grid::counts).unwrap_or_default()
    }

    /// The objects that may be seen from some point of the cell
    /// `[cmin, cmax]` whose tracer slack is `slack`, as far as the free
    /// space shows; `None` when it proves nothing for this cell.
    pub(crate) fn visible(
        &self,
        scene: &Scene,
        solids: &[SlicedSolid],
        hierarchy: &BoxTree,
        cell: (DVec3, DVec3),
        slack: f64,
    ) -> Option<ObjectSet> {
        // The cell's slack bounds the rounding of its rays, and the grid
        // was padded for slacks up to half its pad. A segment from below a
        // floor can come up into its solid through it, unseen, so only
        // cells above every floor get a proof (and a city of floorless
        // blocks on a terrain, its street cells below some block's floor,
        // never builds the grid).
        if slack.is_nan() || 2.0 * slack > self.pad || cell.0.z - self.pad <= self.floor {
            return None;
        }
        let grid = self
            .grid
            .get_or_init(|| Grid::build(scene, solids, self.budget));
        Some(grid.visible(scene, solids, hierarchy, cell))
    }
}

impl Grid {
    /// Builds the grid over the scene's solids, with at most about
    /// `budget` voxels.
    fn build(scene: &Scene, solids: &[SlicedSolid], budget: usize) -> Self {
        let b = scene.bounds();
        let (smin, smax) = (b.min.as_dvec3(), b.max.as_dvec3());
        let extent = (smax - smin).max_element().max(1e-6);
        let (lo, hi, pad) = grid_box(scene).unwrap_or((smin, smax, 0.0));
        let scale = extent + lo.abs().max(hi.abs()).max_element();
        let planes = choose_planes(solids, lo, hi, smin, smax, extent, budget);
        let blocker: Vec<bool> = solids
            .iter()
            .map(|s| {
                s.open_bottom.is_none_or(|f| {
                    s.max.z > f && planes[2].binary_search_by(|p| p.total_cmp(&f)).is_ok()
                })
            })
            .collect();
        let dims = [0, 1, 2].map(|a| planes[a].len() - 1);
        let total = dims[0] * dims[1] * dims[2];
        let samples = [(0, 0.5), (1, OFF_Y), (2, OFF_Z)].map(|(a, f)| {
            planes[a]
                .windows(2)
                .map(|w| w[0] + f * (w[1] - w[0]))
                .collect()
        });
        let mut grid = Self {
            planes,
            dims,
            samples,
            label: Vec::new(),
            reach: Vec::new(),
            blocker,
            near: solids.iter().map(|_| std::sync::OnceLock::new()).collect(),
            pad,
            scale,
            components: 0,
            blocked: 0,
        };
        let blocked = grid.blocked(solids, total);
        grid.blocked = blocked.iter().filter(|&&b| b).count();
        grid.label_components(&blocked);
        grid.reach = grid.reach_of_objects(scene);
        grid
    }

    fn counts(&self) -> SealedCounts {
        SealedCounts {
            voxels: self.label.len(),
            blocked: self.blocked,
            components: self.components,
        }
    }

    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// The voxels of index ranges along x, y and z (x fastest), with
    /// their indices.
    fn voxels(&self, r: &[Range<usize>; 3]) -> impl Iterator<Item = (usize, [usize; 3])> + '_ {
        let [ri, rj, rk] = r.clone();
        rk.flat_map(move |k| {
            let ri = ri.clone();
            rj.clone()
                .flat_map(move |j| ri.clone().map(move |i| [i, j, k]))
        })
        .map(|[i, j, k]| (self.index(i, j, k), [i, j, k]))
    }

    fn voxel_box(&self, [i, j, k]: [usize; 3]) -> (DVec3, DVec3) {
        let p = &self.planes;
        (
            DVec3::new(p[0][i], p[1][j], p[2][k]),
            DVec3::new(p[0][i + 1], p[1][j + 1], p[2][k + 1]),
        )
    }

    /// The voxels that lie in one solid: their open box meets none of its
    /// triangles (the other solids' do not matter) and a point of them is
    /// inside it, by the parity of each row's line along x (rows the line
    /// cannot decide are left out); then [`Grid::block_seams`].
    fn blocked(&self, solids: &[SlicedSolid], total: usize) -> Vec<bool> {
        let mut blocked = vec![false; total];
        // The last solid whose surface meets each voxel, plus one.
        let mut touched = vec![0u32; total];
        for (si, s) in solids.iter().enumerate() {
            if !self.blocker[si] {
                continue;
            }
            let stamp = si as u32 + 1;
            for t in &s.triangles {
                let (tmin, tmax) = tri_box(t);
                let r = [0, 1, 2].map(|a| open_range(&self.planes[a], tmin[a], tmax[a]));
                for (v, ijk) in self.voxels(&r) {
                    if touched[v] == stamp {
                        continue;
                    }
                    let (a, b) = self.voxel_box(ijk);
                    if tri_meets_box(t, a, b, self.scale) {
                        touched[v] = stamp;
                    }
                }
            }
            self.inside_voxels(s, |v, decided| {
                if decided && touched[v] != stamp {
                    blocked[v] = true;
                }
            });
        }
        self.block_seams(solids, &mut blocked);
        blocked
    }

    /// Calls `each(v, true)` for every voxel of the solid's box whose row
    /// point lies inside the solid by the parity of the row's line along
    /// x, and `each(v, false)` for every voxel of a row the line cannot
    /// decide (it passes near an edge, runs nearly parallel to a triangle,
    /// or crosses an odd number of times). Each row's line runs through a
    /// point of the open rectangle of its voxels' y and z ranges; not the
    /// centre, which lies on the diagonal of every rectangular face whose
    /// corners are planes of the grid, but a point off every such
    /// diagonal. Any point of an open voxel that no surface of the solid
    /// meets tells whether the whole voxel is inside.
    fn inside_voxels(&self, s: &SlicedSolid, mut each: impl FnMut(usize, bool)) {
        let [xc, yc, zc] = &self.samples;
        let rows_y = closed_centres(yc, s.min.y, s.max.y);
        let rows_z = closed_centres(zc, s.min.z, s.max.z);
        let ny = rows_y.len();
        let rows = ny * rows_z.len();
        if rows == 0 {
            return;
        }
        let mut crossings: Vec<Vec<f64>> = vec![Vec::new(); rows];
        let mut doubtful = vec![false; rows];
        for t in &s.triangles {
            let (tmin, tmax) = tri_box(t);
            for k in closed_centres(zc, tmin.z, tmax.z) {
                for j in closed_centres(yc, tmin.y, tmax.y) {
                    let row = (j - rows_y.start) + ny * (k - rows_z.start);
                    match crossing_x(t, yc[j], zc[k]) {
                        Crossing::Miss => {}
                        Crossing::Doubtful => doubtful[row] = true,
                        Crossing::At(x) => crossings[row].push(x),
                    }
                }
            }
        }
        for (row, xs) in crossings.iter_mut().enumerate() {
            let (j, k) = (rows_y.start + row % ny, rows_z.start + row / ny);
            if doubtful[row] || xs.len() % 2 == 1 {
                for i in closed_centres(xc, s.min.x, s.max.x) {
                    each(self.index(i, j, k), false);
                }
                continue;
            }
            xs.sort_by(f64::total_cmp);
            for pair in xs.chunks_exact(2) {
                let (a, b) = (pair[0], pair[1]);
                for i in closed_centres(xc, a, b) {
                    if xc[i] > a && xc[i] < b {
                        each(self.index(i, j, k), true);
                    }
                }
            }
        }
    }

    /// Voxels that solids' surfaces meet in one plane only (two walls
    /// mitred at a corner share a slanted face, and no plane of the grid
    /// can follow it): the plane cuts such a voxel into two open convex
    /// pieces that no surface meets, so each lies wholly inside or wholly
    /// outside each solid; the voxel is blocked when each piece has a
    /// point inside one of the solids whose surfaces meet it.
    fn block_seams(&self, solids: &[SlicedSolid], blocked: &mut [bool]) {
        struct Seam {
            /// The first triangle met: its plane is the seam's.
            plane: [DVec3; 3],
            /// A surface off that plane meets the voxel too.
            many: bool,
            solids: Vec<u32>,
        }
        // Exactly in the plane (Shewchuk's adaptive predicate on the
        // solids' own vertices): a face a hair off it leaves a real gap.
        let in_plane =
            |plane: &[DVec3; 3], t: &[DVec3; 3]| t.iter().all(|&p| orient(plane, p) == 0.0);
        let mut seams: std::collections::BTreeMap<usize, Seam> = Default::default();
        for (si, s) in solids.iter().enumerate() {
            if !self.blocker[si] {
                continue;
            }
            for t in &s.triangles {
                if (t[1] - t[0]).cross(t[2] - t[0]) == DVec3::ZERO {
                    continue;
                }
                let (tmin, tmax) = tri_box(t);
                let r = [0, 1, 2].map(|a| open_range(&self.planes[a], tmin[a], tmax[a]));
                for (v, ijk) in self.voxels(&r) {
                    if blocked[v] {
                        continue;
                    }
                    if let Some(seam) = seams.get(&v)
                        && (seam.many
                            || (seam.solids.last() == Some(&(si as u32))
                                && in_plane(&seam.plane, t)))
                    {
                        continue;
                    }
                    let (a, b) = self.voxel_box(ijk);
                    if !tri_meets_box(t, a, b, self.scale) {
                        continue;
                    }
                    let seam = seams.entry(v).or_insert_with(|| Seam {
                        plane: *t,
                        many: false,
                        solids: Vec::new(),
                    });
                    if !in_plane(&seam.plane, t) {
                        seam.many = true;
                    }
                    if seam.solids.last() != Some(&(si as u32)) {
                        seam.solids.push(si as u32);
                    }
                }
            }
        }
        for (v, seam) in seams {
            if seam.many {
                continue;
            }
            let [nx, ny, _] = self.dims;
            let (a, b) = self.voxel_box([v % nx, (v / nx) % ny, v / (nx * ny)]);
            let c = 0.5 * (a + b);
            let corners: Vec<(DVec3, f64)> = (0..8)
                .map(|m| {
                    let p = DVec3::new(
                        if m & 1 == 0 { a.x } else { b.x },
                        if m & 2 == 0 { a.y } else { b.y },
                        if m & 4 == 0 { a.z } else { b.z },
                    );
                    (p, orient(&seam.plane, p))
                })
                .collect();
            let mut all_inside = true;
            for sign in [1.0, -1.0] {
                // The open voxel has a piece on this side exactly when a
                // corner lies strictly on it (exact signs). A point of the
                // piece: the corner farthest on it, moved towards the
                // centre until it is strictly inside the voxel and still
                // (exactly) on this side.
                let Some(&(corner, _)) = corners
                    .iter()
                    .filter(|x| sign * x.1 > 0.0)
                    .max_by(|x, y| (sign * x.1).total_cmp(&(sign * y.1)))
                else {
                    continue; // No piece on this side.
                };
                let point = (0..12).map(|m| OFF_Y * 0.5f64.powi(m)).find_map(|f| {
                    let p = corner + (c - corner) * f;
                    (p.cmpgt(a).all() && p.cmplt(b).all() && sign * orient(&seam.plane, p) > 0.0)
                        .then_some(p)
                });
                let inside = point.is_some_and(|p| {
                    seam.solids
                        .iter()
                        .any(|&si| point_inside(&solids[si as usize], p) == Some(true))
                });
                if !inside {
                    all_inside = false;
                    break;
                }
            }
            if all_inside {
                blocked[v] = true;
            }
        }
    }

    /// Labels the free voxels by 26-connected component, in scan order.
    fn label_components(&mut self, blocked: &[bool]) {
        let [nx, ny, nz] = self.dims;
        let mut label: Vec<u32> = blocked
            .iter()
            .map(|&b| if b { BLOCKED } else { BLOCKED - 1 })
            .collect();
        let mut next = 0u32;
        let mut stack = Vec::new();
        for start in 0..label.len() {
            if label[start] != BLOCKED - 1 {
                continue;
            }
            label[start] = next;
            stack.push(start);
            while let Some(v) = stack.pop() {
                let (i, j, k) = (v % nx, (v / nx) % ny, v / (nx * ny));
                for dk in -1i64..=1 {
                    let k2 = k as i64 + dk;
                    if k2 < 0 || k2 >= nz as i64 {
                        continue;
                    }
                    for dj in -1i64..=1 {
                        let j2 = j as i64 + dj;
                        if j2 < 0 || j2 >= ny as i64 {
                            continue;
                        }
                        for di in -1i64..=1 {
                            let i2 = i as i64 + di;
                            if i2 < 0 || i2 >= nx as i64 {
                                continue;
                            }
                            let w = self.index(i2 as usize, j2 as usize, k2 as usize);
                            if label[w] == BLOCKED - 1 {
                                label[w] = next;
                                stack.push(w);
                            }
                        }
                    }
                }
            }
            next += 1;
        }
        self.components = next as usize;
        self.label = label;
    }

    /// Per object, the components of the free voxels its triangles meet
    /// (each voxel grown by the pad).
    fn reach_of_objects(&self, scene: &Scene) -> Vec<Vec<u32>> {
        let pad = DVec3::splat(self.pad);
        (0..scene.objects().len())
            .into_par_iter()
            .map(|o| {
                let mut found: Vec<u32> = Vec::new();
                for t in scene.object_triangles(o) {
                    let t = t.map(|v| v.as_dvec3());
                    let (tmin, tmax) = tri_box(&t);
                    let r = [0, 1, 2].map(|a| {
                        closed_range(&self.planes[a], tmin[a] - self.pad, tmax[a] + self.pad)
                    });
                    for (v, ijk) in self.voxels(&r) {
                        let l = self.label[v];
                        if l == BLOCKED || found.contains(&l) {
                            continue;
                        }
                        let (a, b) = self.voxel_box(ijk);
                        if tri_meets_box(&t, a - pad, b + pad, self.scale) {
                            found.push(l);
                        }
                    }
                }
                found.sort_unstable();
                found
            })
            .collect()
    }

    /// [`Sealed::visible`], once the cell is known to be above every
    /// floor and within the grid's slack.
    fn visible(
        &self,
        scene: &Scene,
        solids: &[SlicedSolid],
        hierarchy: &BoxTree,
        (cmin, cmax): (DVec3, DVec3),
    ) -> ObjectSet {
        let pad = self.pad;
        let (pmin, pmax) = (cmin - pad, cmax + pad);
        let lo = DVec3::new(self.planes[0][0], self.planes[1][0], self.planes[2][0]);
        let hi = DVec3::new(
            self.planes[0][self.dims[0]],
            self.planes[1][self.dims[1]],
            self.planes[2][self.dims[2]],
        );
        let mut seeds: Vec<u32> = Vec::new();
        if !(pmin.cmpgt(lo).all() && pmax.cmplt(hi).all()) {
            // Beyond the grid: segments enter it through the outer shell
            // of voxels, which holds no solid (voxel 0 is one of them).
            seeds.push(self.label[0]);
        }
        let seed_box = |a: DVec3, b: DVec3, seeds: &mut Vec<u32>| {
            let r = [0, 1, 2].map(|k| closed_range(&self.planes[k], a[k], b[k]));
            for (v, _) in self.voxels(&r) {
                let l = self.label[v];
                if l != BLOCKED {
                    seeds.push(l);
                }
            }
        };
        seed_box(pmin, pmax, &mut seeds);
        // The solids the cell meets (it may lie inside them).
        let met: Vec<usize> = (0..solids.len())
            .filter(|&si| {
                let s = &solids[si];
                self.blocker[si]
                    && s.min.cmple(pmax).all()
                    && s.max.cmpge(pmin).all()
                    && self.meets(s, pmin, pmax)
            })
            .collect();
        // From inside a solid open at the bottom a ray can leave through
        // its floor, which the tracer does not see (a review's
        // counterexample): what the voxels just under the floor reach is
        // reached too.
        for &si in &met {
            let s = &solids[si];
            if let Some(floor) = s.open_bottom {
                let (a, b) = (s.min - pad, s.max + pad);
                seed_box(
                    DVec3::new(a.x, a.y, floor - pad),
                    DVec3::new(b.x, b.y, floor),
                    &mut seeds,
                );
            }
        }
        seeds.sort_unstable();
        seeds.dedup();
        let objects = scene.objects().len();
        let mut keep = ObjectSet::new(objects);
        for (o, comps) in self.reach.iter().enumerate() {
            if comps.iter().any(|c| seeds.binary_search(c).is_ok()) {
                keep.insert(o);
            }
        }
        let mut near = Vec::new();
        let mut keep_meeting = |a: DVec3, b: DVec3, keep: &mut ObjectSet| {
            let outward = Aabb::new(
                a.as_vec3().map(f32::next_down),
                b.as_vec3().map(f32::next_up),
            );
            near.clear();
            hierarchy.overlapping(&outward, &mut near);
            for &j in &near {
                let o = &scene.objects()[j as usize].bounds;
                if o.min.as_dvec3().cmple(b).all() && o.max.as_dvec3().cmpge(a).all() {
                    keep.insert(j as usize);
                }
            }
        };
        // Short segments: whatever comes within two pads of the cell.
        keep_meeting(pmin - pad, pmax + pad, &mut keep);
        // Viewpoints inside a solid see what lies within it (and, for one
        // open at the bottom, what is reached under its floor, above).
        for si in met {
            let s = &solids[si];
            let near = self.near[si].get_or_init(|| self.near_objects(scene, s, hierarchy));
            for &o in near {
                keep.insert(o as usize);
            }
        }
        keep
    }

    /// The objects with a point within the pad of a closed solid: whose
    /// triangles (grown by the pad) meet a voxel holding a point of it,
    /// one its surface meets (closed boxes) or one inside it. A ray from
    /// a viewpoint inside the solid stays in it up to its first hit.
    fn near_objects(&self, scene: &Scene, s: &SlicedSolid, hierarchy: &BoxTree) -> Vec<u32> {
        let pad = DVec3::splat(self.pad);
        let mut region: Vec<usize> = Vec::new();
        for t in &s.triangles {
            let (tmin, tmax) = tri_box(t);
            let r = [0, 1, 2].map(|a| closed_range(&self.planes[a], tmin[a], tmax[a]));
            for (v, ijk) in self.voxels(&r) {
                let (a, b) = self.voxel_box(ijk);
                if tri_meets_box(t, a, b, self.scale) {
                    region.push(v);
                }
            }
        }
        region.sort_unstable();
        region.dedup();
        // Inside by parity, or undecided (counted as inside).
        self.inside_voxels(s, |v, _| region.push(v));
        region.sort_unstable();
        region.dedup();
        let (lo, hi) = (s.min - pad, s.max + pad);
        let outward = Aabb::new(
            lo.as_vec3().map(f32::next_down),
            hi.as_vec3().map(f32::next_up),
        );
        let mut candidates = Vec::new();
        hierarchy.overlapping(&outward, &mut candidates);
        candidates.sort_unstable();
        let mut near = Vec::new();
        for o in candidates {
            // A big object (a terrain) whose box meets the solid's is kept
            // without looking at its triangles one by one.
            let triangles = scene.object_triangles(o as usize);
            if triangles.len() > 4096 {
                near.push(o);
                continue;
            }
            let meets = triangles.iter().any(|t| {
                let t = t.map(|v| v.as_dvec3());
                let (tmin, tmax) = tri_box(&t);
                if !((tmin - pad).cmple(hi).all() && (tmax + pad).cmpge(lo).all()) {
                    return false;
                }
                let r = [0, 1, 2]
                    .map(|a| closed_range(&self.planes[a], tmin[a] - self.pad, tmax[a] + self.pad));
                self.voxels(&r).any(|(v, ijk)| {
                    let (a, b) = self.voxel_box(ijk);
                    region.binary_search(&v).is_ok()
                        && tri_meets_box(&t, a - pad, b + pad, self.scale)
                })
            });
            if meets || o == s.object {
                near.push(o);
            }
        }
        near
    }

    /// Whether the closed box `[a, b]` may meet the closed solid: a
    /// triangle meets it, or its centre is inside (or the parity cannot
    /// tell).
    fn meets(&self, s: &SlicedSolid, a: DVec3, b: DVec3) -> bool {
        let mut parity = false;
        let c = 0.5 * (a + b);
        for t in &s.triangles {
            let (tmin, tmax) = tri_box(t);
            if tmin.cmple(b).all() && tmax.cmpge(a).all() && tri_meets_box(t, a, b, self.scale) {
                return true;
            }
            if tmin.y <= c.y && tmax.y >= c.y && tmin.z <= c.z && tmax.z >= c.z {
                match crossing_x(t, c.y, c.z) {
                    Crossing::Miss => {}
                    Crossing::Doubtful => return true,
                    Crossing::At(x) => {
                        // The box is not met, so the crossing is off it.
                        if x > c.x {
                            parity = !parity;
                        }
                    }
                }
            }
        }
        parity
    }
}

/// The exact orientation of `p` against the plane through a triangle's
/// corners: its sign is exact (0 exactly when `p` lies in the plane), its
/// size about six times the tetrahedron's volume.
fn orient(plane: &[DVec3; 3], p: DVec3) -> f64 {
    let k = |v: DVec3| robust::Coord3D {
        x: v.x,
        y: v.y,
        z: v.z,
    };
    robust::orient3d(k(plane[0]), k(plane[1]), k(plane[2]), k(p))
}

/// Whether a point is inside a solid, by the parity of the crossings of
/// a line from it along +x (+y, then +z, where a crossing along the first
/// is doubtful); `None` when none decides.
fn point_inside(s: &SlicedSolid, p: DVec3) -> Option<bool> {
    if !(s.min.cmple(p).all() && s.max.cmpge(p).all()) {
        return Some(false);
    }
    if s.open_bottom.is_some_and(|f| p.z <= f) {
        return Some(false);
    }
    // The axis first, then the two others, as x, y, z.
    let swizzle = |v: DVec3, axis: usize| match axis {
        0 => v,
        1 => DVec3::new(v.y, v.z, v.x),
        _ => DVec3::new(v.z, v.x, v.y),
    };
    'axes: for axis in 0..3 {
        let q = swizzle(p, axis);
        let mut odd = false;
        for t in &s.triangles {
            let t = t.map(|v| swizzle(v, axis));
            let (tmin, tmax) = tri_box(&t);
            if tmax.x < q.x || tmin.y > q.y || tmax.y < q.y || tmin.z > q.z || tmax.z < q.z {
                continue;
            }
            match crossing_x(&t, q.y, q.z) {
                Crossing::Miss => {}
                Crossing::Doubtful => continue 'axes,
                Crossing::At(x) => {
                    if x == q.x {
                        continue 'axes;
                    }
                    if x > q.x {
                        odd = !odd;
                    }
                }
            }
        }
        return Some(odd);
    }
    None
}

/// Chooses the grid's planes: the scene's box and the grid's, the floors
/// of floorless solids, the axis-aligned planes of the solids' faces (the
/// largest total area first when they are too many), and a uniform fill.
fn choose_planes(
    solids: &[SlicedSolid],
    lo: DVec3,
    hi: DVec3,
    smin: DVec3,
    smax: DVec3,
    extent: f64,
    budget: usize,
) -> [Vec<f64>; 3] {
    // Per axis, (coordinate, weight): the floors of solids open at the
    // bottom first, then faces by their total area.
    let mut faces: [Vec<(f64, f64)>; 3] = Default::default();
    for s in solids {
        if let Some(f) = s.open_bottom
            && s.max.z > f
        {
            faces[2].push((f, f64::MAX));
        }
        for t in &s.triangles {
            for (a, axis) in faces.iter_mut().enumerate() {
                if t[0][a] == t[1][a] && t[1][a] == t[2][a] {
                    let area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
                    axis.push((t[0][a], area));
                }
            }
        }
    }
    // Merge equal coordinates, then rank by weight.
    let mut ranked: [Vec<(f64, f64)>; 3] = Default::default();
    for a in 0..3 {
        faces[a].sort_by(|x, y| x.0.total_cmp(&y.0));
        for &(c, w) in &faces[a] {
            match ranked[a].last_mut() {
                Some(last) if last.0 == c => last.1 = (last.1 + w).min(f64::MAX),
                _ => ranked[a].push((c, w)),
            }
        }
        ranked[a].sort_by(|x, y| y.1.total_cmp(&x.1).then(x.0.total_cmp(&y.0)));
    }
    // Half the budget for the faces at most; the grid's box and the
    // scene's are always planes (the outer shell of voxels holds no
    // solid), whatever the budget. A floor dropped here leaves its solid
    // out of the sealing (`Grid::blocker`).
    let mut keep = [0, 1, 2].map(|a| ranked[a].len());
    let cells = |keep: &[usize; 3]| keep.iter().map(|&k| k + 3).product::<usize>();
    while cells(&keep) > budget / 2 {
        let a = (0..3).max_by_key(|&a| (keep[a], a)).unwrap_or(0);
        if keep[a] == 0 {
            break;
        }
        keep[a] -= (keep[a] / 16).max(1);
    }
    let mut planes: [Vec<f64>; 3] = Default::default();
    for a in 0..3 {
        let mut p: Vec<f64> = ranked[a][..keep[a]].iter().map(|x| x.0).collect();
        p.extend([lo[a], smin[a], smax[a], hi[a]]);
        p.sort_by(f64::total_cmp);
        p.dedup();
        planes[a] = p;
    }
    // The uniform fill: the finest spacing (down to the scene's longest
    // side over FILL) that keeps the grid within the budget.
    let count = |step: f64| -> usize {
        planes
            .iter()
            .map(|p| {
                p.windows(2)
                    .map(|w| ((w[1] - w[0]) / step).ceil().max(1.0) as usize)
                    .sum::<usize>()
            })
            .product()
    };
    let mut step = extent / FILL;
    while count(step) > budget && step < extent {
        step *= 1.25;
    }
    planes.map(|p| {
        let mut out = Vec::with_capacity(p.len());
        for w in p.windows(2) {
            let n = ((w[1] - w[0]) / step).ceil().max(1.0) as usize;
            for m in 0..n {
                out.push(w[0] + (w[1] - w[0]) * m as f64 / n as f64);
            }
        }
        if let Some(&last) = p.last() {
            out.push(last);
        }
        out.dedup();
        out
    })
}

fn tri_box(t: &[DVec3; 3]) -> (DVec3, DVec3) {
    (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))
}

/// Voxels `i` whose open interval `(p[i], p[i + 1])` meets `[a, b]`.
fn open_range(p: &[f64], a: f64, b: f64) -> Range<usize> {
    let n = p.len() - 1;
    let start = p.partition_point(|&x| x <= a).saturating_sub(1);
    let end = p.partition_point(|&x| x < b).min(n);
    start..end.max(start)
}

/// Voxels `i` whose closed interval `[p[i], p[i + 1]]` meets `[a, b]`.
fn closed_range(p: &[f64], a: f64, b: f64) -> Range<usize> {
    let n = p.len() - 1;
    let start = p.partition_point(|&x| x < a).saturating_sub(1);
    let end = p.partition_point(|&x| x <= b).min(n);
    start..end.max(start)
}

/// Indices of the sorted centres `c` within `[a, b]`.
fn closed_centres(c: &[f64], a: f64, b: f64) -> Range<usize> {
    let start = c.partition_point(|&x| x < a);
    let end = c.partition_point(|&x| x <= b);
    start..end.max(start)
}

/// Whether the triangle may meet the box, given that their boxes overlap:
/// false only when one of the other separating axes (the triangle's
/// normal, the box's axes crossed with its edges) separates them by more
/// than a margin.
fn tri_meets_box(t: &[DVec3; 3], bmin: DVec3, bmax: DVec3, scale: f64) -> bool {
    let c = 0.5 * (bmin + bmax);
    let h = 0.5 * (bmax - bmin);
    let v = t.map(|p| p - c);
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let separated = |axis: DVec3| -> bool {
        let len = axis.length();
        if len == 0.0 {
            return false;
        }
        let p = v.map(|q| q.dot(axis));
        let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        let r = h.x * axis.x.abs() + h.y * axis.y.abs() + h.z * axis.z.abs();
        let tol = 1e-9 * len * scale;
        lo > r + tol || hi < -r - tol
    };
    if separated(e[0].cross(e[1])) {
        return false;
    }
    for edge in e {
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            if separated(axis.cross(edge)) {
                return false;
            }
        }
    }
    true
}

/// Where the line along x through `(y, z)` crosses a triangle.
enum Crossing {
    Miss,
    /// Too near an edge, or the triangle too near parallel to the line.
    Doubtful,
    At(f64),
}

fn crossing_x(t: &[DVec3; 3], y: f64, z: f64) -> Crossing {
    let edge = |a: DVec3, b: DVec3| {
        let t1 = (b.y - a.y) * (z - a.z);
        let t2 = (b.z - a.z) * (y - a.y);
        (t1 - t2, 1e-12 * (t1.abs() + t2.abs()))
    };
    let es = [edge(t[0], t[1]), edge(t[1], t[2]), edge(t[2], t[0])];
    let pos = es.iter().any(|&(e, err)| e > err);
    let neg = es.iter().any(|&(e, err)| e < -err);
    if pos && neg {
        return Crossing::Miss;
    }
    if es.iter().any(|&(e, err)| e.abs() <= err) {
        return Crossing::Doubtful;
    }
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    if n.x.abs() <= 1e-9 * n.length() {
        return Crossing::Doubtful;
    }
    Crossing::At(t[0].x - (n.y * (y - t[0].y) + n.z * (z - t[0].z)) / n.x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_take_open_and_closed_intervals_as_named() {
        let p = [0.0, 1.0, 2.0, 3.0];
        assert_eq!(open_range(&p, 1.0, 2.0), 1..2);
        assert_eq!(closed_range(&p, 1.0, 2.0), 0..3);
        assert!(open_range(&p, 1.0, 1.0).is_empty());
        assert_eq!(open_range(&p, 0.5, 0.5), 0..1);
        assert!(closed_range(&p, -5.0, -4.0).is_empty());
        assert_eq!(closed_range(&p, 2.5, 9.0), 2..3);
        assert_eq!(open_range(&p, -1.0, 9.0), 0..3);
    }

    #[test]
    fn a_triangle_on_a_voxel_face_does_not_meet_it_and_one_across_does() {
        let p = [0.0, 1.0, 2.0];
        // A triangle in the plane z = 1 between two voxels meets neither
        // open box along z.
        assert!(open_range(&p, 1.0, 1.0).is_empty());
        assert_eq!(closed_range(&p, 1.0, 1.0), 0..2);
        // A slanted one across the box meets it; one beyond its corner
        // (x + y = 2.5, the box reaching x + y = 2) does not.
        let slanted = [
            DVec3::new(0.0, 0.0, 0.5),
            DVec3::new(1.0, 0.0, 1.5),
            DVec3::new(0.0, 1.0, 1.5),
        ];
        assert!(tri_meets_box(&slanted, DVec3::ZERO, DVec3::ONE, 10.0));
        let beyond = [
            DVec3::new(2.5, 0.0, 0.0),
            DVec3::new(0.0, 2.5, 0.0),
            DVec3::new(0.0, 2.5, 1.0),
        ];
        assert!(!tri_meets_box(&beyond, DVec3::ZERO, DVec3::ONE, 10.0));
        // Within the margin counts as meeting.
        let grazing = [
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 1.0),
        ];
        assert!(tri_meets_box(&grazing, DVec3::ZERO, DVec3::ONE, 10.0));
    }

    #[test]
    fn the_line_along_x_crosses_a_triangle_where_it_should() {
        let t = [
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(4.0, 1.0, 0.0),
            DVec3::new(3.0, 0.0, 1.0),
        ];
        match crossing_x(&t, 0.25, 0.25) {
            Crossing::At(x) => assert!((x - 2.75).abs() < 1e-12, "{x}"),
            _ => panic!("the line crosses"),
        }
        assert!(matches!(crossing_x(&t, 0.9, 0.9), Crossing::Miss));
        assert!(matches!(crossing_x(&t, 0.5, 0.0), Crossing::Doubtful));
        // A triangle parallel to x: missed off its plane.
        let wall = [
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(5.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 5.0),
        ];
        assert!(matches!(crossing_x(&wall, 0.5, 0.5), Crossing::Miss));
    }
}
