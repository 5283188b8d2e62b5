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

pub use aabb::Aabb;
#[cfg(feature = "builder")]
pub use box_tree::{BoxNode, BoxTree};
pub use cell::Cell;
pub use frame::{Frame, Up};
