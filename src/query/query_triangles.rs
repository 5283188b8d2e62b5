//! Queries at slice granularity (papers/004): per visible object, the
//! ranges of its triangles to draw, less the slices its leaves' hidden
//! slices cull.
//!
//! A triangle is drawn when some leaf the query meets holds its object
//! and does not cull it; so the answer is the union of what each leaf
//! would draw, as the object sets are, and a slice is culled only where
//! every leaf met proved it hidden. Without slices in the file (or for a
//! box of positions outside the tree's, where nothing is culled) every
//! visible object is drawn whole.

use std::f32::consts::PI;
use std::ops::Range;

use glam::DVec3;

use super::{Clipped, Pvs, SetSizeError, View, frustum_angles};
use crate::bitset::ObjectSet;
use crate::geom::Aabb;
use crate::slices::{SliceIndex, TreeSlices};

/// One visible object's triangles to draw.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct ObjectTriangles {
    /// The object (its index in the scene and in every set).
    pub object: u32,
    /// Ranges of its triangles, as indices into the object's own
    /// triangles in the scene's order (`Scene::object_triangles`):
    /// increasing, disjoint, not touching, never empty.
    pub ranges: Vec<Range<u32>>,
}

impl ObjectTriangles {
    /// The number of triangles to draw.
    pub fn count(&self) -> u64 {
        self.ranges.iter().map(|r| u64::from(r.end - r.start)).sum()
    }
}

impl Pvs {
    /// The leaves' hidden slices, when the file has them (`vis5d build
    /// --slices N`).
    pub fn slices(&self) -> Option<&TreeSlices> {
        self.slices.as_ref()
    }

    /// [`Pvs::query_range`] (the objects, into `out`), and per object of
    /// `out` the triangles to draw, in object order.
    pub fn query_range_triangles(
        &self,
        positions: &Aabb,
        theta: (f32, f32),
        phi: (f32, f32),
        out: &mut ObjectSet,
    ) -> Result<Vec<ObjectTriangles>, SetSizeError> {
        self.query_range(positions, theta, phi, out)?;
        let boxes = if theta.0 <= theta.1 {
            vec![(theta.0, theta.1, phi.0, phi.1)]
        } else {
            vec![(theta.0, PI, phi.0, phi.1), (-PI, theta.1, phi.0, phi.1)]
        };
        self.triangles_of(positions, &boxes, out)
    }

    /// [`Pvs::query_view`] (the objects, into `out`), and per object of
    /// `out` the triangles to draw, in object order.
    pub fn query_view_triangles(
        &self,
        view: &View,
        out: &mut ObjectSet,
    ) -> Result<Vec<ObjectTriangles>, SetSizeError> {
        self.query_view(view, out)?;
        let ranges = frustum_angles(view.dir, view.up, view.fov_x, view.fov_y);
        self.triangles_of(&view.eyes(), ranges.boxes(), out)
    }

    /// [`Pvs::query_view_world`] (the objects, into `out`), and per
    /// object of `out` the triangles to draw, in object order.
    pub fn query_view_world_triangles(
        &self,
        eye: DVec3,
        view: &View,
        out: &mut ObjectSet,
    ) -> Result<Vec<ObjectTriangles>, SetSizeError> {
        self.query_view_world(eye, view, out)?;
        let (positions, local) = self.local_view(eye, view);
        let ranges = frustum_angles(local.dir, local.up, local.fov_x, local.fov_y);
        self.triangles_of(&positions, ranges.boxes(), out)
    }

    /// The triangles to draw of each object of `objects` (the answer of
    /// range queries of `positions` x each of the angle boxes `(theta0,
    /// theta1, phi0, phi1)`, such as [`super::AngularRanges::boxes`]), for
    /// the leaves those ranges meet; each object whole without slices.
    /// An error when `objects` is not of the file's size.
    pub fn triangles_of(
        &self,
        positions: &Aabb,
        boxes: &[(f32, f32, f32, f32)],
        objects: &ObjectSet,
    ) -> Result<Vec<ObjectTriangles>, SetSizeError> {
        self.check_set(objects)?;
        let whole = |o: usize| ObjectTriangles {
            object: o as u32,
            ranges: match self.objects.triangles(o) {
                0 => Vec::new(),
                n => std::iter::once(0..n).collect(),
            },
        };
        let Some(slices) = &self.slices else {
            return Ok(objects.iter().map(whole).collect());
        };
        let (mut ranks, mut sets) = (Vec::new(), Vec::new());
        for &(t0, t1, p0, p1) in boxes {
            if !self.leaves_met(positions, (t0, t1), (p0, p1), &mut ranks, &mut sets) {
                // Outside the tree or not a range: nothing culled.
                return Ok(objects.iter().map(whole).collect());
            }
        }
        // The leaves met, each once, with their sets.
        let words = self.tree.words();
        let mut leaves: Vec<(u32, &[u64])> = ranks
            .iter()
            .enumerate()
            .map(|(k, &rank)| (rank, &sets[k * words..(k + 1) * words]))
            .collect();
        leaves.sort_unstable_by_key(|&(rank, _)| rank);
        leaves.dedup_by_key(|&mut (rank, _)| rank);
        Ok(objects
            .iter()
            .map(|o| {
                // Each holding leaf's indices for the object, looked up
                // once; a leaf without any draws it whole.
                let holding: Option<Vec<_>> = leaves
                    .iter()
                    .filter(|&&(_, set)| set[o / 64] >> (o % 64) & 1 == 1)
                    .map(|&(rank, _)| slices.hidden(rank as usize, o))
                    .collect();
                let Some(holding) = holding.filter(|h| !h.is_empty()) else {
                    return whole(o);
                };
                let mut ranges: Vec<Range<u32>> = Vec::new();
                for t in 0..self.objects.triangles(o) {
                    let culled_in = |indices: &&[SliceIndex]| {
                        slices
                            .sliced
                            .culled_by(o, t as usize, |p| indices.get(p).copied())
                    };
                    if !holding.iter().all(culled_in) {
                        match ranges.last_mut() {
                            Some(r) if r.end == t => r.end = t + 1,
                            _ => ranges.push(t..t + 1),
                        }
                    }
                }
                ObjectTriangles {
                    object: o as u32,
                    ranges,
                }
            })
            .collect())
    }

    /// Appends to `ranks` the preorder ranks of the leaves the range
    /// meets (clipped as [`Pvs::query_range`] clips it), and their sets to
    /// `sets` ([`Pvs::answer_words`] words each); `false` when the range
    /// has a NaN or reaches outside the tree's box of positions (the query
    /// then culls nothing). An empty range meets no leaf.
    fn leaves_met(
        &self,
        positions: &Aabb,
        theta: (f32, f32),
        phi: (f32, f32),
        ranks: &mut Vec<u32>,
        sets: &mut Vec<u64>,
    ) -> bool {
        let range = match self.clip_range(positions, theta, phi) {
            Clipped::Empty => return true,
            Clipped::Everything => return false,
            Clipped::Range(range) => range,
        };
        self.tree.leaves_met(&range, ranks, sets);
        true
    }
}
