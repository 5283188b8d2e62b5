//! The slice-wise structure (papers/004 sec. 3): each object cut into
//! axis-aligned slices along x, y and z, and, per view cell, the part of a
//! partially visible object that is hidden, as one slice index per axis.
//!
//! **Slices** (sec. 3.2). An object's box is cut into `n` slices of equal
//! width along each axis (one slice along an axis where the box is
//! flat). A triangle belongs to every slice its box overlaps (closed:
//! a triangle ending exactly on a boundary belongs to both sides), so
//! each triangle is in at least one slice of each axis (the paper's
//! "each triangle is encoded in at least three slices").
//!
//! **The index** (sec. 3.3, Fig. 5). Per axis a signed count: along x,
//! `+k` says the first `k` slices (from the low end) are hidden, `-k` the
//! last `k`, and `n` (either sign) all of them; the same along y; along z
//! (up), `k` says the lowest `k` slices are. The hidden part is the box
//! those slices make together, and a triangle is culled when all of its
//! slices on every axis are hidden, that is, when it lies in that box.
//! This is the paper's three visibility forms (Fig. 2): the lower part
//! hidden (x and y all, z some: horizontal), one side hidden top to bottom
//! (x or y some, z all: vertical), and one lower corner (L-shaped).
//!
//! **Finding it** (Algorithms 2 and 3, reworked). For each horizontal
//! axis and each of its ends, the hidden box grows along that axis one
//! slice at a time while the height of the highest hidden box only goes
//! down (a box inside a hidden box is hidden): a staircase of at most
//! `2n` box tests. Of the boxes found (the full-width lower part among
//! them), the one that culls the most triangles wins: the paper's
//! "maximally occluded axis" and "occlusion rectangle", chosen by what it
//! culls. Objects of many triangles (a terrain) are also searched for
//! hidden lower corners cut along both horizontal axes (the index has a
//! sign on both). The smallest box of each form is tried first: when none
//! is hidden, no larger box is, and the piece costs 4-8 box tests. The box
//! test is the caller's (a conservative oracle's box test), so the slices
//! are as conservative as the oracle.
//!
//! Deviations from the paper are in `notes/shrink.md` ("Slices").

use glam::DVec3;

#[cfg(feature = "builder")]
use crate::scene::Scene;

mod slices_file;
#[cfg(feature = "builder")]
mod slices_tree;

pub(crate) use slices_file::{decode as decode_section, encode as encode_section};
#[cfg(feature = "builder")]
pub use slices_tree::leaf_slices;

/// The most slices along an axis.
pub const MAX_SLICES: usize = 255;

/// The most slices along an axis a `.v5d` file stores: an index is then
/// one byte an axis (papers/004: "3 bytes, one for each axis").
pub const MAX_STORED_SLICES: usize = 127;

/// Per leaf of a tree, the objects it holds that have hidden slices, in
/// increasing order: the object and one index per piece of it.
pub type LeafSlices = Vec<(u32, Vec<SliceIndex>)>;

/// A tree's slices: the scene sliced and, per leaf in preorder, the hidden
/// slices of its objects (what a `.v5d` file of version 4 may hold).
#[derive(Clone, Debug, PartialEq)]
pub struct TreeSlices {
    /// The scene's pieces and slices.
    pub sliced: SlicedScene,
    /// Per leaf, in preorder.
    pub leaves: Vec<LeafSlices>,
}

impl TreeSlices {
    /// The heap bytes it holds (its vectors' capacities).
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        let leaves: usize = self
            .leaves
            .iter()
            .map(|row| {
                row.capacity() * size_of::<(u32, Vec<SliceIndex>)>()
                    + row
                        .iter()
                        .map(|(_, v)| v.capacity() * size_of::<SliceIndex>())
                        .sum::<usize>()
            })
            .sum();
        self.sliced.memory_bytes() + self.leaves.capacity() * size_of::<LeafSlices>() + leaves
    }

    /// The indices of object `object`'s pieces in leaf `leaf` (its
    /// preorder rank among the leaves), or `None` when nothing of it is
    /// hidden there.
    pub fn hidden(&self, leaf: usize, object: usize) -> Option<&[SliceIndex]> {
        let row = self.leaves.get(leaf)?;
        let k = row.binary_search_by_key(&(object as u32), |e| e.0).ok()?;
        Some(&row[k].1)
    }

    /// Whether object `object`'s triangle `t` is culled in leaf `leaf`.
    pub fn culled(&self, leaf: usize, object: usize, t: usize) -> bool {
        self.hidden(leaf, object).is_some_and(|indices| {
            self.sliced
                .culled_by(object, t, |p| indices.get(p).copied())
        })
    }
}

/// Why a scene cannot be sliced.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SliceError {
    /// The slice count is outside 1..=255.
    #[error("invalid slice count {0}: it must be in 1..={MAX_SLICES}")]
    Count(usize),
    /// An object's box is not finite.
    #[error("object {object} ({name}) cannot be sliced: its box is not finite")]
    Object {
        /// The object's index.
        object: usize,
        /// Its name.
        name: String,
    },
}

/// The hidden part of an object from a cell: a signed slice count per
/// axis (see the module's doc). [`SliceIndex::NONE`] hides nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SliceIndex {
    /// Along x: `+k` the first `k` slices, `-k` the last `k`.
    pub x: i16,
    /// Along y: `+k` the first `k` slices, `-k` the last `k`.
    pub y: i16,
    /// Along z: the lowest `z` slices.
    pub z: u8,
}

impl SliceIndex {
    /// Nothing hidden.
    pub const NONE: SliceIndex = SliceIndex { x: 0, y: 0, z: 0 };
}

/// The hidden slices of one kept object from one cell: per piece of the
/// object (see [`SlicedScene`]), in piece order, the index and the
/// triangles it culls ([`SliceIndex::NONE`] and 0 for a piece with
/// nothing hidden).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HiddenSlices {
    /// Per piece, the index and the triangles it culls.
    pub pieces: Vec<(SliceIndex, usize)>,
}

impl HiddenSlices {
    /// The triangles culled, over every piece.
    pub fn culled(&self) -> usize {
        self.pieces.iter().map(|&(_, n)| n).sum()
    }
}

/// Per object, of two oracles' answers (`Oracle::cell_slices`,
/// `ShrinkOracle::cell_slices`), piece by piece the hidden slices that
/// cull more: both are proved, so either will do. `into` empty takes
/// `other` whole.
pub fn keep_the_larger(into: &mut Vec<Option<HiddenSlices>>, other: Vec<Option<HiddenSlices>>) {
    if into.is_empty() {
        *into = other;
        return;
    }
    for (a, b) in into.iter_mut().zip(other) {
        match (a.as_mut(), b) {
            (_, None) => {}
            (None, b) => *a = b,
            (Some(a), Some(b)) => {
                for (x, y) in a.pieces.iter_mut().zip(b.pieces) {
                    if y.1 > x.1 {
                        *x = y;
                    }
                }
            }
        }
    }
}

/// One piece of an object, sliced (an object of few triangles is one
/// piece).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectSlices {
    /// The piece's box.
    pub min: DVec3,
    /// The piece's box.
    pub max: DVec3,
    /// Slices along x, y and z.
    pub counts: [usize; 3],
    /// The piece's triangles (indices into the object's), in increasing
    /// order; the piece's own triangle `t` is `triangles[t]`.
    pub triangles: Vec<u32>,
    /// Per triangle (in the piece's order), the lowest slice it overlaps
    /// along each axis.
    lo: Vec<[u8; 3]>,
    /// Per triangle, the highest.
    hi: Vec<[u8; 3]>,
}

impl ObjectSlices {
    /// The heap bytes it holds.
    fn memory_bytes(&self) -> usize {
        self.triangles.capacity() * 4 + (self.lo.capacity() + self.hi.capacity()) * 3
    }
}

/// Every object of a scene, cut into pieces and sliced.
///
/// **Pieces** (papers/004 sec. 6: "a subdivision at the object level
/// could be done to create smaller objects"). An object of more than
/// [`PIECE_TRIANGLES`] triangles (a terrain, a detailed building) is cut
/// on a grid across x and y into about one piece per [`PIECE_TRIANGLES`]
/// triangles, as square as its footprint allows and at most
/// [`MAX_PIECES_PER_AXIS`] along an axis; each triangle goes to the piece
/// its centroid lies in, and each piece (the box of its triangles) is
/// sliced and gets its own index. One index an object cannot say that
/// the parts of a terrain behind the blocks on both sides of a street are
/// hidden; one a piece can.
#[derive(Clone, Debug, PartialEq)]
pub struct SlicedScene {
    /// Slices an axis.
    slices: usize,
    /// Per object, its pieces.
    objects: Vec<Vec<ObjectSlices>>,
    /// Per object of more than one piece, per triangle, its piece and its
    /// index there; empty for one piece.
    place: Vec<Vec<(u32, u32)>>,
}

/// Objects of more than this many triangles are cut into pieces.
pub const PIECE_TRIANGLES: usize = 1024;

/// The most pieces along x or y.
pub const MAX_PIECES_PER_AXIS: usize = 16;

#[cfg(feature = "builder")]
impl SlicedScene {
    /// Cuts every object of `scene` into pieces (see the type) and each
    /// piece into `slices` slices along each axis (one along an axis
    /// where its box is flat).
    pub fn new(scene: &Scene, slices: usize) -> Result<Self, SliceError> {
        if !(1..=MAX_SLICES).contains(&slices) {
            return Err(SliceError::Count(slices));
        }
        let mut objects = Vec::with_capacity(scene.objects().len());
        let mut place = Vec::with_capacity(scene.objects().len());
        for o in 0..scene.objects().len() {
            let object = &scene.objects()[o];
            let tris = scene.object_triangles(o);
            let (min, max) = if tris.is_empty() {
                (DVec3::ZERO, DVec3::ZERO)
            } else {
                (object.bounds.min.as_dvec3(), object.bounds.max.as_dvec3())
            };
            if !(min.is_finite() && max.is_finite()) {
                return Err(SliceError::Object {
                    object: o,
                    name: object.name.clone(),
                });
            }
            let tris: Vec<[DVec3; 3]> = tris.iter().map(|t| t.map(|v| v.as_dvec3())).collect();
            let groups = piece_groups(&tris, min, max);
            if groups.len() == 1 {
                objects.push(vec![ObjectSlices::new(min, max, slices, &tris)]);
                place.push(Vec::new());
                continue;
            }
            let mut where_ = vec![(0u32, 0u32); tris.len()];
            let pieces = groups
                .iter()
                .enumerate()
                .map(|(p, group)| {
                    let own: Vec<[DVec3; 3]> = group.iter().map(|&t| tris[t as usize]).collect();
                    let lo = own.iter().flatten().fold(DVec3::INFINITY, |a, &v| a.min(v));
                    let hi = own
                        .iter()
                        .flatten()
                        .fold(DVec3::NEG_INFINITY, |a, &v| a.max(v));
                    for (k, &t) in group.iter().enumerate() {
                        where_[t as usize] = (p as u32, k as u32);
                    }
                    let mut piece = ObjectSlices::new(lo, hi, slices, &own);
                    piece.triangles = group.clone();
                    piece
                })
                .collect();
            objects.push(pieces);
            place.push(where_);
        }
        Ok(Self {
            slices,
            objects,
            place,
        })
    }
}

impl SlicedScene {
    /// Slices an axis.
    pub fn slices(&self) -> usize {
        self.slices
    }

    /// The heap bytes it holds (its vectors' capacities).
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        let pieces: usize = self
            .objects
            .iter()
            .map(|o| {
                o.capacity() * size_of::<ObjectSlices>()
                    + o.iter().map(ObjectSlices::memory_bytes).sum::<usize>()
            })
            .sum();
        let place: usize = self
            .place
            .iter()
            .map(|p| p.capacity() * size_of::<(u32, u32)>())
            .sum();
        pieces + place + (self.objects.capacity() + self.place.capacity()) * size_of::<Vec<()>>()
    }

    /// Object `i`'s pieces (one for most objects).
    pub fn pieces(&self, i: usize) -> &[ObjectSlices] {
        &self.objects[i]
    }

    /// Object `i`'s triangle `t` (below its triangle count): its piece and
    /// its index there.
    pub fn place(&self, i: usize, t: usize) -> (usize, usize) {
        if self.objects[i].len() == 1 {
            return (0, t);
        }
        let (p, k) = self.place[i][t];
        (p as usize, k as usize)
    }

    /// The hidden slices of object `i`, piece by piece
    /// ([`ObjectSlices::best_index`]); `None` when no piece has any.
    pub fn hidden_slices(
        &self,
        i: usize,
        hidden: &mut dyn FnMut(DVec3, DVec3) -> bool,
    ) -> Option<HiddenSlices> {
        let pieces: Vec<(SliceIndex, usize)> = self.objects[i]
            .iter()
            .map(|p| p.best_index(hidden).unwrap_or((SliceIndex::NONE, 0)))
            .collect();
        pieces
            .iter()
            .any(|&(_, n)| n > 0)
            .then_some(HiddenSlices { pieces })
    }

    /// Whether object `i`'s triangle `t` (in the object's order) is culled
    /// by `hidden`.
    pub fn culled(&self, i: usize, t: usize, hidden: &HiddenSlices) -> bool {
        self.culled_by(i, t, |p| hidden.pieces.get(p).map(|&(index, _)| index))
    }

    /// Whether object `i`'s triangle `t` is culled by the index
    /// `index_of(piece)` gives its piece (none: not culled).
    pub fn culled_by(
        &self,
        i: usize,
        t: usize,
        index_of: impl Fn(usize) -> Option<SliceIndex>,
    ) -> bool {
        let (p, k) = self.place(i, t);
        index_of(p).is_some_and(|index| self.objects[i][p].culled(k, index))
    }

    /// The number of object `i`'s triangles `hidden` culls.
    pub fn culled_count(&self, i: usize, hidden: &HiddenSlices) -> usize {
        self.objects[i]
            .iter()
            .zip(&hidden.pieces)
            .map(|(p, &(index, _))| p.culled_count(index))
            .sum()
    }
}

/// The pieces of an object's triangles (in its box `[min, max]`): one
/// group of every triangle for an object of at most [`PIECE_TRIANGLES`],
/// else the non-empty cells of a grid across x and y, each the triangles
/// whose centroid lies in it, in increasing order.
#[cfg(feature = "builder")]
fn piece_groups(tris: &[[DVec3; 3]], min: DVec3, max: DVec3) -> Vec<Vec<u32>> {
    let all = || vec![(0..tris.len() as u32).collect::<Vec<u32>>()];
    if tris.len() <= PIECE_TRIANGLES {
        return all();
    }
    let want = tris.len().div_ceil(PIECE_TRIANGLES) as f64;
    let (ex, ey) = (max.x - min.x, max.y - min.y);
    let cap = MAX_PIECES_PER_AXIS as f64;
    // kx / ky = ex / ey and kx ky = want, each in 1..=cap.
    let (kx, ky) = if ex <= 0.0 || ey <= 0.0 {
        let k = want.min(cap).max(1.0);
        if ex > 0.0 {
            (k, 1.0)
        } else if ey > 0.0 {
            (1.0, k)
        } else {
            (1.0, 1.0)
        }
    } else {
        let kx = (want * ex / ey).sqrt().round().clamp(1.0, cap);
        let ky = (want / kx).round().clamp(1.0, cap);
        (kx, ky)
    };
    let (kx, ky) = (kx as usize, ky as usize);
    if kx * ky == 1 {
        return all();
    }
    let cell = |v: f64, lo: f64, e: f64, k: usize| -> usize {
        if e > 0.0 {
            (((v - lo) / e * k as f64).floor().max(0.0) as usize).min(k - 1)
        } else {
            0
        }
    };
    let mut groups = vec![Vec::new(); kx * ky];
    for (t, tri) in tris.iter().enumerate() {
        let c = (tri[0] + tri[1] + tri[2]) / 3.0;
        let (i, j) = (cell(c.x, min.x, ex, kx), cell(c.y, min.y, ey, ky));
        groups[j * kx + i].push(t as u32);
    }
    groups.retain(|g| !g.is_empty());
    groups
}

impl ObjectSlices {
    /// The slices of the triangles `tris` in the box `[min, max]`, `n`
    /// along each axis where the box has an extent (one piece of all of
    /// an object's triangles).
    pub fn new(min: DVec3, max: DVec3, n: usize, tris: &[[DVec3; 3]]) -> Self {
        let counts = [0, 1, 2].map(|a| if max[a] > min[a] { n } else { 1 });
        let slice = |a: usize, v: f64| -> u8 {
            let w = (max[a] - min[a]) / counts[a] as f64;
            if w > 0.0 {
                ((v - min[a]) / w)
                    .floor()
                    .clamp(0.0, counts[a] as f64 - 1.0) as u8
            } else {
                0
            }
        };
        let mut lo = Vec::with_capacity(tris.len());
        let mut hi = Vec::with_capacity(tris.len());
        for t in tris {
            let (a, b) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            lo.push([0, 1, 2].map(|k| slice(k, a[k])));
            hi.push([0, 1, 2].map(|k| slice(k, b[k])));
        }
        Self {
            min,
            max,
            counts,
            triangles: (0..tris.len() as u32).collect(),
            lo,
            hi,
        }
    }

    /// The triangles (indices into the object's) that overlap slice `i`
    /// along `axis` (the paper's "slice triangle pointer list", Fig. 4).
    pub fn slice_triangles(&self, axis: usize, i: usize) -> Vec<u32> {
        (0..self.lo.len())
            .filter(|&t| usize::from(self.lo[t][axis]) <= i && i <= usize::from(self.hi[t][axis]))
            .map(|t| self.triangles[t])
            .collect()
    }

    /// The slice range `[from, to)` an index hides along `axis`.
    fn range(&self, index: SliceIndex, axis: usize) -> (usize, usize) {
        let n = self.counts[axis];
        match axis {
            0 | 1 => {
                let k = if axis == 0 { index.x } else { index.y };
                let m = usize::from(k.unsigned_abs()).min(n);
                if k >= 0 { (0, m) } else { (n - m, n) }
            }
            _ => (0, usize::from(index.z).min(n)),
        }
    }

    /// The box an index hides (empty when it hides nothing).
    pub fn hidden_box(&self, index: SliceIndex) -> Option<(DVec3, DVec3)> {
        let mut a = self.min;
        let mut b = self.max;
        for axis in 0..3 {
            let (from, to) = self.range(index, axis);
            if from >= to {
                return None;
            }
            let w = (self.max[axis] - self.min[axis]) / self.counts[axis] as f64;
            a[axis] = self.min[axis] + w * from as f64;
            b[axis] = if to == self.counts[axis] {
                self.max[axis]
            } else {
                self.min[axis] + w * to as f64
            };
        }
        Some((a, b))
    }

    /// Whether the piece's triangle `t` is culled by `index` (it lies in
    /// the hidden box).
    pub fn culled(&self, t: usize, index: SliceIndex) -> bool {
        (0..3).all(|axis| {
            let (from, to) = self.range(index, axis);
            usize::from(self.lo[t][axis]) >= from && usize::from(self.hi[t][axis]) < to
        })
    }

    /// The number of triangles `index` culls.
    pub fn culled_count(&self, index: SliceIndex) -> usize {
        (0..self.lo.len())
            .filter(|&t| self.culled(t, index))
            .count()
    }

    /// The index that culls the most triangles among those the staircase
    /// search finds, with the count; `hidden(a, b)` must say whether the
    /// box `[a, b]` is hidden from the cell (conservatively). `None` when
    /// no slice box is hidden.
    pub fn best_index(
        &self,
        hidden: &mut dyn FnMut(DVec3, DVec3) -> bool,
    ) -> Option<(SliceIndex, usize)> {
        let [nx, ny, nz] = self.counts;
        // The smallest box of each form first: every box the searches
        // below try holds one of them, so when none is hidden (a box
        // inside a hidden box is hidden) nothing is, and a piece in view
        // costs 4-8 box tests instead of hundreds.
        let corners = self.lo.len() >= CORNER_SEARCH_TRIANGLES && nx > 1 && ny > 1;
        let (fx, fy) = (nx as i16, ny as i16);
        let mut smallest = vec![
            SliceIndex { x: 1, y: fy, z: 1 },
            SliceIndex { x: -1, y: fy, z: 1 },
            SliceIndex { x: fx, y: 1, z: 1 },
            SliceIndex { x: fx, y: -1, z: 1 },
        ];
        if corners {
            for (x, y) in [(1, 1), (1, -1), (-1, 1), (-1, -1)] {
                smallest.push(SliceIndex { x, y, z: 1 });
            }
        }
        if !smallest
            .into_iter()
            .any(|index| self.hidden_box(index).is_some_and(|(a, b)| hidden(a, b)))
        {
            return None;
        }
        // Counts of triangles by (slices hidden along the axis from one
        // end, slices hidden from the bottom): cumulative tables.
        let table = |axis: usize, from_low: bool| -> Vec<u32> {
            let n = self.counts[axis];
            let mut t = vec![0u32; (n + 1) * (nz + 1)];
            for k in 0..self.lo.len() {
                // Slices needed from this end to cover the triangle.
                let need = if from_low {
                    usize::from(self.hi[k][axis]) + 1
                } else {
                    n - usize::from(self.lo[k][axis])
                };
                let up = usize::from(self.hi[k][2]) + 1;
                t[need * (nz + 1) + up] += 1;
            }
            // Prefix sums over both.
            for i in 0..=n {
                for j in 0..=nz {
                    let mut v = t[i * (nz + 1) + j];
                    if i > 0 {
                        v += t[(i - 1) * (nz + 1) + j];
                    }
                    if j > 0 {
                        v += t[i * (nz + 1) + j - 1];
                    }
                    if i > 0 && j > 0 {
                        v -= t[(i - 1) * (nz + 1) + j - 1];
                    }
                    t[i * (nz + 1) + j] = v;
                }
            }
            t
        };
        let mut best: Option<(SliceIndex, usize)> = None;
        for (axis, n) in [(0usize, nx), (1, ny)] {
            for from_low in [true, false] {
                let counts = table(axis, from_low);
                let mut k = nz;
                for i in 1..=n {
                    let index = |i: usize, k: usize| {
                        let s = if from_low { i as i16 } else { -(i as i16) };
                        let full = [nx as i16, ny as i16];
                        let (x, y) = if axis == 0 {
                            (s, full[1])
                        } else {
                            (full[0], s)
                        };
                        SliceIndex { x, y, z: k as u8 }
                    };
                    while k > 0 {
                        let (a, b) = self.hidden_box(index(i, k)).expect("a box");
                        if hidden(a, b) {
                            break;
                        }
                        k -= 1;
                    }
                    if k == 0 {
                        break;
                    }
                    let culled = counts[i * (nz + 1) + k] as usize;
                    if culled > 0 && best.is_none_or(|(_, c)| culled > c) {
                        best = Some((index(i, k), culled));
                    }
                }
            }
        }
        // Objects of many triangles (terrains, big meshes): lower corners
        // cut along both horizontal axes too, each as a staircase in the
        // second axis with the height found by bisection.
        if corners {
            for (low_x, low_y) in [(true, true), (true, false), (false, true), (false, false)] {
                let index = |i: usize, j: usize, k: usize| SliceIndex {
                    x: if low_x { i as i16 } else { -(i as i16) },
                    y: if low_y { j as i16 } else { -(j as i16) },
                    z: k as u8,
                };
                let mut j_max = ny;
                for i in 1..nx {
                    let mut j = j_max;
                    // The tallest hidden box of width (i, j), by bisection.
                    let height = |j: usize, hidden: &mut dyn FnMut(DVec3, DVec3) -> bool| {
                        let (mut lo, mut hi) = (0usize, nz);
                        while lo < hi {
                            let mid = (lo + hi).div_ceil(2);
                            let (a, b) = self.hidden_box(index(i, j, mid)).expect("a box");
                            if hidden(a, b) {
                                lo = mid;
                            } else {
                                hi = mid - 1;
                            }
                        }
                        lo
                    };
                    let mut k = 0;
                    while j > 0 {
                        k = height(j, hidden);
                        if k > 0 {
                            break;
                        }
                        j -= 1;
                    }
                    if j == 0 {
                        break;
                    }
                    j_max = j;
                    let culled = self.culled_count(index(i, j, k));
                    if culled > 0 && best.is_none_or(|(_, c)| culled > c) {
                        best = Some((index(i, j, k), culled));
                    }
                }
            }
        }
        best
    }
}

/// Objects of at least this many triangles are also searched for hidden
/// lower corners cut along both horizontal axes.
pub const CORNER_SEARCH_TRIANGLES: usize = 256;

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_object() -> (ObjectSlices, Vec<[DVec3; 3]>) {
        // A 4 x 4 x 4 box of small triangles, one in each unit cube.
        let mut tris = Vec::new();
        for x in 0..4 {
            for y in 0..4 {
                for z in 0..4 {
                    let o = DVec3::new(x as f64, y as f64, z as f64) + 0.25;
                    tris.push([o, o + DVec3::X * 0.5, o + DVec3::Y * 0.5 + DVec3::Z * 0.5]);
                }
            }
        }
        (
            ObjectSlices::new(DVec3::ZERO, DVec3::splat(4.0), 4, &tris),
            tris,
        )
    }

    #[test]
    fn triangles_belong_to_every_slice_they_overlap() {
        let tris = vec![
            [
                DVec3::ZERO,
                DVec3::new(2.0, 0.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            [
                DVec3::new(3.5, 3.5, 3.5),
                DVec3::splat(4.0),
                DVec3::new(4.0, 3.5, 4.0),
            ],
        ];
        let s = ObjectSlices::new(DVec3::ZERO, DVec3::splat(4.0), 4, &tris);
        // The first spans x slices 0..=2 (it ends on the boundary of 2).
        assert_eq!(s.slice_triangles(0, 2), vec![0]);
        assert_eq!(s.slice_triangles(0, 3), vec![1]);
        assert_eq!(s.slice_triangles(1, 1), vec![0]);
        assert_eq!(s.slice_triangles(2, 0), vec![0]);
        // A flat box has one slice along its flat axis.
        let flat = ObjectSlices::new(DVec3::ZERO, DVec3::new(4.0, 4.0, 0.0), 8, &tris[..1]);
        assert_eq!(flat.counts, [8, 8, 1]);
    }

    #[test]
    fn an_index_culls_exactly_the_triangles_in_its_box() {
        let (s, tris) = grid_object();
        for index in [
            SliceIndex { x: 2, y: 4, z: 1 },
            SliceIndex { x: -1, y: 4, z: 4 },
            SliceIndex { x: 4, y: -3, z: 2 },
            SliceIndex::NONE,
        ] {
            let boxed = s.hidden_box(index);
            for (t, tri) in tris.iter().enumerate() {
                let inside = boxed.is_some_and(|(a, b)| {
                    tri.iter()
                        .all(|p| (0..3).all(|k| p[k] >= a[k] && p[k] <= b[k]))
                });
                assert_eq!(s.culled(t, index), inside, "{index:?} {t}");
            }
        }
        assert_eq!(s.culled_count(SliceIndex { x: 2, y: 4, z: 1 }), 8);
    }

    #[test]
    fn the_search_finds_the_lower_corner_an_occluder_hides() {
        let (s, _) = grid_object();
        // Hidden: whatever lies in x < 3, z < 2 (an occluder on the low x
        // side, two units tall).
        let mut tests = 0;
        let mut hidden = |a: DVec3, b: DVec3| {
            tests += 1;
            let _ = a;
            b.x <= 3.0 && b.z <= 2.0
        };
        let (index, culled) = s.best_index(&mut hidden).expect("something hidden");
        assert_eq!(index, SliceIndex { x: 3, y: 4, z: 2 });
        assert_eq!(culled, 3 * 4 * 2);
        assert!(tests <= 4 * (4 + 4), "{tests} box tests");
        // Nothing hidden: no index, after the 4 smallest boxes.
        let mut tests = 0;
        assert!(
            s.best_index(&mut |_, _| {
                tests += 1;
                false
            })
            .is_none()
        );
        assert_eq!(tests, 4);
        // All hidden: the whole box (counted once).
        let (index, culled) = s.best_index(&mut |_, _| true).unwrap();
        assert_eq!(culled, 64, "{index:?}");
    }

    #[test]
    fn big_objects_are_searched_for_corners_cut_both_ways() {
        // 8 x 8 x 4 small triangles (256): an occluder hides x < 2, y > 5
        // (the high y end), z < 3.
        let mut tris = Vec::new();
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..4 {
                    let o = DVec3::new(x as f64, y as f64, z as f64) + 0.25;
                    tris.push([o, o + DVec3::X * 0.5, o + DVec3::Y * 0.5 + DVec3::Z * 0.5]);
                }
            }
        }
        let s = ObjectSlices::new(DVec3::ZERO, DVec3::new(8.0, 8.0, 4.0), 8, &tris);
        // Slices are 1 wide along x and y, 0.5 along z.
        let mut hidden = |a: DVec3, b: DVec3| b.x <= 2.0 && a.y >= 5.0 && b.z <= 3.0;
        let (index, culled) = s.best_index(&mut hidden).expect("a corner");
        assert_eq!(index, SliceIndex { x: 2, y: -3, z: 6 });
        assert_eq!(culled, 2 * 3 * 3);
        // In view: 8 smallest boxes (4 corners too) and no more.
        let mut tests = 0;
        let none = s.best_index(&mut |_, _| {
            tests += 1;
            false
        });
        assert!(none.is_none());
        assert_eq!(tests, 8);
    }

    /// A flat terrain of `nx` x `ny` unit squares (two triangles each).
    #[cfg(feature = "builder")]
    fn terrain(nx: usize, ny: usize) -> Vec<[DVec3; 3]> {
        let mut tris = Vec::new();
        for i in 0..nx {
            for j in 0..ny {
                let p =
                    |x: usize, y: usize| DVec3::new(x as f64, y as f64, ((x + y) % 3) as f64 * 0.1);
                tris.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
                tris.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
            }
        }
        tris
    }

    #[test]
    #[cfg(feature = "builder")]
    fn big_objects_are_cut_into_pieces_across_their_footprint() {
        // 64 x 32 squares: 4,096 triangles, 4 pieces wanted, twice as
        // long as wide: round(sqrt(4 x 2)) = 3 along x, round(4 / 3) = 1
        // along y.
        let tris = terrain(64, 32);
        let (min, max) = (DVec3::ZERO, DVec3::new(64.0, 32.0, 0.2));
        let groups = piece_groups(&tris, min, max);
        assert_eq!(groups.len(), 3, "{}", groups.len());
        // Every triangle in exactly one piece, in order.
        let mut all: Vec<u32> = groups.concat();
        assert!(groups.iter().all(|g| g.windows(2).all(|w| w[0] < w[1])));
        all.sort_unstable();
        assert_eq!(all, (0..tris.len() as u32).collect::<Vec<_>>());
        // Small objects stay whole, and the grid never passes its cap.
        assert_eq!(piece_groups(&tris[..PIECE_TRIANGLES], min, max).len(), 1);
        let huge = terrain(512, 256);
        let groups = piece_groups(&huge, min, DVec3::new(512.0, 256.0, 0.2));
        assert!(groups.len() <= MAX_PIECES_PER_AXIS * MAX_PIECES_PER_AXIS);
        // (256 wanted: 23 x 11 by the footprint, 16 x 16 by the cap.)
        assert_eq!(groups.len(), MAX_PIECES_PER_AXIS * MAX_PIECES_PER_AXIS);
    }

    #[test]
    #[cfg(feature = "builder")]
    fn pieces_hide_what_one_index_cannot() {
        // A terrain of 96 x 32 squares (6,144 triangles: 6 pieces wanted,
        // 4 x 2 by its footprint); an occluder hides both ends (x < 24 and
        // x > 72), which one box of slices cannot say.
        let tris = terrain(96, 32);
        let (min, max) = (DVec3::ZERO, DVec3::new(96.0, 32.0, 0.2));
        let scene_pieces = piece_groups(&tris, min, max);
        assert!(scene_pieces.len() >= 4, "{}", scene_pieces.len());
        let sliced = SlicedScene {
            slices: 8,
            objects: vec![
                scene_pieces
                    .iter()
                    .map(|g| {
                        let own: Vec<[DVec3; 3]> = g.iter().map(|&t| tris[t as usize]).collect();
                        let lo = own.iter().flatten().fold(DVec3::INFINITY, |a, &v| a.min(v));
                        let hi = own
                            .iter()
                            .flatten()
                            .fold(DVec3::NEG_INFINITY, |a, &v| a.max(v));
                        let mut p = ObjectSlices::new(lo, hi, 8, &own);
                        p.triangles = g.clone();
                        p
                    })
                    .collect(),
            ],
            place: vec![{
                let mut w = vec![(0, 0); tris.len()];
                for (p, g) in scene_pieces.iter().enumerate() {
                    for (k, &t) in g.iter().enumerate() {
                        w[t as usize] = (p as u32, k as u32);
                    }
                }
                w
            }],
        };
        let mut hidden = |a: DVec3, b: DVec3| b.x <= 24.0 || a.x >= 72.0;
        let h = sliced.hidden_slices(0, &mut hidden).expect("ends hidden");
        assert_eq!(h.pieces.len(), scene_pieces.len());
        assert_eq!(h.culled(), sliced.culled_count(0, &h));
        // Culled: exactly triangles inside x <= 24 or x >= 72, as far as
        // the pieces' slices resolve them; never one between.
        let mut culled = 0;
        for (t, tri) in tris.iter().enumerate() {
            if sliced.culled(0, t, &h) {
                culled += 1;
                let (a, b) = (
                    tri[0].min(tri[1]).min(tri[2]),
                    tri[0].max(tri[1]).max(tri[2]),
                );
                assert!(b.x <= 24.0 || a.x >= 72.0, "triangle {t} culled: {a} {b}");
            }
        }
        assert_eq!(culled, h.culled());
        // Both ends: more than one index (one object-wide box) could cull.
        let whole = ObjectSlices::new(min, max, 8, &tris);
        let (_, one) = whole.best_index(&mut hidden).expect("one end");
        assert!(culled > one, "{culled} vs {one}");
        // The larger of two answers, piece by piece.
        let mut a = vec![Some(h.clone()), None];
        let mut other = h.clone();
        other.pieces[0] = (SliceIndex::NONE, 0);
        let last = other.pieces.len() - 1;
        other.pieces[last].1 += 1;
        keep_the_larger(&mut a, vec![Some(other), Some(h.clone())]);
        let merged = a[0].as_ref().unwrap();
        assert_eq!(merged.pieces[0], h.pieces[0]);
        assert_eq!(merged.pieces[last].1, h.pieces[last].1 + 1);
        assert_eq!(a[1].as_ref(), Some(&h));
    }

    #[test]
    #[cfg(feature = "builder")]
    fn bad_counts_are_refused() {
        let scene = crate::scene::procedural::generate(
            crate::scene::procedural::SceneKind::Apartment,
            1,
            1,
        );
        assert_eq!(
            SlicedScene::new(&scene, 0).unwrap_err(),
            SliceError::Count(0)
        );
        assert_eq!(
            SlicedScene::new(&scene, 256).unwrap_err(),
            SliceError::Count(256)
        );
        let sliced = SlicedScene::new(&scene, 16).unwrap();
        assert!(
            sliced.pieces(0)[0]
                .counts
                .iter()
                .filter(|c| **c == 16)
                .count()
                >= 2
        );
    }
}
