//! Viewpoints inside closed convex solids.
//!
//! A view cell often reaches into a building or a wall: a k-d cell of the
//! bake, a street cell beside a block. A viewpoint strictly inside a
//! closed solid sees nothing but the solid's inside and whatever lies
//! within it: every ray from it leaves the solid through its surface,
//! which the (two-sided, watertight) tracer hits. So the part of a cell
//! inside a solid needs no projection: the oracle runs on the rest, and
//! keeps the solid and every object whose box meets the solid's box.
//!
//! Only whole slabs are cut off (the cell stays a box): for each closed
//! convex solid whose box overlaps the cell, each side of the cell, the
//! thickest slab along that side lying inside the solid by more than a
//! margin (the tracer's rounding slack plus the solid's convexity
//! tolerance), found exactly from the solid's face planes. A cell wholly
//! inside a solid sees only what is within the solid.

use glam::DVec3;

use super::oracle_occluders::Occluder;

/// What [`reduce`] found.
#[derive(Clone, Debug, PartialEq)]
pub enum Reduced {
    /// The cell, with every slab that lies inside a solid cut off, and the
    /// solids (indices into the occluders) that cut it (none: the cell as
    /// it was).
    Cell {
        /// The smaller cell's lower corner.
        min: DVec3,
        /// The smaller cell's upper corner.
        max: DVec3,
        /// The solids that cut slabs off.
        solids: Vec<usize>,
    },
    /// The whole cell lies inside this solid.
    Inside(usize),
}

/// The largest `n . p` over the cell's face at `axis == value`, the other
/// axes spanning the cell.
fn face_max(n: DVec3, cmin: DVec3, cmax: DVec3, axis: usize, value: f64) -> f64 {
    (0..3)
        .map(|b| {
            if b == axis {
                n[b] * value
            } else {
                (n[b] * cmin[b]).max(n[b] * cmax[b])
            }
        })
        .sum()
}

/// How far the slab of the cell from `axis == far` towards the cell's
/// other side can reach while lying inside the solid by `margin`: the
/// smallest (for the upper side, `upper`) or largest coordinate `c` such
/// that the slab between `c` and `far` is inside; `None` when not even
/// the face at `far` is.
fn slab_reach(
    planes: &[(DVec3, f64)],
    cmin: DVec3,
    cmax: DVec3,
    axis: usize,
    upper: bool,
    margin: f64,
) -> Option<f64> {
    let far = if upper { cmax[axis] } else { cmin[axis] };
    let mut reach = if upper { cmin[axis] } else { cmax[axis] };
    for &(n, d) in planes {
        let limit = d - margin;
        if face_max(n, cmin, cmax, axis, far) > limit {
            return None;
        }
        // The rest of the face's corners but the cut axis.
        let rest = face_max(n, cmin, cmax, axis, 0.0);
        let na = n[axis];
        // n_a c + rest <= limit, binding only where c moves outwards.
        if upper && na < 0.0 {
            reach = reach.max((limit - rest) / na);
        } else if !upper && na > 0.0 {
            reach = reach.min((limit - rest) / na);
        }
    }
    // Rounding: the slab's near face must itself be inside, moved a
    // thousandth of the margin towards `far` (a thinner slab) unless it
    // is the cell's own face.
    let near = if upper { cmin[axis] } else { cmax[axis] };
    if reach != near {
        reach += if upper { 1e-3 } else { -1e-3 } * margin;
    }
    let inside = planes
        .iter()
        .all(|&(n, d)| face_max(n, cmin, cmax, axis, reach) <= d - margin);
    inside.then_some(reach)
}

/// Cuts off the slabs of the cell `[cmin, cmax]` that lie inside closed
/// convex solids (by more than `slack` plus each solid's tolerance), until
/// none is left; `skip` names solids not to use (their objects proved
/// hidden from a parent cell hold no viewpoint of it, so this never
/// matters for soundness; it keeps the parent's proof intact).
pub fn reduce(
    occluders: &[Occluder],
    cmin: DVec3,
    cmax: DVec3,
    slack: f64,
    skip: &dyn Fn(&Occluder) -> bool,
) -> Reduced {
    let (mut lo, mut hi) = (cmin, cmax);
    let mut solids = Vec::new();
    loop {
        let mut changed = false;
        for (i, o) in occluders.iter().enumerate() {
            if !o.solid || o.planes.is_empty() || skip(o) {
                continue;
            }
            // Its box must overlap the cell's inside.
            if !(o.min.cmplt(hi).all() && o.max.cmpgt(lo).all()) {
                continue;
            }
            let margin = slack + 16.0 * o.tolerance();
            for axis in 0..3 {
                for upper in [true, false] {
                    let Some(c) = slab_reach(&o.planes, lo, hi, axis, upper, margin) else {
                        continue;
                    };
                    let whole = if upper { c <= lo[axis] } else { c >= hi[axis] };
                    if whole {
                        return Reduced::Inside(i);
                    }
                    if upper && c < hi[axis] {
                        hi[axis] = c;
                    } else if !upper && c > lo[axis] {
                        lo[axis] = c;
                    } else {
                        continue;
                    }
                    changed = true;
                    if !solids.contains(&i) {
                        solids.push(i);
                    }
                }
            }
        }
        if !changed {
            break;
        }
    }
    Reduced::Cell {
        min: lo,
        max: hi,
        solids,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box `[a, b]` as a solid occluder.
    fn box_solid(a: DVec3, b: DVec3) -> Occluder {
        Occluder::test_box(0, a, b)
    }

    #[test]
    fn a_cell_reaching_into_a_box_loses_the_slab_inside_it() {
        let solid = box_solid(DVec3::new(2.0, -10.0, -10.0), DVec3::new(10.0, 10.0, 10.0));
        let r = reduce(&[solid], DVec3::ZERO, DVec3::splat(4.0), 1e-6, &|_| false);
        let Reduced::Cell { min, max, solids } = r else {
            panic!("{r:?}")
        };
        assert_eq!(solids, vec![0]);
        assert_eq!(min, DVec3::ZERO);
        // Cut a margin inside the solid's face at x = 2.
        assert!(max.x > 2.0 && max.x < 2.0 + 1e-4, "{max}");
        assert_eq!((max.y, max.z), (4.0, 4.0));
    }

    #[test]
    fn corners_and_surfaces_cut_nothing_and_the_inside_is_whole() {
        // Only a corner of the cell in the box: no slab.
        let corner = box_solid(DVec3::splat(2.0), DVec3::splat(10.0));
        let r = reduce(&[corner], DVec3::ZERO, DVec3::splat(4.0), 1e-6, &|_| false);
        assert_eq!(
            r,
            Reduced::Cell {
                min: DVec3::ZERO,
                max: DVec3::splat(4.0),
                solids: vec![]
            }
        );
        // A cell whose side lies on the solid's surface: its face there is
        // not strictly inside, so nothing is cut.
        let flush = box_solid(DVec3::new(2.0, 0.0, 0.0), DVec3::new(10.0, 4.0, 4.0));
        let r = reduce(&[flush], DVec3::ZERO, DVec3::splat(4.0), 1e-6, &|_| false);
        assert!(
            matches!(r, Reduced::Cell { ref solids, .. } if solids.is_empty()),
            "{r:?}"
        );
        // Wholly inside.
        let around = box_solid(DVec3::splat(-1.0), DVec3::splat(5.0));
        let r = reduce(&[around], DVec3::ZERO, DVec3::splat(4.0), 1e-6, &|_| false);
        assert_eq!(r, Reduced::Inside(0));
        // Skipped solids cut nothing.
        let solid = box_solid(DVec3::new(2.0, -10.0, -10.0), DVec3::new(10.0, 10.0, 10.0));
        let r = reduce(&[solid], DVec3::ZERO, DVec3::splat(4.0), 1e-6, &|_| true);
        assert!(matches!(r, Reduced::Cell { ref solids, .. } if solids.is_empty()));
    }

    #[test]
    fn a_slanted_solid_cuts_only_what_lies_inside_it() {
        // The half-space x + y >= 6 (bounded far away) as a solid: the
        // cell [0, 4]^3 has the slab x in [c, 4] inside only where
        // c + 0 >= 6 + margin: nowhere. Widen the cell along x to 10.
        let mut s = box_solid(DVec3::new(-100.0, -100.0, -100.0), DVec3::splat(100.0));
        let n = DVec3::new(-1.0, -1.0, 0.0).normalize();
        s.planes.push((n, n.dot(DVec3::new(6.0, 0.0, 0.0))));
        let r = reduce(&[s], DVec3::ZERO, DVec3::new(10.0, 4.0, 4.0), 1e-9, &|_| {
            false
        });
        let Reduced::Cell { max, .. } = r else {
            panic!("{r:?}")
        };
        // The slab x >= c is inside where c + 0 >= 6 (the corner y = 0),
        // by the margin (the solid's tolerance is relative to its size).
        assert!(max.x > 6.0 && max.x < 6.01, "{max}");
        // Every corner of the removed slab is inside the plane.
        for y in [0.0, 4.0] {
            for x in [max.x, 10.0] {
                let p = DVec3::new(x, y, 0.0);
                assert!(n.dot(p) <= n.dot(DVec3::new(6.0, 0.0, 0.0)));
            }
        }
    }
}
