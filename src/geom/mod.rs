//! Geometry shared by every stage: boxes now; 5D view cells, ray
//! parametrisation and frustum conversion join here with the builder.
//!
//! Nothing here depends on the builder's crates, so the runtime query side
//! can use it with `default-features = false`.

mod aabb;
pub mod cell;

pub use aabb::Aabb;
pub use cell::Cell;
