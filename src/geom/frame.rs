//! Where a scene's local coordinates sit in the world, and which way is up.
//!
//! vis5d works in f32, whose steps grow with the coordinate: a model in UTM
//! coordinates (x near 500,000 m) is resolved to 3 cm, and the tracer's
//! rounding margins, which grow with the largest coordinate, made such a
//! scene build a hundred times slower than the same scene at the origin.
//! So a scene far from the origin relative to its size is held in a local
//! frame centred on it (see [`Frame::for_bounds`] for when), the origin in
//! f64.
//!
//! The local frame also puts the scene's up axis ([`Up`], `vis5d build
//! --up`) on local z: the angular parametrisation of directions (phi from
//! +z, theta about it; [`crate::geom::cell`]) and everything that means
//! "floor" or "above" (floorless buildings, street cells) work in local
//! coordinates, so a Y-up scene built with `--up y` gets the same tree as
//! the same scene turned Z-up. The axes are turned by a cyclic
//! permutation, exact in floating point and right-handed:
//! `local = P(world - origin)`, `world = P^-1(local) + origin`.
//!
//! Files keep the origin and the up axis (notes/format.md), and
//! [`crate::query::Pvs`] takes world coordinates and converts them.

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

/// A scene's up axis in world coordinates: the one local z follows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Up {
    /// World +x is up: local (x, y, z) = world (y, z, x).
    X,
    /// World +y is up (glTF, most game engines): local (x, y, z) = world
    /// (z, x, y).
    Y,
    /// World +z is up (the default; CAD, GIS): local = world.
    #[default]
    Z,
}

impl Up {
    /// Its world axis: 0, 1 or 2.
    pub fn axis(self) -> usize {
        match self {
            Up::X => 0,
            Up::Y => 1,
            Up::Z => 2,
        }
    }

    /// The up axis of world axis `axis` (0, 1 or 2).
    pub fn from_axis(axis: usize) -> Option<Up> {
        [Up::X, Up::Y, Up::Z].get(axis).copied()
    }

    /// "x", "y" or "z".
    pub fn name(self) -> &'static str {
        ["x", "y", "z"][self.axis()]
    }

    /// The world axis that local axis `k` (0, 1, 2) is: local z is the up
    /// axis, local x and y the two after it, cyclically.
    pub fn world_axis(self, k: usize) -> usize {
        (self.axis() + 1 + k) % 3
    }

    /// The world unit vector pointing up.
    pub fn world_vector(self) -> Vec3 {
        let mut v = Vec3::ZERO;
        v[self.axis()] = 1.0;
        v
    }
}

impl std::fmt::Display for Up {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Up {
    type Err = String;

    fn from_str(s: &str) -> Result<Up, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "x" | "+x" => Ok(Up::X),
            "y" | "+y" => Ok(Up::Y),
            "z" | "+z" => Ok(Up::Z),
            other => Err(format!("the up axis must be x, y or z, not {other:?}")),
        }
    }
}

/// A scene's local frame: `world = P^-1(local) + origin`, `P` the cyclic
/// permutation of the axes that puts the `up` axis on local z.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Frame {
    /// The world position of the local origin.
    pub origin: DVec3,
    /// The world axis that local z follows.
    pub up: Up,
}

impl Frame {
    /// The frame whose local coordinates are the world's.
    pub const IDENTITY: Frame = Frame {
        origin: DVec3::ZERO,
        up: Up::Z,
    };

    /// The frame for a scene with world bounds `[min, max]` (finite, `min
    /// <= max`) and up axis `up`: the origin zero when the scene's centre
    /// lies within [`FAR_DIAGONALS`] diagonals of it (every scene modelled
    /// around it: its files and coordinates stay as they were), else an
    /// origin near the centre on a multiple of the largest power of two
    /// not above the diagonal, `step`: `floor(centre / step + 1/3) step`
    /// (local coordinates stay within about a diagonal of zero, and the
    /// origin is a short number). The third keeps the rule's jumps away
    /// from round centres, which decimal coordinates often have: a scene
    /// written as text and read back, its coordinates off by a rounding,
    /// gets the same origin.
    pub fn for_bounds(min: DVec3, max: DVec3, up: Up) -> Frame {
        let centre = (min + max) * 0.5;
        let diagonal = (max - min).length();
        if centre.abs().max_element() <= FAR_DIAGONALS * diagonal || diagonal == 0.0 {
            return Frame {
                origin: DVec3::ZERO,
                up,
            };
        }
        let step = 2f64.powi(diagonal.log2().floor() as i32);
        // `+ 0.0` makes a -0.0 coordinate +0.0 (it hashes differently).
        let origin = (centre / step + DVec3::splat(1.0 / 3.0)).floor() * step + DVec3::ZERO;
        Frame { origin, up }
    }

    /// Whether local and world coordinates are the same (no origin, +z up).
    pub fn is_identity(&self) -> bool {
        self.origin == DVec3::ZERO && self.up == Up::Z
    }

    /// Whether the origin is the world's (the frame at most turns the axes).
    pub fn at_world_origin(&self) -> bool {
        self.origin == DVec3::ZERO
    }

    /// `P v`: world axes to local ones (no translation).
    fn turn_in<T: Copy>(self, v: [T; 3]) -> [T; 3] {
        let a = |k: usize| v[self.up.world_axis(k)];
        [a(0), a(1), a(2)]
    }

    /// `P^-1 v`: local axes to world ones (no translation).
    fn turn_out<T: Copy + Default>(self, v: [T; 3]) -> [T; 3] {
        let mut out = [T::default(); 3];
        for (k, &c) in v.iter().enumerate() {
            out[self.up.world_axis(k)] = c;
        }
        out
    }

    /// The local point nearest to the world point `p`.
    pub fn to_local(self, p: DVec3) -> Vec3 {
        DVec3::from_array(self.turn_in((p - self.origin).to_array())).as_vec3()
    }

    /// The world point of the local point `p` (exact up to f64 rounding).
    pub fn to_world(self, p: Vec3) -> DVec3 {
        DVec3::from_array(self.turn_out(p.as_dvec3().to_array())) + self.origin
    }

    /// A world direction (or any vector: no translation) in local axes;
    /// exact.
    pub fn dir_to_local(self, d: Vec3) -> Vec3 {
        Vec3::from_array(self.turn_in(d.to_array()))
    }

    /// A local direction in world axes; exact.
    pub fn dir_to_world(self, d: Vec3) -> Vec3 {
        Vec3::from_array(self.turn_out(d.to_array()))
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
        let lo = self.turn_in((min - self.origin).to_array());
        let hi = self.turn_in((max - self.origin).to_array());
        Aabb::new(
            Vec3::new(down(lo[0]), down(lo[1]), down(lo[2])),
            Vec3::new(up(hi[0]), up(hi[1]), up(hi[2])),
        )
    }

    /// The world point of the local point `p` as text, `x,y,z`: the f32
    /// values as they are for a frame at the world's origin (so a scene
    /// near the origin reads as it always did), else for each coordinate
    /// the shortest decimal whose local value is `p`'s (`1000000.15`, not
    /// the `1000000.150000006` that the f32 `-7.85` plus `1000008` makes).
    pub fn world_text(&self, p: Vec3) -> String {
        let w = self.turn_out(p.to_array());
        if self.at_world_origin() {
            return format!("{},{},{}", w[0], w[1], w[2]);
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
            text(w[0], self.origin.x),
            text(w[1], self.origin.y),
            text(w[2], self.origin.z)
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
        let f = Frame::for_bounds(
            DVec3::new(-3.0, 0.0, 0.0),
            DVec3::new(10.0, 8.0, 3.0),
            Up::Z,
        );
        assert!(f.is_identity());
        // A scene 4 diagonals out is still "near".
        let f = Frame::for_bounds(DVec3::new(7.0, 0.0, 0.0), DVec3::new(9.0, 0.0, 0.0), Up::Z);
        assert!(f.is_identity(), "{f:?}");
    }

    #[test]
    fn far_scenes_are_centred_on_a_round_origin() {
        // The apartment's size, in UTM coordinates.
        let min = DVec3::new(500_123.25, 4_649_876.5, 12.0);
        let max = min + DVec3::new(13.0, 9.5, 3.0);
        let f = Frame::for_bounds(min, max, Up::Z);
        let diagonal = (max - min).length();
        let step = 16.0; // the largest power of two not above 16.4
        assert_eq!(f.origin % step, DVec3::ZERO, "{f:?}");
        // Round centres are away from the rule's jumps: (40, 44, -2) with
        // step 8 stays put when the bounds move by a rounding.
        let (lo, hi) = (DVec3::new(35.0, 39.0, -7.0), DVec3::new(45.0, 49.0, 3.0));
        let g = Frame::for_bounds(lo + 400.0, hi + 400.0, Up::Z);
        for e in [1e-9, -1e-9] {
            assert_eq!(Frame::for_bounds(lo + 400.0 + e, hi + 400.0 + e, Up::Z), g);
        }
        // No negative zero.
        let z = Frame::for_bounds(
            DVec3::new(1e6, -1.0, -1.5),
            DVec3::new(1e6 + 1.0, 1.0, 1.4999),
            Up::Z,
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
            up: Up::Z,
        };
        let p = Vec3::new(-7.85, 0.15, 2.75);
        assert_eq!(f.world_text(p), "1000000.15,1000000.15,2.75");
        assert_eq!(Frame::IDENTITY.world_text(p), "-7.85,0.15,2.75");
    }

    #[test]
    fn boxes_round_outwards() {
        let f = Frame {
            origin: DVec3::new(1e6, 0.0, 0.0),
            up: Up::Z,
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

    #[test]
    fn up_axes_turn_exactly_and_keep_handedness() {
        for up in [Up::X, Up::Y, Up::Z] {
            let f = Frame {
                origin: DVec3::new(1e6, -2e5, 3.0),
                up,
            };
            // Up is local +z; the frame is right-handed.
            assert_eq!(f.dir_to_local(up.world_vector()), Vec3::Z);
            let (a, b) = (Vec3::new(0.3, -1.7, 2.9), Vec3::new(-4.1, 0.6, 1.25));
            assert_eq!(
                f.dir_to_local(a.cross(b)),
                f.dir_to_local(a).cross(f.dir_to_local(b))
            );
            assert_eq!(f.dir_to_world(f.dir_to_local(a)), a);
            let p = Vec3::new(-7.85, 0.15, 2.75);
            let w = f.to_world(p);
            assert_eq!(f.to_local(w), p);
            let text: Vec<f64> = f
                .world_text(p)
                .split(',')
                .map(|t| t.parse().unwrap())
                .collect();
            assert!((DVec3::from_slice(&text) - w).abs().max_element() < 1e-6);
            let b = f.box_to_local(w - 0.5, w + 0.25);
            assert!(b.contains(p), "{b:?} {p}");
            let (lo, hi) = f.box_to_world(&b);
            assert!(lo.cmple(w - 0.5).all() && hi.cmpge(w + 0.25).all());
            assert_eq!(up.to_string().parse::<Up>(), Ok(up));
        }
        let y = Frame {
            origin: DVec3::ZERO,
            up: Up::Y,
        };
        // Y up: local (x, y, z) = world (z, x, y).
        assert_eq!(
            y.dir_to_local(Vec3::new(1.0, 2.0, 3.0)),
            Vec3::new(3.0, 1.0, 2.0)
        );
        assert_eq!(y.world_text(Vec3::new(3.0, 1.0, 2.0)), "1,2,3");
        assert!(!y.is_identity() && y.at_world_origin());
        assert!("w".parse::<Up>().is_err());
    }
}
