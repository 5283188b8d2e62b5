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
//! Scene ------------------------------------------+
//!    |  trace: BVH over all triangles (obvhs)      |
//!    v                                             |
//! Tracer: closest hit -> (object, triangle, t),    |
//!         one ray or batches in parallel (rayon)   |
//!    v                                             |
//! (next: ray samples per 5D cell, SPRT, k-d tree, .v5d file, runtime
//!  range queries, the conservative GPU oracle, comparison reports)
//! ```
//!
//! ## Modules
//!
//! - [`geom`]: boxes (and later 5D cells); no dependencies, always built.
//! - [`scene`] (feature `builder`): OBJ and glTF loading, validation,
//!   uniform surface sampling, procedural test scenes.
//! - [`trace`] (feature `builder`): the BVH tracer.
//!
//! ## Features
//!
//! - default (`cli`): the `vis5d` command-line tool and everything below.
//! - `builder`: the preprocess: scene loaders, procedural scenes, tracer.
//! - none (`default-features = false`): the runtime side only, free of
//!   obvhs, rayon, gltf, tobj and clap.

#![warn(missing_docs)]

pub mod bitset;
#[cfg(feature = "builder")]
pub mod build;
pub mod geom;
#[cfg(feature = "builder")]
pub mod sample;
#[cfg(feature = "builder")]
pub mod scene;
#[cfg(feature = "builder")]
pub mod sprt;
#[cfg(feature = "builder")]
pub mod trace;
pub mod tree;
