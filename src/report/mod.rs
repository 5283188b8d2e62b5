//! Comparison reports (`vis5d report`): per view, what each visibility
//! method would draw, against a ground truth rendered by ray casting.
//!
//! - **Ground truth** ([`truth`]): an ID buffer of one ray per pixel
//!   through the shared [`Camera`](crate::render::Camera); per view the
//!   objects seen and their pixel counts (the set `S_E`).
//! - **Methods**, each giving the set `S_A` of objects to draw per view:
//!   view-frustum culling ([`frustum_set`]: the objects whose bounding box
//!   meets the frustum), the lazy occlusion grid of papers/002, the vis5d
//!   tree (a `.v5d` queried per view, culled to the frustum by the query
//!   itself), the extended-projection oracle of a small cell around the
//!   eye, occluder shrinking for the same cell, and what neither of the two
//!   proves hidden (each restricted to the frustum).
//! - **Metrics** ([`ViewMetrics::of`]): objects and triangles drawn, pixels
//!   whose object is missing (the pixel error), missed objects, and the set
//!   errors of papers/003: under-estimation `Q_u = |S_E \ S_A| / |S_E|` and
//!   over-estimation `Q_o = |S_A \ S_E| / |S_E|`.
//!
//! - **The experiment** ([`run`]): every view through every [`Method`],
//!   with the lazy grid's costs lazy against busy ([`GridCost`]), into an
//!   [`Experiment`]; [`MethodRun::summary`] gives a method's figures over
//!   the views.
//!
//! - **Pictures** ([`picture`]): the ID buffers of the first views in
//!   flat shades by object, the objects a method dropped in red; and a
//!   top-down [`map`] of the tree's cells with the eyes on it.
//!
//! The command (`src/cli/report.rs`) loads the scene and the tree, runs the
//! experiment, and writes the page, the JSON, the Markdown and the
//! pictures.

mod report_image;
mod report_metrics;
mod report_run;

pub use report_image::{
    BACKGROUND, DRAWN_SIDE, DROPPED, EYE, LAYER_SHADES, Layers, MAX_LAYERS, Map, OUTLINE, Picture,
    drawn_picture, map, object_shade, picture,
};
pub use report_metrics::{MethodSummary, ViewMetrics, ViewTruth, frustum_set, truth, truth_of};
pub use report_run::{
    Experiment, GridCost, Method, MethodRun, Oracles, ReportError, ReportParams, Trees, run,
};
