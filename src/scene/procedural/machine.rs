//! `machine`: a closed casing 1.2 x 0.7 x 0.9 m with a ventilation grating
//! in its front face and about 150 internal parts (rollers, gears, motors,
//! circuit boards with chips, shafts), like the copy machine of papers/003
//! sec. 8, whose internal parts were "visible through the ventilation
//! grating". From outside, the inside can be seen only through the 12 mm
//! slots between the grating's slats.

use glam::Vec3;
use rand::RngExt;
use rand_pcg::Pcg64;

use super::Model;
use super::shapes::{push_box, push_cylinder};

const W: f32 = 1.2;
const D: f32 = 0.7;
const H: f32 = 0.9;
const WALL: f32 = 0.02;
/// The grating's opening in the front face (y = 0): x and z ranges.
const OPEN_X: (f32, f32) = (0.3, 0.9);
const OPEN_Z: (f32, f32) = (0.3, 0.6);

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

pub(super) fn generate(rng: &mut Pcg64) -> Model {
    let mut m = Model::default();
    push_box(m.object("casing/bottom"), v(0.0, 0.0, 0.0), v(W, D, WALL));
    push_box(m.object("casing/top"), v(0.0, 0.0, H - WALL), v(W, D, H));
    push_box(
        m.object("casing/left"),
        v(0.0, 0.0, WALL),
        v(WALL, D, H - WALL),
    );
    push_box(
        m.object("casing/right"),
        v(W - WALL, 0.0, WALL),
        v(W, D, H - WALL),
    );
    push_box(
        m.object("casing/back"),
        v(WALL, D - WALL, WALL),
        v(W - WALL, D, H - WALL),
    );
    let front = m.object("casing/front");
    let (x0, x1, z0, z1) = (OPEN_X.0, OPEN_X.1, OPEN_Z.0, OPEN_Z.1);
    push_box(front, v(WALL, 0.0, WALL), v(W - WALL, WALL, z0));
    push_box(front, v(WALL, 0.0, z1), v(W - WALL, WALL, H - WALL));
    push_box(front, v(WALL, 0.0, z0), v(x0, WALL, z1));
    push_box(front, v(x1, 0.0, z0), v(W - WALL, WALL, z1));
    // Ten slats 18 mm high, 12 mm apart.
    let grating = m.object("casing/grating");
    for k in 0..10 {
        let z = z0 + 0.012 + 0.03 * k as f32;
        push_box(grating, v(x0, 0.0, z), v(x1, WALL, z + 0.018));
    }
    // Inside: x in (WALL, W - WALL), y in (WALL, D - WALL), z in (WALL, H - WALL).
    let inner = |rng: &mut Pcg64, margin: f32| {
        v(
            rng.random_range(WALL + margin..W - WALL - margin),
            rng.random_range(WALL + margin + 0.03..D - WALL - margin),
            rng.random_range(WALL + margin..H - WALL - margin),
        )
    };
    for k in 0..12 {
        let z = 0.1 + 0.06 * k as f32;
        let y = rng.random_range(0.15..0.55f32);
        push_cylinder(
            m.object(format!("roller_{k}")),
            v(0.1, y, z),
            Vec3::X * 1.0,
            0.02,
            10,
        );
    }
    for k in 0..30 {
        let c = inner(rng, 0.08);
        let r = rng.random_range(0.02..0.07f32);
        push_cylinder(m.object(format!("gear_{k}")), c, Vec3::Y * 0.015, r, 12);
    }
    for k in 0..8 {
        let c = inner(rng, 0.1);
        let motor = m.object(format!("motor_{k}"));
        push_box(motor, c - v(0.04, 0.04, 0.04), c + v(0.04, 0.04, 0.04));
        push_cylinder(motor, c + v(0.04, 0.0, 0.0), Vec3::X * 0.05, 0.006, 6);
    }
    for k in 0..16 {
        let c = inner(rng, 0.06);
        let len = rng.random_range(0.1..0.5f32);
        let dir = [Vec3::X, Vec3::Y, Vec3::Z][rng.random_range(0..3usize)];
        let start = (c - dir * len * 0.5).clamp(
            v(WALL, 0.05, WALL),
            v(W - WALL, D - WALL, H - WALL) - dir * len,
        );
        push_cylinder(m.object(format!("shaft_{k}")), start, dir * len, 0.005, 6);
    }
    let mut chip = 0;
    for k in 0..6 {
        let c = v(
            rng.random_range(0.15..1.05f32),
            D - WALL - 0.03,
            rng.random_range(0.15..0.75f32),
        );
        push_box(
            m.object(format!("board_{k}")),
            c - v(0.1, 0.002, 0.07),
            c + v(0.1, 0.0, 0.07),
        );
        for _ in 0..rng.random_range(8..14) {
            let p = c + v(
                rng.random_range(-0.08..0.08f32),
                -0.002,
                rng.random_range(-0.05..0.05f32),
            );
            push_box(
                m.object(format!("chip_{chip}")),
                p - v(0.012, 0.006, 0.012),
                p + v(0.012, 0.0, 0.012),
            );
            chip += 1;
        }
    }
    for k in 0..4 {
        let z = 0.08 + 0.2 * k as f32;
        push_box(
            m.object(format!("tray_{k}")),
            v(0.2, 0.3, z),
            v(1.0, 0.65, z + 0.01),
        );
    }
    m
}
