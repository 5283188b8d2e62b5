//! Convex polygons in the plane (f64), the one set of 2D helpers of the
//! oracle's projections, its CPU and GPU rasterisers and its occluder
//! extraction: signed area, rectangles, convex hull and clipping.
//!
//! Polygons are vertex lists, counter-clockwise where a function says so;
//! the last vertex joins the first.

use glam::DVec2;

/// The signed area of a polygon (positive when counter-clockwise).
pub fn signed_area(p: &[DVec2]) -> f64 {
    let mut a = 0.0;
    for i in 0..p.len() {
        a += p[i].perp_dot(p[(i + 1) % p.len()]);
    }
    0.5 * a
}

/// The rectangle `[min, max]`, counter-clockwise from `min`.
pub fn rectangle(min: DVec2, max: DVec2) -> Vec<DVec2> {
    vec![min, DVec2::new(max.x, min.y), max, DVec2::new(min.x, max.y)]
}

/// The convex hull of points, counter-clockwise (Andrew's monotone chain);
/// collinear points dropped; empty when the points span no area. Sorts
/// and dedups `points` in place.
pub fn convex_hull(points: &mut Vec<DVec2>) -> Vec<DVec2> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    if points.len() < 3 {
        return Vec::new();
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<DVec2> = Vec::with_capacity(points.len() * 2);
    for &p in points.iter() {
        while hull.len() >= 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    let lower = hull.len() + 1;
    for &p in points.iter().rev().skip(1) {
        while hull.len() >= lower && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    hull.pop();
    hull
}

/// Keeps the part of a convex polygon where `f >= 0` (`f` affine):
/// Sutherland-Hodgman against one half-plane. A new vertex is placed on
/// its edge with the parameter clamped to [0, 1], so that it stays on the
/// segment, hence inside the half-planes clipped before.
pub fn clip_half_plane(poly: &[DVec2], f: impl Fn(DVec2) -> f64) -> Vec<DVec2> {
    let mut out = Vec::with_capacity(poly.len() + 1);
    clip_half_plane_into(poly, f, &mut out);
    out
}

/// [`clip_half_plane`] into `out` (cleared first), so that a caller
/// clipping many polygons reuses one buffer.
fn clip_half_plane_into(poly: &[DVec2], f: impl Fn(DVec2) -> f64, out: &mut Vec<DVec2>) {
    out.clear();
    for (i, &a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        let (fa, fb) = (f(a), f(b));
        if fa >= 0.0 {
            out.push(a);
        }
        if (fa >= 0.0) != (fb >= 0.0) {
            let t = (fa / (fa - fb)).clamp(0.0, 1.0);
            out.push(a + (b - a) * t);
        }
    }
}

/// Clips the convex polygon `subject` to the convex polygon `clip` (both
/// counter-clockwise): their intersection, empty when they do not overlap
/// (or meet only along an edge or at a point).
pub fn clip_convex(subject: &[DVec2], clip: &[DVec2]) -> Vec<DVec2> {
    let (mut out, mut scratch) = (Vec::new(), Vec::new());
    clip_convex_into(subject, clip, &mut out, &mut scratch);
    out
}

/// [`clip_convex`] into `out` (cleared first), with `scratch` as the
/// second buffer: the same polygon, without an allocation per edge.
pub fn clip_convex_into(
    subject: &[DVec2],
    clip: &[DVec2],
    out: &mut Vec<DVec2>,
    scratch: &mut Vec<DVec2>,
) {
    out.clear();
    out.extend_from_slice(subject);
    for i in 0..clip.len() {
        if out.is_empty() {
            break;
        }
        let (a, b) = (clip[i], clip[(i + 1) % clip.len()]);
        clip_half_plane_into(out, |p| (b - a).perp_dot(p - a), scratch);
        std::mem::swap(out, scratch);
    }
    if out.len() < 3 || signed_area(out) <= 0.0 {
        out.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sq(a: f64, b: f64) -> Vec<DVec2> {
        rectangle(DVec2::splat(a), DVec2::splat(b))
    }

    #[test]
    fn hull_and_clip() {
        let mut pts = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.5, 0.5),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
        ];
        let h = convex_hull(&mut pts);
        assert_eq!(h.len(), 4);
        assert!((signed_area(&h) - 1.0).abs() < 1e-12);
        let c = clip_convex(&sq(0.0, 2.0), &sq(1.0, 3.0));
        assert!((signed_area(&c) - 1.0).abs() < 1e-12);
        assert!(clip_convex(&sq(0.0, 1.0), &sq(2.0, 3.0)).is_empty());
        let mut cw = sq(0.0, 1.0);
        cw.reverse();
        assert!((signed_area(&cw) + 1.0).abs() < 1e-12);
        let half = clip_half_plane(&sq(0.0, 2.0), |p| 1.0 - p.x);
        assert!((signed_area(&half) - 2.0).abs() < 1e-12);
    }

    /// Clipping by random half-planes keeps exactly the part of a square
    /// on the kept side: points sampled on a grid agree.
    #[test]
    fn clipping_keeps_the_kept_side() {
        let square = sq(0.0, 1.0);
        for k in 0..50 {
            let angle = k as f64 * 0.7;
            let (n, d) = (
                DVec2::new(angle.cos(), angle.sin()),
                (k as f64 * 0.37).fract(),
            );
            let kept = clip_half_plane(&square, |p| n.dot(p) - d);
            for i in 1..20 {
                for j in 1..20 {
                    let p = DVec2::new(i as f64 / 20.0, j as f64 / 20.0);
                    let side = n.dot(p) - d;
                    if side.abs() < 1e-9 || kept.len() < 3 {
                        continue;
                    }
                    let inside = (0..kept.len()).all(|e| {
                        (kept[(e + 1) % kept.len()] - kept[e]).perp_dot(p - kept[e]) >= -1e-12
                    });
                    assert_eq!(inside, side > 0.0, "{k}: {p}");
                }
            }
        }
    }
}
