//! Object bounds in a `.v5d` file (version 2): each object's bounding box
//! quantised to 16 bits per coordinate on a grid over the union of the
//! boxes, rounded outwards, so that a query can cull its answer to a view's
//! frustum without the scene (notes/format.md, "Object bounds").
//!
//! Outwards means exactly that: the decoded box holds the object's box, bit
//! for bit in f32, whatever the rounding of the grid arithmetic (the
//! quantiser steps a code out until its decoded value does).

use glam::Vec3;

use crate::geom::Aabb;

/// The largest code: a coordinate at the grid's high side.
const TOP: u16 = u16::MAX;

/// The codes of an object whose bounds are not known (a file rewritten
/// from version 1): low codes at the top, high codes at the bottom, an
/// inverted box no real bounds quantise to.
pub const UNKNOWN: [u16; 6] = [TOP, TOP, TOP, 0, 0, 0];

/// The grid the bounds are quantised on: a box, each axis cut into
/// 65,535 steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundsGrid {
    /// The box the codes span (the union of the objects' boxes).
    pub space: Aabb,
}

impl BoundsGrid {
    /// The grid over the union of `boxes` (the zero box when there are
    /// none, or only empty ones).
    pub fn over<'a>(boxes: impl IntoIterator<Item = &'a Aabb>) -> Self {
        let space = boxes.into_iter().fold(Aabb::EMPTY, |u, b| u.union(b));
        Self {
            space: if space.is_empty() {
                Aabb::new(Vec3::ZERO, Vec3::ZERO)
            } else {
                space
            },
        }
    }

    /// Whether the grid's box is one (finite corners, low <= high).
    pub fn is_valid(&self) -> bool {
        let s = &self.space;
        s.min.is_finite() && s.max.is_finite() && s.min.cmple(s.max).all()
    }

    /// The f32 value of `code` on `axis`, rounded down (`up` false) or up:
    /// the grid's sides exactly at codes 0 and 65,535.
    fn value(&self, axis: usize, code: u16, up: bool) -> f32 {
        let (lo, hi) = (self.space.min[axis], self.space.max[axis]);
        match code {
            0 => lo,
            TOP => hi,
            _ => {
                let exact = f64::from(lo)
                    + (f64::from(hi) - f64::from(lo)) * f64::from(code) / f64::from(TOP);
                let v = exact as f32;
                if up && f64::from(v) < exact {
                    v.next_up()
                } else if !up && f64::from(v) > exact {
                    v.next_down()
                } else {
                    v
                }
            }
        }
        .clamp(lo, hi)
    }

    /// The codes of `b` (a box inside the grid's), rounded outwards;
    /// [`UNKNOWN`] for `None` and for an empty box (an object of no
    /// triangles has none).
    pub fn quantise(&self, b: Option<&Aabb>) -> [u16; 6] {
        let Some(b) = b.filter(|b| !b.is_empty()) else {
            return UNKNOWN;
        };
        let mut q = [0u16; 6];
        for axis in 0..3 {
            let (lo, hi) = (self.space.min[axis], self.space.max[axis]);
            let span = f64::from(hi) - f64::from(lo);
            let at = |x: f32| (f64::from(x) - f64::from(lo)) / span * f64::from(TOP);
            // The largest code whose value is at most the minimum, and the
            // smallest whose value is at least the maximum: outwards, and
            // the same codes again for a decoded box (so a file read and
            // written again keeps its bytes).
            if span == 0.0 {
                // A flat grid: every code decodes to its one value.
                q[axis] = 0;
                q[3 + axis] = TOP;
                continue;
            }
            let mut low = at(b.min[axis]).floor().clamp(0.0, f64::from(TOP)) as u16;
            while low > 0 && self.value(axis, low, false) > b.min[axis] {
                low -= 1;
            }
            while low < TOP && self.value(axis, low + 1, false) <= b.min[axis] {
                low += 1;
            }
            let mut high = at(b.max[axis]).ceil().clamp(0.0, f64::from(TOP)) as u16;
            while high < TOP && self.value(axis, high, true) < b.max[axis] {
                high += 1;
            }
            while high > 0 && self.value(axis, high - 1, true) >= b.max[axis] {
                high -= 1;
            }
            // Where the grid's steps are finer than f32 there, several codes
            // decode to one value and a flat box's codes can cross: the low
            // code's value rounded up holds the maximum too (it is at least
            // the high code's, which does).
            q[axis] = low;
            q[3 + axis] = high.max(low);
        }
        q
    }

    /// The box of codes `q`: `None` for [`UNKNOWN`], an error for any
    /// other inverted box.
    pub fn dequantise(&self, q: [u16; 6]) -> Result<Option<Aabb>, String> {
        if q == UNKNOWN {
            return Ok(None);
        }
        if (0..3).any(|k| q[k] > q[3 + k]) {
            return Err(format!("the bounds codes {q:?} are not a box"));
        }
        let corner = |base: usize, up: bool| {
            Vec3::new(
                self.value(0, q[base], up),
                self.value(1, q[base + 1], up),
                self.value(2, q[base + 2], up),
            )
        };
        Ok(Some(Aabb::new(corner(0, false), corner(3, true))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    #[test]
    fn decoded_bounds_hold_the_objects_bounds() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        for scale in [1e-6f32, 1.0, 3e3, 1e9] {
            let boxes: Vec<Aabb> = (0..500)
                .map(|_| {
                    let p = Vec3::new(rng.random(), rng.random(), rng.random()) * scale
                        - Vec3::splat(0.3 * scale);
                    let s = Vec3::new(rng.random(), rng.random(), rng.random())
                        * scale
                        * rng.random::<f32>().powi(4);
                    Aabb::new(p, p + s)
                })
                .collect();
            let grid = BoundsGrid::over(&boxes);
            for b in &boxes {
                let q = grid.quantise(Some(b));
                let d = grid.dequantise(q).unwrap().unwrap();
                // A decoded box codes to the same codes.
                assert_eq!(grid.quantise(Some(&d)), q);
                assert!(
                    d.min.cmple(b.min).all() && d.max.cmpge(b.max).all(),
                    "{b:?} {d:?}"
                );
                // Tight: within two steps of the grid.
                let step = grid.space.size() / f32::from(TOP);
                assert!(
                    ((b.min - d.min) - 2.0 * step).max_element() <= 0.0,
                    "{b:?} {d:?}"
                );
                assert!(
                    ((d.max - b.max) - 2.0 * step).max_element() <= 0.0,
                    "{b:?} {d:?}"
                );
            }
        }
    }

    #[test]
    fn flat_grids_unknown_bounds_and_inverted_codes() {
        // A floor plan: the grid is flat in z.
        let boxes = [
            Aabb::new(Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 1.0, 2.0)),
            Aabb::new(Vec3::new(3.0, 1.0, 2.0), Vec3::new(4.0, 5.0, 2.0)),
        ];
        let grid = BoundsGrid::over(&boxes);
        for b in &boxes {
            let d = grid.dequantise(grid.quantise(Some(b))).unwrap().unwrap();
            assert!(
                d.min.cmple(b.min).all() && d.max.cmpge(b.max).all(),
                "{b:?} {d:?}"
            );
            assert_eq!((d.min.z, d.max.z), (2.0, 2.0));
        }
        assert_eq!(grid.quantise(None), UNKNOWN);
        // A grid thinner than 65,535 f32 steps (a site plan at z = 50 with
        // a 5 cm kerb): flat boxes on it used to get crossed codes, which
        // the reader refuses.
        let boxes = [
            Aabb::new(Vec3::new(0.0, 0.0, 50.0), Vec3::new(40.0, 40.0, 50.0)),
            Aabb::new(Vec3::new(0.0, 0.0, 50.05), Vec3::new(40.0, 1.0, 50.05)),
        ];
        let grid = BoundsGrid::over(&boxes);
        for b in &boxes {
            let q = grid.quantise(Some(b));
            let d = grid.dequantise(q).unwrap().unwrap();
            assert!(
                d.min.cmple(b.min).all() && d.max.cmpge(b.max).all(),
                "{b:?} {d:?}"
            );
            assert_eq!(grid.quantise(Some(&d)), q);
        }
        assert_eq!(grid.dequantise(UNKNOWN).unwrap(), None);
        assert!(grid.dequantise([5, 0, 0, 4, 9, 9]).is_err());
        assert!(BoundsGrid::over(&[]).is_valid());
    }
}
