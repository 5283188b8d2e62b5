//! Distances and intersection tests between points, segments, triangles
//! and small convex point sets, in f64, for the shrinking's checks.
//!
//! Each test errs on one side only where its caller needs it: the
//! distances are exact up to rounding (their callers compare them with a
//! margin), and [`hulls_may_intersect`] answers "may intersect" unless an
//! axis separates the two sets by more than a rounding margin.

use glam::DVec3;

/// The squared distance from `p` to the triangle `t` (closest point by
/// Voronoi regions, Ericson, *Real-Time Collision Detection*, 5.1.5).
pub fn point_triangle_distance_sq(p: DVec3, t: &[DVec3; 3]) -> f64 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + v * ab)).length_squared();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + w * ac)).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + w * (c - b))).length_squared();
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // A degenerate triangle: the nearest of its edges.
        return segment_segment_distance_sq(p, p, a, b)
            .min(segment_segment_distance_sq(p, p, b, c))
            .min(segment_segment_distance_sq(p, p, c, a));
    }
    let (v, w) = (vb / denom, vc / denom);
    (p - (a + ab * v + ac * w)).length_squared()
}

/// The squared distance between the segments `p1 q1` and `p2 q2` (Ericson
/// 5.1.9, degenerate segments included).
pub fn segment_segment_distance_sq(p1: DVec3, q1: DVec3, p2: DVec3, q2: DVec3) -> f64 {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    let tiny = f64::MIN_POSITIVE;
    let (s, t);
    if a <= tiny && e <= tiny {
        return r.length_squared();
    }
    if a <= tiny {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(r);
        if e <= tiny {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    ((p1 + d1 * s) - (p2 + d2 * t)).length_squared()
}

/// Whether the segment `p q` may meet the triangle `t`: true when it does,
/// and also when it passes within rounding of it (the callers reject on
/// "may meet").
pub fn segment_may_meet_triangle(p: DVec3, q: DVec3, t: &[DVec3; 3]) -> bool {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let scale = (p - t[0])
        .abs()
        .max((q - t[0]).abs())
        .max((t[1] - t[0]).abs())
        .max((t[2] - t[0]).abs())
        .max_element();
    let tol = 1e-12 * scale * n.length();
    let (dp, dq) = (n.dot(p - t[0]), n.dot(q - t[0]));
    if (dp > tol && dq > tol) || (dp < -tol && dq < -tol) {
        return false;
    }
    if (dp - dq).abs() <= tol {
        // In (or along) the triangle's plane: its distance to the edges
        // decides; the callers also test the edges against each other.
        return true;
    }
    let x = p + (q - p) * (dp / (dp - dq));
    // x in the triangle (inclusive, with slack): the signs of the three
    // sub-triangles' normals against n.
    let slack = 1e-9 * n.length_squared();
    (0..3).all(|k| {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        (b - a).cross(x - a).dot(n) >= -slack
    })
}

/// The distance between two triangles: 0 when they may meet, else the
/// smallest of the vertex-triangle and edge-edge distances.
pub fn triangle_distance(a: &[DVec3; 3], b: &[DVec3; 3]) -> f64 {
    for k in 0..3 {
        let (p, q) = (a[k], a[(k + 1) % 3]);
        if segment_may_meet_triangle(p, q, b) {
            return 0.0;
        }
        let (p, q) = (b[k], b[(k + 1) % 3]);
        if segment_may_meet_triangle(p, q, a) {
            return 0.0;
        }
    }
    let mut best = f64::INFINITY;
    for k in 0..3 {
        best = best
            .min(point_triangle_distance_sq(a[k], b))
            .min(point_triangle_distance_sq(b[k], a));
        for l in 0..3 {
            best = best.min(segment_segment_distance_sq(
                a[k],
                a[(k + 1) % 3],
                b[l],
                b[(l + 1) % 3],
            ));
        }
    }
    best.sqrt()
}

/// The distance from `p` to the box `[min, max]` (0 inside).
pub fn point_box_distance(p: DVec3, min: DVec3, max: DVec3) -> f64 {
    (min - p).max(p - max).max(DVec3::ZERO).length()
}

/// Whether the convex hulls of two point sets may intersect: false only
/// when some axis separates them by more than rounding. The axes tried
/// are the normals of every plane through three points of one set and
/// the cross products of every pair of point-to-point directions, one
/// from each set: a superset of the separating-axis theorem's face
/// normals and edge pairs, so two disjoint hulls are always told apart
/// (up to the margin).
pub fn hulls_may_intersect(a: &[DVec3], b: &[DVec3]) -> bool {
    let scale = a
        .iter()
        .chain(b)
        .fold(0.0f64, |m, p| m.max(p.abs().max_element()));
    let separates = |axis: DVec3| -> bool {
        let len = axis.length();
        if len <= 1e-300 {
            return false;
        }
        let (mut alo, mut ahi, mut blo, mut bhi) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for p in a {
            let d = p.dot(axis);
            alo = alo.min(d);
            ahi = ahi.max(d);
        }
        for p in b {
            let d = p.dot(axis);
            blo = blo.min(d);
            bhi = bhi.max(d);
        }
        let margin = 1e-9 * scale * len;
        ahi + margin < blo || bhi + margin < alo
    };
    // Boxes first.
    for k in 0..3 {
        let mut axis = DVec3::ZERO;
        axis[k] = 1.0;
        if separates(axis) {
            return false;
        }
    }
    for set in [a, b] {
        for i in 0..set.len() {
            for j in i + 1..set.len() {
                for k in j + 1..set.len() {
                    if separates((set[j] - set[i]).cross(set[k] - set[i])) {
                        return false;
                    }
                }
            }
        }
    }
    let dirs = |set: &[DVec3]| -> Vec<DVec3> {
        let mut out = Vec::new();
        for i in 0..set.len() {
            for j in i + 1..set.len() {
                out.push(set[j] - set[i]);
            }
        }
        out
    };
    let (da, db) = (dirs(a), dirs(b));
    for &u in &da {
        for &v in &db {
            if separates(u.cross(v)) {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    fn random_point(rng: &mut Pcg64) -> DVec3 {
        DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
    }

    /// The smallest distance between two triangles, by dense sampling of
    /// both (an upper bound on the true one that converges to it).
    fn sampled_distance(a: &[DVec3; 3], b: &[DVec3; 3]) -> f64 {
        let n = 24;
        let pts = |t: &[DVec3; 3]| {
            let mut out = Vec::new();
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    out.push(t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v);
                }
            }
            out
        };
        let (pa, pb) = (pts(a), pts(b));
        let mut best = f64::INFINITY;
        for p in &pa {
            best = best.min(point_triangle_distance_sq(*p, b).sqrt());
        }
        for p in &pb {
            best = best.min(point_triangle_distance_sq(*p, a).sqrt());
        }
        best
    }

    #[test]
    fn triangle_distances_are_never_above_what_sampling_finds() {
        let mut rng = Pcg64::seed_from_u64(7);
        for _ in 0..300 {
            let a = [0; 3].map(|_| random_point(&mut rng));
            let b = [0; 3].map(|_| random_point(&mut rng) + DVec3::X * rng.random_range(0.0..2.0));
            let d = triangle_distance(&a, &b);
            let s = sampled_distance(&a, &b);
            // Never more than the true distance (sampling's points are on
            // the triangles, so s is at least the true distance).
            assert!(d <= s + 1e-12, "{d} > sampled {s}: {a:?} {b:?}");
            // And not far below it: a point-to-triangle distance from the
            // sampled points converges to the true one.
            assert!(d >= s - 0.2, "{d} << sampled {s}");
        }
    }

    #[test]
    fn crossing_triangles_are_at_distance_zero() {
        let a = [
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let b = [
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::new(0.1, 0.0, 1.0),
            DVec3::new(0.0, 0.1, 1.0),
        ];
        assert_eq!(triangle_distance(&a, &b), 0.0);
        // Lifted above, the nearest points are b's lowest corner over a.
        let lifted = b.map(|p| p + DVec3::Z * 1.5);
        assert!((triangle_distance(&a, &lifted) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn hulls_apart_are_separated_and_overlapping_ones_are_not() {
        let cube = |o: DVec3, s: f64| -> Vec<DVec3> {
            (0..8)
                .map(|k| o + DVec3::new((k & 1) as f64, ((k >> 1) & 1) as f64, (k >> 2) as f64) * s)
                .collect()
        };
        assert!(!hulls_may_intersect(
            &cube(DVec3::ZERO, 1.0),
            &cube(DVec3::X * 1.01, 1.0)
        ));
        assert!(hulls_may_intersect(
            &cube(DVec3::ZERO, 1.0),
            &cube(DVec3::splat(0.99), 1.0)
        ));
        // Two tetrahedra apart only along an edge-edge axis.
        let a = vec![
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, -1.0, -1.0),
            DVec3::new(0.0, 1.0, -1.0),
        ];
        let b: Vec<DVec3> = vec![
            DVec3::new(0.0, -1.0, 0.01),
            DVec3::new(0.0, 1.0, 0.01),
            DVec3::new(-1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
        ];
        assert!(!hulls_may_intersect(&a, &b));
        let b2: Vec<DVec3> = b.iter().map(|p| *p - DVec3::Z * 0.02).collect();
        assert!(hulls_may_intersect(&a, &b2));
    }
}
