//! Axis-aligned boxes in 3D.
//!
//! The one box type of the crate: object bounds, scene bounds, and (later) the
//! spatial part of 5D view cells. Kept free of the builder's dependencies so
//! the runtime query side can use it.

use glam::Vec3;

/// An axis-aligned box `[min, max]`, closed on both sides.
///
/// The empty box has `min = +inf` and `max = -inf`, so that
/// [`Aabb::grow`] and [`Aabb::union`] need no special case.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// The smallest corner.
    pub min: Vec3,
    /// The largest corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box: contains nothing, neutral for [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::INFINITY,
        max: Vec3::NEG_INFINITY,
    };

    /// The box with the given corners (not checked: `min <= max` is the
    /// caller's promise).
    pub const fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    /// The smallest box holding every point of `points` (empty when there
    /// are none).
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        let mut b = Self::EMPTY;
        for p in points {
            b.grow(p);
        }
        b
    }

    /// Whether the closed boxes share a point (touching counts).
    pub fn overlaps(&self, other: &Aabb) -> bool {
        self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
    }

    /// Whether the box holds no point.
    pub fn is_empty(&self) -> bool {
        !(self.min.cmple(self.max).all())
    }

    /// Grows the box to hold `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box holding both boxes.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// The extent along each axis (`max - min`); negative for the empty box.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// The centre point.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// The length of the diagonal: the box's scale, 0 for a point.
    pub fn diagonal(&self) -> f32 {
        if self.is_empty() {
            0.0
        } else {
            self.size().length()
        }
    }

    /// The volume; 0 for flat or empty boxes.
    pub fn volume(&self) -> f32 {
        let s = self.size().max(Vec3::ZERO);
        s.x * s.y * s.z
    }

    /// Whether `p` lies in the closed box.
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The box grown by `margin` on every side.
    pub fn expanded(&self, margin: f32) -> Aabb {
        Aabb {
            min: self.min - Vec3::splat(margin),
            max: self.max + Vec3::splat(margin),
        }
    }

    /// The box with every side at least `thickness` long (grown evenly
    /// about its centre where shorter) and, whatever f32 rounding does at
    /// the box's coordinates, `min < max` on every axis: a flat scene (a
    /// floor plan, one triangle) still has a volume of viewpoints.
    pub fn thickened(&self, thickness: f32) -> Aabb {
        let mut b = *self;
        for k in 0..3 {
            let short = thickness - (b.max[k] - b.min[k]);
            if short > 0.0 {
                b.min[k] -= 0.5 * short;
                b.max[k] += 0.5 * short;
            }
            if b.min[k] >= b.max[k] {
                b.min[k] = b.min[k].next_down();
                b.max[k] = b.max[k].next_up();
            }
        }
        b
    }

    /// The point of the box at relative coordinates `t` (each in `[0, 1]`):
    /// `min + t * (max - min)`. Uniform `t` gives a uniform point.
    pub fn lerp(&self, t: Vec3) -> Vec3 {
        self.min + t * (self.max - self.min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thickened_boxes_have_a_volume() {
        let flat = Aabb::new(Vec3::new(0.0, 0.0, 2.0), Vec3::new(4.0, 3.0, 2.0));
        let t = flat.thickened(0.5);
        assert_eq!(t.min, Vec3::new(0.0, 0.0, 1.75));
        assert_eq!(t.max, Vec3::new(4.0, 3.0, 2.25));
        // Far from the origin, where the thickness rounds away.
        let far = Aabb::new(Vec3::splat(1e9), Vec3::new(1e9 + 1024.0, 1e9 + 1024.0, 1e9));
        let t = far.thickened(1e-3);
        assert!(t.min.cmplt(t.max).all(), "{t:?}");
        assert_eq!(t.min.x, 1e9);
        // A box with volume is left alone.
        let solid = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(solid.thickened(0.5), solid);
    }

    #[test]
    fn empty_box_is_neutral() {
        let b = Aabb::new(Vec3::new(0.0, 1.0, 2.0), Vec3::new(3.0, 4.0, 5.0));
        assert!(Aabb::EMPTY.is_empty());
        assert!(!b.is_empty());
        assert_eq!(Aabb::EMPTY.union(&b), b);
        assert_eq!(Aabb::EMPTY.diagonal(), 0.0);
        assert_eq!(Aabb::EMPTY.volume(), 0.0);
    }

    #[test]
    fn from_points_measures() {
        let b = Aabb::from_points([Vec3::new(1.0, -1.0, 0.0), Vec3::new(-1.0, 1.0, 2.0)]);
        assert_eq!(b.min, Vec3::new(-1.0, -1.0, 0.0));
        assert_eq!(b.max, Vec3::new(1.0, 1.0, 2.0));
        assert_eq!(b.volume(), 8.0);
        assert_eq!(b.center(), Vec3::new(0.0, 0.0, 1.0));
        assert!(b.contains(Vec3::new(1.0, 1.0, 2.0)));
        assert!(!b.contains(Vec3::new(1.0, 1.0, 2.1)));
        assert_eq!(b.lerp(Vec3::splat(0.5)), b.center());
        assert_eq!(b.expanded(1.0).size(), Vec3::new(4.0, 4.0, 4.0));
    }
}
