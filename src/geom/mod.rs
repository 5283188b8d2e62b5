//! Geometry shared by every stage: boxes ([`Aabb`]), 5D view cells and
//! the ray parametrisation ([`cell`]), the local frame of a scene far from
//! the origin ([`Frame`]); with the builder, convex polygons
//! in the plane ([`polygon`]) and the hierarchy of object boxes
//! ([`BoxTree`]).
//!
//! Nothing here depends on the builder's crates, so the runtime query side
//! can use it with `default-features = false`.
#![cfg_attr(
    not(feature = "builder"),
    doc = "\n\n[`polygon`]: crate#features\n[`BoxTree`]: crate#features"
)]

mod aabb;
#[cfg(feature = "builder")]
mod box_tree;
pub mod cell;
pub mod frame;
#[cfg(feature = "builder")]
pub mod polygon;
pub(crate) mod trig;

pub use aabb::Aabb;
#[cfg(feature = "builder")]
pub use box_tree::{BoxNode, BoxTree};
pub use cell::Cell;
pub use frame::{Frame, Up};

use glam::DVec3;

/// Whether a triangle given by f64 corners has (numerically) zero area
/// (`scene::is_degenerate`, the loaders' rule): the cross product of two
/// edges is at most `1e-12` times the squared longest edge, or the corners
/// coincide. The edges are scaled by their largest component first, so
/// that huge coordinates (1e160) do not overflow into a false "zero".
pub fn zero_area(&[a, b, c]: &[DVec3; 3]) -> bool {
    let (e0, e1, e2) = (b - a, c - a, c - b);
    let scale = e0.abs().max(e1.abs()).max(e2.abs()).max_element();
    if scale == 0.0 {
        return true;
    }
    if !scale.is_finite() {
        // Corners too far apart for f64 differences: not a zero area.
        return false;
    }
    // Scaled only where squares would overflow or underflow, so that
    // every other triangle is decided exactly as before.
    let (e0, e1, e2) = if (1e-100..1e100).contains(&scale) {
        (e0, e1, e2)
    } else {
        (e0 / scale, e1 / scale, e2 / scale)
    };
    let longest = e0
        .length_squared()
        .max(e1.length_squared())
        .max(e2.length_squared());
    let cross = e0.cross(e1).length();
    cross <= 1e-12 * longest
}
