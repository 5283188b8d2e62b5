//! Axis-aligned planar patches: every triangle of the scene lying in a
//! plane `x = c`, `y = c` or `z = c`, grouped by that plane, across
//! objects. Floors, slabs, ceilings, flat roofs and the walls of most
//! buildings are such patches, and they are rarely convex: a slab with a
//! stair opening, a wall with a door, a floor made of many tiles.
//!
//! A patch is drawn, on a projection plane that is its own plane, as the
//! *union* of its triangles, not triangle by triangle: a pixel is covered
//! when no *boundary edge* of the patch touches it and its centre lies in
//! some triangle. A boundary edge is an edge (the same two f32 corners)
//! that does not have triangles on both of its sides and does not lie
//! inside one triangle of the patch (a wall's foot standing on a slab).
//! The union's border lies on boundary edges (near a point inside an edge
//! with a triangle on each side, or inside a triangle, the patch covers a
//! whole disc), so a pixel that no boundary edge touches lies wholly
//! inside the union or wholly outside it, and its centre tells which. T-junctions and gaps between triangles that
//! do not share corners stay boundary edges: they are never papered over.
//!
//! Depth on its own plane is 0: a segment from the cell to a point of the
//! patch ends on the patch. The occlusion sweep (`oracle_sweep.rs`) carries
//! the patch to the planes behind it by reprojection, which is the
//! extended projection of a planar occluder parallel to the planes
//! (papers/001 sec. 5.1), exact up to the pixels.

use std::collections::HashMap;

use glam::DVec2;

use crate::scene::Scene;

/// Relative margin against rounding, in pixels, on the side of "not
/// covered".
const MARGIN: f64 = 1e-6;

/// The triangles of a scene lying in one axis-aligned plane.
#[derive(Clone, Debug)]
pub struct Patch {
    /// The plane's axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// The plane's coordinate along the axis.
    pub coord: f64,
    /// The triangles, in the plane's coordinates
    /// `(p[(axis + 1) % 3], p[(axis + 2) % 3])` (a [`super::Frame`]'s `u`, `v`).
    pub triangles: Vec<[DVec2; 3]>,
    /// The edges without a triangle on each side.
    pub boundary: Vec<[DVec2; 2]>,
    /// The triangles' bounding box in the plane.
    pub min: DVec2,
    /// The triangles' bounding box in the plane.
    pub max: DVec2,
    /// The triangles' total area.
    pub area: f64,
}

/// The patches of a scene, sorted by axis, then coordinate. Planes of less
/// than `min_area` in all are left out, and so are the triangles of objects
/// that do not occlude.
pub fn extract(scene: &Scene, min_area: f64) -> Vec<Patch> {
    let mut groups: HashMap<(usize, u32), Vec<[DVec2; 3]>> = HashMap::new();
    let occluding = (0..scene.objects().len())
        .filter(|&o| scene.objects()[o].flags.occludes())
        .flat_map(|o| scene.object_triangles(o));
    for t in occluding {
        for axis in 0..3 {
            let c = t[0][axis];
            if t[1][axis].to_bits() != c.to_bits() || t[2][axis].to_bits() != c.to_bits() {
                continue;
            }
            let uv = |p: glam::Vec3| DVec2::new(p[(axis + 1) % 3] as f64, p[(axis + 2) % 3] as f64);
            let tri = [uv(t[0]), uv(t[1]), uv(t[2])];
            if cross(tri[1] - tri[0], tri[2] - tri[0]) != 0.0 {
                groups.entry((axis, c.to_bits())).or_default().push(tri);
            }
            break;
        }
    }
    let mut out: Vec<Patch> = groups
        .into_iter()
        .filter_map(|((axis, bits), triangles)| {
            let area: f64 = triangles
                .iter()
                .map(|t| 0.5 * cross(t[1] - t[0], t[2] - t[0]).abs())
                .sum();
            (area >= min_area).then(|| patch(axis, f32::from_bits(bits) as f64, triangles, area))
        })
        .collect();
    out.sort_by(|a, b| a.axis.cmp(&b.axis).then(a.coord.total_cmp(&b.coord)));
    out
}

fn cross(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// A patch from its triangles: finds the boundary edges.
fn patch(axis: usize, coord: f64, triangles: Vec<[DVec2; 3]>, area: f64) -> Patch {
    // Per edge (corners ordered by their bits), whether a triangle lies on
    // its left and on its right.
    let key = |p: DVec2| (p.x.to_bits(), p.y.to_bits());
    type Corner = (u64, u64);
    let mut sides: HashMap<(Corner, Corner), (DVec2, DVec2, bool, bool)> = HashMap::new();
    for t in &triangles {
        for k in 0..3 {
            let (mut a, mut b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            if key(b) < key(a) {
                std::mem::swap(&mut a, &mut b);
            }
            let left = cross(b - a, c - a) > 0.0;
            let e = sides
                .entry((key(a), key(b)))
                .or_insert((a, b, false, false));
            if left {
                e.2 = true;
            } else {
                e.3 = true;
            }
        }
    }
    // An edge inside one triangle of the patch (its ends in the closed
    // triangle, its middle strictly inside; a wall standing on a slab)
    // has that triangle on both sides: not a border of the union.
    let inside = |t: &[DVec2; 3], p: DVec2, strict: bool| {
        let o = cross(t[1] - t[0], t[2] - t[0]).signum();
        (0..3).all(|k| {
            let s = o * cross(t[(k + 1) % 3] - t[k], p - t[k]);
            if strict { s > 0.0 } else { s >= 0.0 }
        })
    };
    let covered = |a: DVec2, b: DVec2| {
        let m = 0.5 * (a + b);
        triangles.iter().any(|t| {
            let lo = t[0].min(t[1]).min(t[2]);
            let hi = t[0].max(t[1]).max(t[2]);
            a.min(b).cmpge(lo).all()
                && a.max(b).cmple(hi).all()
                && inside(t, m, true)
                && inside(t, a, false)
                && inside(t, b, false)
        })
    };
    let mut boundary: Vec<[DVec2; 2]> = sides
        .into_values()
        .filter(|e| !(e.2 && e.3 || covered(e.0, e.1)))
        .map(|e| [e.0, e.1])
        .collect();
    boundary.sort_by(|a, b| {
        (a[0].x, a[0].y, a[1].x, a[1].y)
            .partial_cmp(&(b[0].x, b[0].y, b[1].x, b[1].y))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let (min, max) = triangles
        .iter()
        .flatten()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    Patch {
        axis,
        coord,
        triangles,
        boundary,
        min,
        max,
        area,
    }
}

/// Writes depth 0 into the pixels of the `n` x `n` `level0` (over the
/// rectangle `[rmin, rmax]` of the patch's own plane, in its `u`, `v`)
/// that the union of the patch's triangles covers entirely; returns how
/// many pixels that is.
pub fn draw_patch(level0: &mut [f64], n: usize, rmin: DVec2, rmax: DVec2, patch: &Patch) -> usize {
    let Some(pixel) = super::oracle_plane::pixel_size((rmin, rmax), n) else {
        return 0;
    };
    let lo = ((patch.min - rmin) / pixel).floor().max(DVec2::ZERO);
    let hi = ((patch.max - rmin) / pixel)
        .ceil()
        .min(DVec2::splat(n as f64));
    if !(lo.x < hi.x && lo.y < hi.y) {
        return 0;
    }
    let (i0, j0) = (lo.x as usize, lo.y as usize);
    let (w, h) = (hi.x as usize - i0, hi.y as usize - j0);
    // Pixels whose centre is in some triangle, less those a boundary edge
    // touches, in the window [i0, i0 + w) x [j0, j0 + h).
    let mut inside = vec![false; w * h];
    let to_px = |p: DVec2| (p - rmin) / pixel - DVec2::new(i0 as f64, j0 as f64);
    for t in &patch.triangles {
        let q = t.map(to_px);
        let (a, b) = q
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        let orient = cross(q[1] - q[0], q[2] - q[0]).signum();
        let (x0, x1) = (
            (a.x - 0.5).ceil().max(0.0),
            (b.x - 0.5).floor().min(w as f64 - 1.0),
        );
        let (y0, y1) = (
            (a.y - 0.5).ceil().max(0.0),
            (b.y - 0.5).floor().min(h as f64 - 1.0),
        );
        if x0 > x1 || y0 > y1 {
            continue;
        }
        for j in y0 as usize..=y1 as usize {
            for i in x0 as usize..=x1 as usize {
                let c = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
                // On an edge counts: the closed triangle holds the centre.
                let s = |p: DVec2, q2: DVec2| orient * cross(q2 - p, c - p) >= 0.0;
                if s(q[0], q[1]) && s(q[1], q[2]) && s(q[2], q[0]) {
                    inside[j * w + i] = true;
                }
            }
        }
    }
    for e in &patch.boundary {
        let (p, q) = (to_px(e[0]), to_px(e[1]));
        let (ylo, yhi) = (p.y.min(q.y) - MARGIN, p.y.max(q.y) + MARGIN);
        let (r0, r1) = (ylo.floor().max(0.0), yhi.floor().min(h as f64 - 1.0));
        if r0 > r1 {
            continue;
        }
        for j in r0 as usize..=r1 as usize {
            // The part of the segment within the row's band, grown.
            let (b0, b1) = (
                (j as f64 - MARGIN).max(ylo),
                (j as f64 + 1.0 + MARGIN).min(yhi),
            );
            let x_at = |y: f64| {
                if q.y == p.y {
                    None
                } else {
                    Some(p.x + (q.x - p.x) * ((y - p.y) / (q.y - p.y)).clamp(0.0, 1.0))
                }
            };
            let (xa, xb) = match (x_at(b0), x_at(b1)) {
                (Some(a), Some(b)) => (a.min(b), a.max(b)),
                _ => (p.x.min(q.x), p.x.max(q.x)),
            };
            let c0 = (xa - MARGIN).floor().max(0.0);
            let c1 = (xb + MARGIN).floor().min(w as f64 - 1.0);
            if c0 > c1 {
                continue;
            }
            for i in c0 as usize..=c1 as usize {
                inside[j * w + i] = false;
            }
        }
    }
    let mut covered = 0;
    for j in 0..h {
        for i in 0..w {
            if inside[j * w + i] {
                let d = &mut level0[(j0 + j) * n + i0 + i];
                *d = d.min(0.0);
                covered += 1;
            }
        }
    }
    covered
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_with_hole() -> Patch {
        // The ring between [0, 8]^2 and the hole [3, 5]^2, as 8 triangles
        // sharing corners.
        let p = |x: f64, y: f64| DVec2::new(x, y);
        let (o, i) = (
            [p(0.0, 0.0), p(8.0, 0.0), p(8.0, 8.0), p(0.0, 8.0)],
            [p(3.0, 3.0), p(5.0, 3.0), p(5.0, 5.0), p(3.0, 5.0)],
        );
        let mut tris = Vec::new();
        for k in 0..4 {
            let n = (k + 1) % 4;
            tris.push([o[k], o[n], i[n]]);
            tris.push([o[k], i[n], i[k]]);
        }
        patch(2, 1.0, tris, 60.0)
    }

    #[test]
    fn a_ring_fuses_across_its_seams_and_keeps_its_hole() {
        let ring = square_with_hole();
        // Only the 8 outer and the 8 inner edges are boundary edges.
        assert_eq!(ring.boundary.len(), 8);
        let n = 16;
        let mut map = vec![f64::INFINITY; n * n];
        // Pixels of half a unit over [0, 8]^2.
        let covered = draw_patch(&mut map, n, DVec2::ZERO, DVec2::splat(8.0), &ring);
        let at = |i: usize, j: usize| map[j * n + i];
        // Seams (the diagonals) are covered; the hole and the pixels along
        // the borders are not.
        assert_eq!(at(2, 2), 0.0);
        assert_eq!(at(1, 7), 0.0);
        assert_eq!(at(7, 7), f64::INFINITY);
        assert_eq!(at(0, 0), f64::INFINITY);
        assert_eq!(at(5, 6), f64::INFINITY);
        // Every covered pixel lies in the ring, with no border through it.
        for j in 0..n {
            for i in 0..n {
                if at(i, j) == 0.0 {
                    let (x0, y0) = (0.5 * i as f64, 0.5 * j as f64);
                    let in_hole = x0 + 0.5 > 3.0 && x0 < 5.0 && y0 + 0.5 > 3.0 && y0 < 5.0;
                    assert!(!in_hole && x0 > 0.0 && y0 > 0.0 && x0 + 0.5 < 8.0 && y0 + 0.5 < 8.0);
                }
            }
        }
        // 16 x 16 less the outer ring of pixels (14 x 14) less the hole and
        // the pixels around it (6 x 6).
        assert_eq!(covered, 14 * 14 - 6 * 6);
    }

    #[test]
    fn a_t_junction_or_a_duplicate_on_one_side_is_a_boundary() {
        let p = |x: f64, y: f64| DVec2::new(x, y);
        // An edge inside a bigger triangle is not a boundary.
        let inner = patch(
            0,
            0.0,
            vec![
                [p(0.0, 0.0), p(4.0, 0.0), p(0.0, 4.0)],
                [p(1.0, 1.0), p(2.0, 1.0), p(1.0, 2.0)],
            ],
            8.5,
        );
        assert_eq!(inner.boundary.len(), 3);
        // Two triangles on the same side of one edge: still a boundary.
        let same_side = patch(
            0,
            0.0,
            vec![
                [p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1.0)],
                [p(0.0, 0.0), p(1.0, 0.0), p(0.5, 2.0)],
            ],
            1.0,
        );
        assert!(
            same_side
                .boundary
                .iter()
                .any(|e| e[0] == p(0.0, 0.0) && e[1] == p(1.0, 0.0))
        );
        // A T-junction: the long edge has a triangle on one side only.
        let t = patch(
            0,
            0.0,
            vec![
                [p(0.0, 0.0), p(2.0, 0.0), p(1.0, 1.0)],
                [p(0.0, 0.0), p(1.0, 0.0), p(1.0, -1.0)],
                [p(1.0, 0.0), p(2.0, 0.0), p(1.0, -1.0)],
            ],
            3.0,
        );
        assert!(
            t.boundary
                .iter()
                .any(|e| e[0] == p(0.0, 0.0) && e[1] == p(2.0, 0.0))
        );
    }
}
