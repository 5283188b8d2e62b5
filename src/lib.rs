//! # vis5d: precomputed from-region visibility
//!
//! vis5d precomputes which objects of a static 3D scene can be seen from
//! which regions of view space, so that a renderer draws only those. It
//! follows Gotsman, Sudarsky & Fayman, *Optimized occlusion culling using
//! five-dimensional subdivision* (Computers & Graphics 23, 1999): the 5D
//! space of viewing rays (a position and a direction) is cut by a k-d tree
//! whose leaves each hold the set of objects visible from some ray of the
//! leaf, decided per object by a sequential test on random rays.
//!
//! ## The pipeline in one screen
//!
//! ```text
//! model.obj / .gltf / .glb
//!    |  scene: objects (name, triangle range, bounds, area table)
//!    v
//! Scene --------------------------------------------+
//!    |  trace: BVH over all triangles (obvhs)        |
//!    v                                               |
//! Tracer: closest hit -> (object, triangle, t)       |
//!    |  sample: cell rays, object samples            |
//!    v                                               |
//! sprt: beta-function SPRT per (cell, object)        |
//!    v                                               |
//! build: 5D k-d tree, splits scored by E(A,B) -> VisTree (tree)
//!    |  codec: three set codings, the .v5d file
//!    v
//! model.v5d --decode--> query::Pvs: range and view queries -> ObjectSet
//! ```
//!
//! ## A render loop
//!
//! An engine links `vis5d` with `default-features = false` (only [`query`],
//! [`codec`], [`tree`], [`geom`] and [`bitset`]), loads the file once and
//! asks for each frame's potentially visible set:
//!
//! ```
//! # #[cfg(feature = "builder")] {
//! use glam::Vec3;
//! use vis5d::{Pvs, View};
//!
//! # // Make a small .v5d file for the example (engines load theirs).
//! # let scene = vis5d::scene::procedural::generate(vis5d::scene::procedural::SceneKind::Apartment, 1, 1);
//! # let tracer = vis5d::trace::Tracer::new(&scene);
//! # let params = vis5d::builder::BuildParams { max_depth: 6, ..Default::default() };
//! # let (tree, _) = vis5d::builder::build(&scene, &tracer, &params, &|_| {}).unwrap();
//! # let bytes = vis5d::codec::write_file(&vis5d::builder::to_file(&scene, tree, &params, None));
//! let pvs = Pvs::from_bytes(&bytes)?; // or Pvs::load("model.v5d")
//! let mut visible = pvs.new_set(); // made once, reused every frame
//! for frame in 0..3 {
//!     let eye = Vec3::new(2.0 + 0.5 * frame as f32, 2.5, 1.6);
//!     // A camera as the engine holds it: eye, forward, up, vertical field
//!     // of view, aspect (or View::from_view_projection(its matrix)).
//!     let view = View::look(eye, Vec3::new(1.0, 0.2, -0.1), Vec3::Z, 1.0, 16.0 / 9.0);
//!     // No allocation; an error only for a set not made by new_set.
//!     let answer = pvs.query_view(&view, &mut visible)?;
//!     // Answer::Everything: the eye is outside the baked view box.
//!     assert_eq!(answer, vis5d::Answer::Tree);
//!     for object in visible.iter() {
//!         let _name = pvs.object(object).map(|o| o.name()); // draw(object)
//!     }
//!     assert!(visible.count() < pvs.object_count());
//! }
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Positions are world coordinates for a scene modelled around the
//! origin, +z up. A scene far from it (a model in UTM coordinates) is
//! built in a local frame whose origin the file keeps
//! ([`Pvs::frame`](query::Pvs::frame)), and a scene built with another up
//! axis (`vis5d build --up y`) in one whose z is its up: pass f64 world
//! positions and world directions to
//! [`query_view_world`](query::Pvs::query_view_world), which converts
//! them, or local ones to `query_view`.
//!
//! ## Modules
//!
//! Each paper has its module, named for what it does:
//!
//! | module | paper | role |
//! |---|---|---|
//! | [`sprt`] | papers/003 sec. 5 | the beta-function sequential test |
//! | [`builder`] | papers/003 sec. 4-5 | the 5D k-d tree built by ray sampling |
//! | [`codec`] | papers/003 sec. 6 | the three set codings and the `.v5d` file |
//! | [`query`] | papers/003 sec. 7 | [`query::Pvs`]: range and view queries |
//! | [`oracle`] | papers/001 | the conservative extended-projection oracle |
//! | [`conservative`] | papers/001 sec. 6 | the conservative bake: a spatial k-d tree of the oracle's sets |
//! | [`shrink`] | papers/004 sec. 4 | occluder shrinking: a second conservative oracle, from the cell's centre |
//! | [`slices`] | papers/004 sec. 3 | objects cut into axis slices; the hidden part of a kept object as one index per axis |
//! | [`lazy_grid`] | papers/002 | the lazy occlusion grid (an online baseline) |
//!
//! Runtime side (always built): [`geom`] (boxes, 5D cells), [`bitset`],
//! [`tree`] (the in-memory tree), [`codec`], [`query`], [`atomic_write`]
//! and [`input`] (files out and in, safely), [`invariant`] (the error of
//! every `validate()`).
//!
//! Builder side (feature `builder`): [`scene`] (OBJ/glTF loading,
//! procedural scenes), [`trace`] (the exact BVH tracer), [`random`] (the
//! shared random draws), [`sample`], [`sprt`], [`builder`], [`render`] (the
//! one camera and the ray-cast ID buffer), [`oracle`], [`shrink`], [`slices`], [`conservative`], [`lazy_grid`],
//! [`report`] (the methods compared against a ray-cast ground truth).
//!
//! ## Features
//!
//! - default (`cli`): the `vis5d` command-line tool and everything below.
//! - `builder`: the preprocess: scene loaders, procedural scenes, tracer,
//!   SPRT, tree builder, the oracle on the CPU, the lazy grid, reports.
//! - `gpu`: the oracle's wgpu rasteriser ([`oracle::GpuRasteriser`]).
//! - `serde`: `serde::Serialize` on the report's figures.
//! - none (`default-features = false`): the runtime side only, free of
//!   obvhs, rayon, gltf, tobj, statrs and clap.

// Without the builder (or the GPU) the modules named above are not built:
// their links lead to the features instead.
#![cfg_attr(
    not(feature = "builder"),
    doc = "\n\n[`sprt`]: crate#features\n[`builder`]: crate#features\n\
           [`conservative`]: crate#features\n[`lazy_grid`]: crate#features\n\
           [`oracle`]: crate#features\n[`shrink`]: crate#features\n\
           [`random`]: crate#features\n[`render`]: crate#features\n\
           [`report`]: crate#features\n[`sample`]: crate#features\n\
           [`scene`]: crate#features\n[`trace`]: crate#features"
)]
#![cfg_attr(
    not(feature = "gpu"),
    doc = "\n\n[`oracle::GpuRasteriser`]: crate#features"
)]
#![warn(missing_docs)]

/// What an engine needs, at the root: load a file ([`Pvs`]), make the
/// answer sets once ([`ObjectSet`], [`Delta`]), ask per camera ([`View`],
/// [`Answer`]), read objects ([`ObjectInfo`]).
pub use bitset::ObjectSet;
pub use query::{Answer, Delta, ObjectInfo, Pvs, PvsError, View};

pub mod atomic_write;
pub mod bitset;
#[cfg(feature = "builder")]
pub mod builder;
pub mod codec;
#[cfg(feature = "builder")]
pub mod conservative;
pub mod geom;
pub mod input;
pub mod invariant;
#[cfg(feature = "builder")]
pub mod lazy_grid;
#[cfg(feature = "builder")]
pub mod oracle;
pub mod query;
#[cfg(feature = "builder")]
pub mod random;
#[cfg(feature = "builder")]
pub mod raylog;
#[cfg(feature = "builder")]
pub mod render;
#[cfg(feature = "builder")]
pub mod report;
#[cfg(feature = "builder")]
pub mod sample;
#[cfg(feature = "builder")]
pub mod scene;
#[cfg(feature = "builder")]
pub mod shrink;
pub mod slices;
#[cfg(feature = "builder")]
pub mod sprt;
#[cfg(feature = "builder")]
pub mod trace;
pub mod tree;
