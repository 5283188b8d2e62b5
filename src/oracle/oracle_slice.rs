//! Slicing solids with the projection plane (papers/001 sec. 3.3).
//!
//! Where the plane cuts a solid (a closed surface, or one open only at its
//! bottom, see [`SlicedSolid`]), the cut is an occluder lying in the plane
//! (Depth 0): a segment from a viewpoint outside the solid to a point
//! inside the cut must cross the solid's surface on the way. This fuses a
//! whole concave object, a building of many small wall polygons say,
//! into one occluder, which convex pieces cannot do.
//!
//! The cut is found as segments, one per triangle crossing the plane; a
//! corner exactly on the plane counts as beyond it (a consistent symbolic
//! perturbation), and each edge's crossing point is computed from its
//! corners in one canonical order, so the segments of neighbouring
//! triangles share endpoints bit for bit and form closed loops. The
//! loops of a solid open at the bottom end on the floor line; the floor's
//! own cut is added by pairing those ends in order along the line (they
//! alternate in and out). A cut whose ends do not all pair up is dropped.
//!
//! Rasterisation is conservative: a pixel is filled only when no segment
//! comes within a hair of it and its centre is inside by the even-odd rule
//! (so the whole pixel is inside).

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::oracle_occluders::SlicedSolid;
use super::oracle_project::Frame;

/// Relative margin, in pixels, around segments.
const MARGIN: f64 = 1e-6;

/// The point where the edge `p`-`q` (frame coordinates, one corner on each
/// side) crosses `w = wp`, computed from the corners in a fixed order.
fn crossing(p: DVec3, q: DVec3, wp: f64) -> DVec2 {
    let key = |v: DVec3| (v.x, v.y, v.z);
    let (a, b) = if key(p).partial_cmp(&key(q)) == Some(std::cmp::Ordering::Less) {
        (p, q)
    } else {
        (q, p)
    };
    let t = (wp - a.z) / (b.z - a.z);
    (a + (b - a) * t).truncate()
}

/// The cut of `solid` by the plane `w = wp` of `frame`, as segments in the
/// plane's coordinates forming closed loops; `None` when it is empty or
/// does not close.
pub fn slice_segments(solid: &SlicedSolid, frame: Frame, wp: f64) -> Option<Vec<[DVec2; 2]>> {
    let beyond = |p: DVec3| p.z >= wp;
    let mut segments: Vec<[DVec2; 2]> = Vec::new();
    for t in &solid.triangles {
        let l = t.map(|p| frame.local(p));
        let side = l.map(beyond);
        if side[0] == side[1] && side[1] == side[2] {
            continue;
        }
        let mut ends = [DVec2::ZERO; 2];
        let mut k = 0;
        for e in 0..3 {
            let (a, b) = (e, (e + 1) % 3);
            if side[a] != side[b] {
                ends[k] = crossing(l[a], l[b], wp);
                k += 1;
            }
        }
        segments.push(ends);
    }
    if segments.is_empty() {
        return None;
    }
    // The floor's cut: pair the loop ends on the floor line.
    if let Some(floor) = solid.open_bottom {
        // Which plane coordinate holds world z (the plane is not
        // horizontal when it crosses the floor's edges).
        let zk = match frame.axis {
            0 => 1,
            1 => 0,
            _ => 2,
        };
        let mut ends: Vec<DVec2> = Vec::new();
        for &[p, q] in &solid.open_edges {
            let (a, b) = (frame.local(p), frame.local(q));
            if beyond(a) != beyond(b) {
                ends.push(crossing(a, b, wp));
            }
        }
        if !ends.is_empty() {
            if zk == 2 || ends.iter().any(|e| e[zk] != floor) || !ends.len().is_multiple_of(2) {
                return None;
            }
            let other = 1 - zk;
            ends.sort_by(|a, b| a[other].total_cmp(&b[other]));
            for pair in ends.chunks(2) {
                segments.push([pair[0], pair[1]]);
            }
        }
    }
    // Closed loops: every end point is shared by an even number of
    // segments.
    let mut degree: HashMap<[u64; 2], u32> = HashMap::with_capacity(segments.len() * 2);
    for s in &segments {
        for p in s {
            *degree.entry([p.x.to_bits(), p.y.to_bits()]).or_insert(0) += 1;
        }
    }
    degree.values().all(|d| d % 2 == 0).then_some(segments)
}

/// Writes `depth` (where smaller) into the pixels of the `n` x `n` map that
/// lie entirely inside the loops of `segments` (pixel coordinates); returns
/// how many.
pub fn draw_slice(map: &mut [f64], n: usize, segments: &[[DVec2; 2]], depth: f64) -> usize {
    let (lo, hi) = segments
        .iter()
        .flatten()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let nf = n as f64;
    if !(lo.x < nf && lo.y < nf && hi.x > 0.0 && hi.y > 0.0) {
        return 0;
    }
    let j0 = lo.y.floor().max(0.0) as usize;
    let j1 = (hi.y.ceil().min(nf)) as usize;
    let i0 = lo.x.floor().max(0.0) as usize;
    let i1 = (hi.x.ceil().min(nf)) as usize;
    let (w, h) = (i1 - i0, j1 - j0);
    if w == 0 || h == 0 {
        return 0;
    }
    // Pixels a segment comes near.
    let mut blocked = vec![false; w * h];
    for &[a, b] in segments {
        let (ya, yb) = (a.y.min(b.y) - MARGIN, a.y.max(b.y) + MARGIN);
        let ra = (ya.floor().max(j0 as f64)) as usize;
        let rb = (yb.floor().min(j1 as f64 - 1.0)).max(-1.0);
        if rb < ra as f64 {
            continue;
        }
        for j in ra..=rb as usize {
            // The segment's x range within the row strip (grown a hair).
            let (s0, s1) = (j as f64 - MARGIN, (j + 1) as f64 + MARGIN);
            let (x0, x1) = if a.y == b.y {
                (a.x.min(b.x), a.x.max(b.x))
            } else {
                let at = |y: f64| a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y);
                let (ta, tb) = (at(s0.max(ya + MARGIN)), at(s1.min(yb - MARGIN)));
                (ta.min(tb), ta.max(tb))
            };
            let c0 = ((x0 - MARGIN).floor().max(i0 as f64)) as usize;
            let c1 = (x1 + MARGIN).floor().min(i1 as f64 - 1.0);
            if c1 < c0 as f64 {
                continue;
            }
            for i in c0..=c1 as usize {
                blocked[(j - j0) * w + (i - i0)] = true;
            }
        }
    }
    // Even-odd fill at pixel centres.
    let mut filled = 0;
    let mut xs: Vec<f64> = Vec::new();
    for j in j0..j1 {
        let y = j as f64 + 0.5;
        xs.clear();
        for &[a, b] in segments {
            if (a.y <= y) != (b.y <= y) {
                xs.push(a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y));
            }
        }
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks_exact(2) {
            let c0 = ((pair[0] - 0.5).ceil().max(i0 as f64)) as usize;
            let c1 = (pair[1] - 0.5).floor().min(i1 as f64 - 1.0);
            if c1 < c0 as f64 {
                continue;
            }
            for i in c0..=c1 as usize {
                if !blocked[(j - j0) * w + (i - i0)] {
                    let d = &mut map[j * n + i];
                    *d = d.min(depth);
                    filled += 1;
                }
            }
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oracle::oracle_occluders::extract;
    use crate::scene::procedural::shapes::push_box;
    use crate::scene::{SceneBuilder, SceneFormat};
    use glam::Vec3;

    fn solid(tris: Vec<[Vec3; 3]>) -> SlicedSolid {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("o");
        for t in tris {
            b.push_triangle(t).unwrap();
        }
        let scene = b.finish(std::path::Path::new("t")).unwrap();
        extract(&scene).solids.remove(0)
    }

    /// An L-shaped prism (two boxes' worth of footprint, one mesh, no
    /// floor), cut by a vertical plane.
    fn l_prism() -> SlicedSolid {
        // Footprint (x, y): (0,0) (4,0) (4,1) (1,1) (1,4) (0,4); height 2.
        let f = [
            (0.0, 0.0),
            (4.0, 0.0),
            (4.0, 1.0),
            (1.0, 1.0),
            (1.0, 4.0),
            (0.0, 4.0),
        ];
        let p = |k: usize, z: f32| Vec3::new(f[k % 6].0, f[k % 6].1, z);
        let mut tris = Vec::new();
        for k in 0..6 {
            tris.push([p(k, 0.0), p(k + 1, 0.0), p(k + 1, 2.0)]);
            tris.push([p(k, 0.0), p(k + 1, 2.0), p(k, 2.0)]);
        }
        // Roof: a fan from the inner corner (1, 1), no new vertices.
        let r = |x: f32, y: f32| Vec3::new(x, y, 2.0);
        tris.push([r(1.0, 1.0), r(1.0, 4.0), r(0.0, 4.0)]);
        tris.push([r(1.0, 1.0), r(0.0, 4.0), r(0.0, 0.0)]);
        tris.push([r(1.0, 1.0), r(0.0, 0.0), r(4.0, 0.0)]);
        tris.push([r(1.0, 1.0), r(4.0, 0.0), r(4.0, 1.0)]);
        solid(tris)
    }

    #[test]
    fn a_floorless_prism_cuts_into_its_cross_section() {
        let s = l_prism();
        assert_eq!(s.open_bottom, Some(0.0));
        // The plane x = 0.5 (frame +x: u = y, v = z): the cut is the
        // rectangle y in [0, 4], z in [0, 2].
        let frame = Frame {
            axis: 0,
            positive: true,
        };
        let segs = slice_segments(&s, frame, 0.5).expect("a closed cut");
        let mut map = vec![f64::INFINITY; 8 * 8];
        // Map the plane rect [0, 4] x [0, 2] onto 8 x 8 pixels.
        let px: Vec<[DVec2; 2]> = segs
            .iter()
            .map(|s| s.map(|p| DVec2::new(p.x * 2.0, p.y * 4.0)))
            .collect();
        let n = draw_slice(&mut map, 8, &px, 0.0);
        // Every pixel but the border ones touching the loop.
        assert_eq!(n, 6 * 6, "{map:?}");
        // The plane x = 2: only the foot of the L, y in [0, 1].
        let segs = slice_segments(&s, frame, 2.0).expect("a closed cut");
        let (lo, hi) = segs
            .iter()
            .flatten()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        assert_eq!((lo, hi), (DVec2::new(0.0, 0.0), DVec2::new(1.0, 2.0)));
    }

    #[test]
    fn a_plane_through_corners_and_faces_still_closes() {
        let mut tris = Vec::new();
        push_box(&mut tris, Vec3::ZERO, Vec3::ONE);
        let s = solid(tris);
        for axis in 0..3 {
            for positive in [true, false] {
                let frame = Frame { axis, positive };
                for wp in [-1.0, 0.0, 0.25, 0.5, 1.0] {
                    let wp = if positive { wp } else { -wp };
                    let segs = slice_segments(&s, frame, wp);
                    if let Some(segs) = segs {
                        let mut map = vec![f64::INFINITY; 16 * 16];
                        let px: Vec<[DVec2; 2]> = segs
                            .iter()
                            .map(|s| s.map(|p| (p + DVec2::splat(0.5)) * 8.0))
                            .collect();
                        let n = draw_slice(&mut map, 16, &px, 0.0);
                        // The unit square fills 8 x 8 pixels but its border.
                        assert!(n <= 64, "{axis} {positive} {wp}: {n}");
                    }
                }
            }
        }
    }
}
