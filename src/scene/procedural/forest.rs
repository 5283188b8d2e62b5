//! `forest`: 30 trees scattered over a 60 x 60 m clearing, no two trunks
//! closer than 4 m, plus a few rocks. A tree is two objects: a trunk (a
//! cylinder) and its leaves (120 small triangles of random orientation
//! filling an ellipsoidal crown), so a crown occludes only partially: the
//! fine, porous occlusion that the sampling must not over-trust.

use glam::Vec3;
use rand::RngExt;
use rand_pcg::Pcg64;

use super::Model;
use super::shapes::{push_box, push_cylinder, push_ellipsoid, push_leaves};

const TREES: usize = 30;
const SIZE: f32 = 60.0;
const LEAVES: usize = 120;

pub(super) fn generate(rng: &mut Pcg64) -> Model {
    let mut m = Model::default();
    push_box(
        m.object("ground"),
        Vec3::new(0.0, 0.0, -0.3),
        Vec3::new(SIZE, SIZE, 0.0),
    );
    let mut spots: Vec<Vec3> = Vec::new();
    while spots.len() < TREES {
        let p = Vec3::new(
            rng.random_range(3.0..SIZE - 3.0),
            rng.random_range(3.0..SIZE - 3.0),
            0.0,
        );
        if spots.iter().all(|q| q.distance(p) >= 4.0) {
            spots.push(p);
        }
    }
    for (i, &p) in spots.iter().enumerate() {
        let height = rng.random_range(3.0..6.0f32);
        let radius = rng.random_range(0.15..0.3f32);
        push_cylinder(
            m.object(format!("tree_{i}/trunk")),
            p,
            Vec3::Z * height,
            radius,
            8,
        );
        let crown = Vec3::new(
            rng.random_range(1.5..2.5f32),
            rng.random_range(1.5..2.5f32),
            rng.random_range(2.0..3.0f32),
        );
        let centre = p + Vec3::Z * (height + crown.z * 0.5);
        let leaves = m.object(format!("tree_{i}/leaves"));
        push_leaves(leaves, rng, centre, crown, LEAVES, 0.15..0.35);
    }
    for k in 0..6 {
        let c = Vec3::new(
            rng.random_range(2.0..SIZE - 2.0),
            rng.random_range(2.0..SIZE - 2.0),
            0.0,
        );
        let r = Vec3::new(
            rng.random_range(0.5..1.5f32),
            rng.random_range(0.5..1.5f32),
            rng.random_range(0.3..0.8f32),
        );
        push_ellipsoid(m.object(format!("rock_{k}")), c, r, 4, 8);
    }
    m
}
