//! `office`: one floor of twelve offices, six on each side of a corridor
//! along x, each with a door to the corridor, desks, chairs, monitors, a
//! cabinet and a whiteboard; the floor is sealed by outer walls, floor and
//! ceiling. From a room one sees the room, a slice of the corridor through
//! the door, and through the opposite door a slice of the room across.

use glam::{Vec2, Vec3};
use rand::RngExt;
use rand_pcg::Pcg64;

use super::Model;
use super::shapes::{push_box, push_cylinder, push_ellipsoid};

const T: f32 = 0.12;
const H: f32 = 3.0;
const ROOMS: usize = 6;
const ROOM_W: f32 = 4.0;
const ROOM_D: f32 = 5.0;
const CORRIDOR: f32 = 2.2;
const DOOR_W: f32 = 0.9;
const DOOR_H: f32 = 2.1;

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

pub(super) fn generate(rng: &mut Pcg64) -> Model {
    let mut m = Model::default();
    let w = ROOMS as f32 * (ROOM_W + T) + T;
    let d = 2.0 * ROOM_D + CORRIDOR + 4.0 * T;
    push_box(m.object("floor"), v(0.0, 0.0, -T), v(w, d, 0.0));
    push_box(m.object("ceiling"), v(0.0, 0.0, H), v(w, d, H + T));
    push_box(m.object("wall_south"), v(0.0, 0.0, 0.0), v(w, T, H));
    push_box(m.object("wall_north"), v(0.0, d - T, 0.0), v(w, d, H));
    push_box(m.object("wall_west"), v(0.0, T, 0.0), v(T, d - T, H));
    push_box(m.object("wall_east"), v(w - T, T, 0.0), v(w, d - T, H));
    // Corridor walls: y ranges of the two walls that face the corridor.
    let south_wall = (T + ROOM_D, 2.0 * T + ROOM_D);
    let north_wall = (d - 2.0 * T - ROOM_D, d - T - ROOM_D);
    for (side, (y0, y1), room_y0) in [
        ("south", south_wall, T),
        ("north", north_wall, north_wall.1),
    ] {
        for r in 0..ROOMS {
            let x0 = T + r as f32 * (ROOM_W + T);
            let name = format!("{side}_{r}");
            // The corridor wall of this room, with a door near one end.
            let door = x0 + rng.random_range(0.3..(ROOM_W - DOOR_W - 0.3));
            let wall = m.object(format!("{name}/corridor_wall"));
            push_box(wall, v(x0 - T, y0, 0.0), v(door, y1, H));
            push_box(wall, v(door + DOOR_W, y0, 0.0), v(x0 + ROOM_W, y1, H));
            push_box(wall, v(door, y0, DOOR_H), v(door + DOOR_W, y1, H));
            if r > 0 {
                push_box(
                    m.object(format!("{name}/partition")),
                    v(x0 - T, room_y0, 0.0),
                    v(x0, room_y0 + ROOM_D, H),
                );
            }
            furnish(&mut m, rng, &name, v(x0, room_y0, 0.0), side == "north");
        }
    }
    m
}

/// Furniture of one room whose interior starts at `o`; `flip` mirrors it
/// in y so that desks face away from the corridor in both rows.
fn furnish(m: &mut Model, rng: &mut Pcg64, name: &str, o: Vec3, flip: bool) {
    // 1 mm off floors and walls, as in the apartment: no coincident faces.
    let p = |x: f32, y: f32, z: f32| {
        let y = if flip { ROOM_D - y } else { y };
        o + Vec3::splat(0.001) + v(x, y, z) * 0.9996
    };
    let bx = |m: &mut Model, obj: &str, a: Vec3, b: Vec3| {
        push_box(m.object(format!("{name}/{obj}")), a.min(b), a.max(b))
    };
    let desks = rng.random_range(2..=3usize);
    for k in 0..desks {
        let x = 0.3 + k as f32 * 1.3 + rng.random_range(0.0..0.1f32);
        let desk = format!("desk_{k}");
        let tris = m.object(format!("{name}/{desk}"));
        let (a, b) = (p(x, 0.1, 0.72), p(x + 1.2, 0.8, 0.75));
        push_box(tris, a.min(b), a.max(b));
        for (lx, ly) in [(0.05, 0.15), (1.1, 0.15), (0.05, 0.7), (1.1, 0.7)] {
            let (a, b) = (p(x + lx, ly, 0.0), p(x + lx + 0.05, ly + 0.05, 0.72));
            push_box(tris, a.min(b), a.max(b));
        }
        bx(
            m,
            &format!("monitor_{k}"),
            p(x + 0.3, 0.2, 0.8),
            p(x + 0.9, 0.23, 1.15),
        );
        bx(
            m,
            &format!("keyboard_{k}"),
            p(x + 0.38, 0.4, 0.75),
            p(x + 0.82, 0.55, 0.77),
        );
        let chair = m.object(format!("{name}/chair_{k}"));
        let c = p(x + 0.6, 1.2, 0.0) + v(rng.random_range(-0.1..0.1f32), 0.0, 0.0);
        push_cylinder(chair, c, Vec3::Z * 0.45, 0.04, 6);
        push_cylinder(chair, c + Vec3::Z * 0.45, Vec3::Z * 0.06, 0.24, 8);
        // The back is on the side away from the desk.
        let bc = c + v(0.0, if flip { -0.22 } else { 0.22 }, 0.0);
        push_box(chair, bc + v(-0.22, -0.02, 0.5), bc + v(0.22, 0.02, 0.95));
    }
    bx(
        m,
        "cabinet",
        p(ROOM_W - 0.5, 0.1, 0.0),
        p(ROOM_W - 0.05, 1.3, 1.1),
    );
    bx(
        m,
        "whiteboard",
        p(0.5, ROOM_D - 0.02, 1.0),
        p(2.5, ROOM_D, 2.0),
    );
    if rng.random_bool(0.7) {
        let plant = m.object(format!("{name}/plant"));
        let c = p(ROOM_W - 0.4, ROOM_D - 0.9, 0.0);
        push_cylinder(plant, c, Vec3::Z * 0.4, 0.2, 8);
        push_ellipsoid(plant, c + Vec3::Z * 0.9, v(0.3, 0.3, 0.5), 4, 6);
    }
    let lamp = Vec2::new(ROOM_W / 2.0, ROOM_D / 2.0);
    bx(
        m,
        "ceiling_light",
        p(lamp.x - 0.6, lamp.y - 0.15, H - 0.05),
        p(lamp.x + 0.6, lamp.y + 0.15, H),
    );
}
