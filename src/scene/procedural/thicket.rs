//! `thicket`: a dense forest, 256 trees on a jittered 2.5 m grid over a 40
//! x 40 m plot, each a trunk and a crown of leaf triangles that starts
//! half a metre above the ground. From a cell among the trees, most trees
//! are behind the leaves of nearer ones, but no single leaf hides much:
//! occlusion comes only from many small occluders together, the case the
//! occlusion sweep of papers/001 (sec. 5, its forest) is for.

use glam::Vec3;
use rand::RngExt;
use rand_pcg::Pcg64;

use super::Model;
use super::shapes::{push_box, push_cylinder, push_leaves};

const SIDE: usize = 16;
const STEP: f32 = 2.5;
const LEAVES: usize = 400;

pub(super) fn generate(rng: &mut Pcg64) -> Model {
    let mut m = Model::default();
    let size = SIDE as f32 * STEP;
    push_box(
        m.object("ground"),
        Vec3::new(0.0, 0.0, -0.3),
        Vec3::new(size, size, 0.0),
    );
    for j in 0..SIDE {
        for i in 0..SIDE {
            let p = Vec3::new(
                (i as f32 + 0.5) * STEP + rng.random_range(-0.6..0.6f32),
                (j as f32 + 0.5) * STEP + rng.random_range(-0.6..0.6f32),
                0.0,
            );
            let height = rng.random_range(4.0..7.0f32);
            push_cylinder(
                m.object(format!("tree_{i}_{j}/trunk")),
                p,
                Vec3::Z * height,
                rng.random_range(0.1..0.2f32),
                8,
            );
            // A crown from 0.5 m to the top, 1-1.4 m in radius.
            let radius = rng.random_range(1.0..1.4f32);
            let (bottom, top) = (0.5, height + 0.5);
            let centre = p + Vec3::Z * (0.5 * (bottom + top));
            let half = Vec3::new(radius, radius, 0.5 * (top - bottom));
            let leaves = m.object(format!("tree_{i}_{j}/leaves"));
            push_leaves(leaves, rng, centre, half, LEAVES, 0.4..0.6);
        }
    }
    m
}
