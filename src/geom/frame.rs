//! Where a scene's local coordinates sit in the world.
//!
//! vis5d works in f32, whose steps grow with the coordinate: a model in UTM
//! coordinates (x near 500,000 m) is resolved to 3 cm, and the tracer's
//! rounding margins, which grow with the largest coordinate, made such a
//! scene build a hundred times slower than the same scene at the origin.
//! So a scene far from the origin relative to its size is held in a local
//! frame centred on it: `world = local + origin`, the origin in f64 (see
//! [`Frame::for_bounds`] for when it is not zero). Files keep the origin
//! (notes/format.md), and [`crate::query::Pvs`] takes world coordinates
//! and converts them.

use glam::{DVec3, Vec3};

use super::Aabb;

/// How far from the origin, in scene diagonals, a scene's centre may lie
/// before it gets a local frame: the tracer's rounding margins grow with
/// the largest coordinate, and up to here they stay within a few times
/// the scene's own.
pub const FAR_DIAGONALS: f64 = 4.0;

/// How far from the origin, in scene diagonals, a scene may lie at all:
/// beyond it even the f64 input coordinates step by more than an f32 step
/// of the scene's own size (2^-24 of its diagonal), so no frame can
/// recover the geometry.
pub const MAX_DIAGONALS: f64 = (1u64 << 28) as f64;

/// A translation from the scene's local coordinates (f32, what every
/// stage works in) to world coordinates (f64, what files and users speak):
/// `world = local + origin`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Frame {
    /// The world position of the local origin.
    pub origin: DVec3,
}

impl Frame {
    /// The frame whose local coordinates are the world's.
    pub const IDENTITY: Frame = Frame {
        origin: DVec3::ZERO,
    };

    /// The frame for a scene with world bounds `[min, max]` (finite, `min
    /// <= max`): the identity when the scene's centre lies within
    /// [`FAR_DIAGONALS`] diagonals of the origin (every scene modelled
    /// around it: its files and coordinates stay as they were), else an
    /// origin near the centre on a multiple of the largest power of two
    /// not above the diagonal, `step`: `floor(centre / step + 1/3) step`
    /// (local coordinates stay within about a diagonal of zero, and the
    /// origin is a short number). The third keeps the rule's jumps away
    /// from round centres, which decimal coordinates often have: a scene
    /// written as text and read back, its coordinates off by a rounding,
    /// gets the same origin.
    pub fn for_bounds(min: DVec3, max: DVec3) -> Frame {
        let centre = (min + max) * 0.5;
        let diagonal = (max - min).length();
        if centre.abs().max_element() <= FAR_DIAGONALS * diagonal || diagonal == 0.0 {
            return Frame::IDENTITY;
        }
        let step = 2f64.powi(diagonal.log2().floor() as i32);
        // `+ 0.0` makes a -0.0 coordinate +0.0 (it hashes differently).
        let origin = (centre / step + DVec3::splat(1.0 / 3.0)).floor() * step + DVec3::ZERO;
        Frame { origin }
    }

    /// Whether local and world coordinates are the same.
    pub fn is_identity(&self) -> bool {
        self.origin == DVec3::ZERO
    }

    /// The local point nearest to the world point `p`.
    pub fn to_local(self, p: DVec3) -> Vec3 {
        (p - self.origin).as_vec3()
    }

    /// The world point of the local point `p` (exact up to f64 rounding).
    pub fn to_world(self, p: Vec3) -> DVec3 {
        p.as_dvec3() + self.origin
    }

    /// The smallest local box holding the world box `[min, max]`: rounded
    /// outwards, so a query over it misses no viewpoint of the world box.
    /// The identity frame gives back f32 corners unchanged.
    pub fn box_to_local(&self, min: DVec3, max: DVec3) -> Aabb {
        let down = |x: f64| {
            let y = x as f32;
            if f64::from(y) > x { y.next_down() } else { y }
        };
        let up = |x: f64| {
            let y = x as f32;
            if f64::from(y) < x { y.next_up() } else { y }
        };
        let (lo, hi) = (min - self.origin, max - self.origin);
        Aabb::new(
            Vec3::new(down(lo.x), down(lo.y), down(lo.z)),
            Vec3::new(up(hi.x), up(hi.y), up(hi.z)),
        )
    }

    /// The world point of the local point `p` as text, `x,y,z`: the f32
    /// values as they are for the identity frame (so a scene near the
    /// origin reads as it always did), else for each coordinate the
    /// shortest decimal whose local value is `p`'s (`1000000.15`, not the
    /// `1000000.150000006` that the f32 `-7.85` plus `1000008` makes).
    pub fn world_text(&self, p: Vec3) -> String {
        if self.is_identity() {
            return format!("{},{},{}", p.x, p.y, p.z);
        }
        let text = |local: f32, origin: f64| {
            let world = f64::from(local) + origin;
            (0..17)
                .map(|digits| format!("{world:.digits$}"))
                .find(|t| t.parse::<f64>().is_ok_and(|w| (w - origin) as f32 == local))
                .unwrap_or_else(|| world.to_string())
        };
        format!(
            "{},{},{}",
            text(p.x, self.origin.x),
            text(p.y, self.origin.y),
            text(p.z, self.origin.z)
        )
    }

    /// The world corners `(min, max)` of the local box `b`.
    pub fn box_to_world(&self, b: &Aabb) -> (DVec3, DVec3) {
        (self.to_world(b.min), self.to_world(b.max))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_near_the_origin_keep_their_coordinates() {
        let f = Frame::for_bounds(DVec3::new(-3.0, 0.0, 0.0), DVec3::new(10.0, 8.0, 3.0));
        assert!(f.is_identity());
        // A scene 4 diagonals out is still "near".
        let f = Frame::for_bounds(DVec3::new(7.0, 0.0, 0.0), DVec3::new(9.0, 0.0, 0.0));
        assert!(f.is_identity(), "{f:?}");
    }

    #[test]
    fn far_scenes_are_centred_on_a_round_origin() {
        // The apartment's size, in UTM coordinates.
        let min = DVec3::new(500_123.25, 4_649_876.5, 12.0);
        let max = min + DVec3::new(13.0, 9.5, 3.0);
        let f = Frame::for_bounds(min, max);
        let diagonal = (max - min).length();
        let step = 16.0; // the largest power of two not above 16.4
        assert_eq!(f.origin % step, DVec3::ZERO, "{f:?}");
        // Round centres are away from the rule's jumps: (40, 44, -2) with
        // step 8 stays put when the bounds move by a rounding.
        let (lo, hi) = (DVec3::new(35.0, 39.0, -7.0), DVec3::new(45.0, 49.0, 3.0));
        let g = Frame::for_bounds(lo + 400.0, hi + 400.0);
        for e in [1e-9, -1e-9] {
            assert_eq!(Frame::for_bounds(lo + 400.0 + e, hi + 400.0 + e), g);
        }
        // No negative zero.
        let z = Frame::for_bounds(
            DVec3::new(1e6, -1.0, -1.5),
            DVec3::new(1e6 + 1.0, 1.0, 1.4999),
        );
        assert!(
            z.origin
                .to_array()
                .iter()
                .all(|c| !c.is_sign_negative() || *c != 0.0),
            "{z:?}"
        );
        assert!(z.origin.z.is_sign_positive(), "{z:?}");
        for p in [min, max] {
            let local = f.to_local(p);
            assert!(f64::from(local.abs().max_element()) <= diagonal, "{local}");
            // Local coordinates resolve the scene as finely as at the origin.
            assert!((f.to_world(local) - p).abs().max_element() < 1e-5);
        }
    }

    #[test]
    fn world_text_is_short_and_exact() {
        let f = Frame {
            origin: DVec3::new(1_000_008.0, 1_000_000.0, 0.0),
        };
        let p = Vec3::new(-7.85, 0.15, 2.75);
        assert_eq!(f.world_text(p), "1000000.15,1000000.15,2.75");
        assert_eq!(Frame::IDENTITY.world_text(p), "-7.85,0.15,2.75");
    }

    #[test]
    fn boxes_round_outwards() {
        let f = Frame {
            origin: DVec3::new(1e6, 0.0, 0.0),
        };
        let (min, max) = (
            DVec3::new(1e6 + 0.1, 0.1, -0.1),
            DVec3::new(1e6 + 0.3, 0.3, 0.2),
        );
        let b = f.box_to_local(min, max);
        let (wmin, wmax) = f.box_to_world(&b);
        assert!(wmin.cmple(min).all() && wmax.cmpge(max).all(), "{b:?}");
        // Tight: within one f32 step.
        assert!((wmin - min).abs().max_element() < 1e-7);
        // The identity frame changes no f32 corner.
        let b = Aabb::new(Vec3::new(0.1, -2.5, 1e-30), Vec3::new(0.2, 3.0, 7.0));
        let (lo, hi) = Frame::IDENTITY.box_to_world(&b);
        assert_eq!(Frame::IDENTITY.box_to_local(lo, hi), b);
    }
}
