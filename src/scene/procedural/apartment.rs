//! `apartment`: a living room and a bedroom joined by a door, sealed by
//! walls, floor and ceiling, furnished down to books and cups: about 170
//! objects and 3,000 triangles, like the 159-object, 3,061-polygon
//! apartment of papers/003 sec. 8.
//!
//! Layout (metres, z up): living room interior x in [0.15, 6.15], bedroom
//! interior x in [6.3, 10.3], both y in [0.15, 5.15], ceiling at 2.6. The
//! shared wall at x in [6.15, 6.3] has a 0.9 m wide, 2.1 m high door at
//! y in [3.75, 4.65], whose leaf stands open into the bedroom. Furniture
//! keeps 1 mm from floors and walls (see `inset`).

use glam::{Vec2, Vec3};
use rand::RngExt;
use rand_pcg::Pcg64;

use super::Model;
use super::shapes::{push_box, push_cone, push_cylinder, push_ellipsoid};
use crate::scene::Triangle;

/// Wall thickness.
const T: f32 = 0.15;
/// Ceiling height.
const H: f32 = 2.6;
/// Interior depth (y) of both rooms.
const D: f32 = 5.0;
/// Interior widths (x) of the living room and the bedroom.
const LIVING_W: f32 = 6.0;
const BED_W: f32 = 4.0;
/// The door in the shared wall, interior y range.
const DOOR_Y: (f32, f32) = (3.6, 4.5);
const DOOR_H: f32 = 2.1;

pub(super) fn generate(rng: &mut Pcg64) -> Model {
    let mut m = Model::default();
    shell(&mut m);
    let living = Vec3::new(T, T, 0.0);
    let bedroom = Vec3::new(LIVING_W + 2.0 * T, T, 0.0);
    living_room(&mut m, rng, living);
    bed_room(&mut m, rng, bedroom);
    m
}

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// Walls, floors, ceilings and the door leaf.
fn shell(m: &mut Model) {
    let w = LIVING_W + BED_W + 3.0 * T;
    let d = D + 2.0 * T;
    let mid = LIVING_W + 1.5 * T;
    let (sx0, sx1) = (LIVING_W + T, LIVING_W + 2.0 * T);
    push_box(
        m.object("living/wall_south"),
        v(0.0, 0.0, 0.0),
        v(mid, T, H),
    );
    push_box(
        m.object("living/wall_north"),
        v(0.0, d - T, 0.0),
        v(mid, d, H),
    );
    push_box(m.object("living/wall_west"), v(0.0, T, 0.0), v(T, d - T, H));
    push_box(m.object("bedroom/wall_south"), v(mid, 0.0, 0.0), v(w, T, H));
    push_box(
        m.object("bedroom/wall_north"),
        v(mid, d - T, 0.0),
        v(w, d, H),
    );
    push_box(
        m.object("bedroom/wall_east"),
        v(w - T, T, 0.0),
        v(w, d - T, H),
    );
    let shared = m.object("wall_shared");
    let (dy0, dy1) = (T + DOOR_Y.0, T + DOOR_Y.1);
    push_box(shared, v(sx0, T, 0.0), v(sx1, dy0, H));
    push_box(shared, v(sx0, dy1, 0.0), v(sx1, d - T, H));
    push_box(shared, v(sx0, dy0, DOOR_H), v(sx1, dy1, H));
    push_box(m.object("living/floor"), v(0.0, 0.0, -T), v(mid, d, 0.0));
    push_box(m.object("living/ceiling"), v(0.0, 0.0, H), v(mid, d, H + T));
    push_box(m.object("bedroom/floor"), v(mid, 0.0, -T), v(w, d, 0.0));
    push_box(m.object("bedroom/ceiling"), v(mid, 0.0, H), v(w, d, H + T));
    // The door leaf, open at 90 degrees against the shared wall.
    push_box(
        m.object("bedroom/door"),
        v(sx1, dy1 - 0.04, 0.01),
        v(sx1 + 0.88, dy1, DOOR_H - 0.02),
    );
}

/// A table: a top of `size` (x, y) at `height`, four legs.
fn table(tris: &mut Vec<Triangle>, c: Vec3, size: Vec2, height: f32) {
    let (hx, hy, leg) = (size.x * 0.5, size.y * 0.5, 0.05);
    push_box(tris, c + v(-hx, -hy, height - 0.04), c + v(hx, hy, height));
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        let p = c + v(sx * (hx - 0.06), sy * (hy - 0.06), 0.0);
        push_box(
            tris,
            p - v(leg / 2.0, leg / 2.0, 0.0),
            p + v(leg / 2.0, leg / 2.0, height - 0.04),
        );
    }
}

/// A chair at `c` whose back is on the side `back` (a unit axis vector in
/// the xy plane): a seat on two side panels, and a back.
fn chair(tris: &mut Vec<Triangle>, c: Vec3, back: Vec2) {
    push_box(tris, c - v(0.21, 0.21, -0.42), c + v(0.21, 0.21, 0.46));
    let side = Vec2::new(back.y.abs(), back.x.abs());
    let along = back.abs();
    for s in [-1.0, 1.0] {
        let p = c + (side * (s * 0.19)).extend(0.0);
        let half = (side * 0.02 + along * 0.21).extend(0.0);
        push_box(tris, p - half, p + half + v(0.0, 0.0, 0.42));
    }
    let b = c + (back * 0.19).extend(0.0);
    let half = (side * 0.21 + along * 0.02).extend(0.0);
    push_box(
        tris,
        b - half + v(0.0, 0.0, 0.46),
        b + half + v(0.0, 0.0, 0.92),
    );
}

/// A row of books standing from `start` along +`dir` (x or y unit) for
/// `length` metres, each its own object, `depth` deep, up to `max_h` high.
#[allow(clippy::too_many_arguments)]
fn books(
    m: &mut Model,
    rng: &mut Pcg64,
    name: &str,
    first: &mut u32,
    start: Vec3,
    dir: Vec2,
    length: f32,
    max_h: f32,
) {
    let across = Vec2::new(dir.y.abs(), dir.x.abs());
    // Shelves are partly filled.
    let length = length * rng.random_range(0.45..0.75f32);
    let mut s = 0.0;
    loop {
        let thick = rng.random_range(0.02..0.06f32);
        let h = rng.random_range(0.6..1.0f32) * max_h;
        let depth = rng.random_range(0.14..0.22f32);
        if s + thick > length {
            break;
        }
        let a = start + (dir * s).extend(0.0);
        let b = a + (dir * thick + across * depth).extend(h);
        push_box(
            m.object(format!("{name}/book_{}", *first)),
            a.min(b),
            a.max(b),
        );
        *first += 1;
        s += thick + rng.random_range(0.0..0.01f32);
    }
}

/// A lamp on a surface at `c`: a foot, a stem and a conical shade.
fn lamp(tris: &mut Vec<Triangle>, c: Vec3, height: f32) {
    push_cylinder(tris, c, Vec3::Z * 0.03, 0.1, 6);
    push_box(tris, c - v(0.012, 0.012, 0.0), c + v(0.012, 0.012, height));
    push_cone(tris, c + Vec3::Z * (height - 0.15), Vec3::Z * 0.3, 0.2, 6);
}

/// A potted plant: a pot and an ellipsoid of foliage.
fn plant(tris: &mut Vec<Triangle>, c: Vec3, height: f32) {
    push_cylinder(tris, c, Vec3::Z * 0.35, 0.18, 6);
    push_ellipsoid(
        tris,
        c + Vec3::Z * (0.35 + height * 0.5),
        v(0.3, 0.3, height * 0.5),
        4,
        6,
    );
}

/// A point of a room's furniture: room-local coordinates (from the
/// interior's low corner) shrunk by 1 mm per 2.5 m and shifted 1 mm in, so
/// that nothing stands exactly on the floor or against a wall. Coincident
/// faces make visibility a matter of rounding (z-fighting): from inside a
/// floor slab, a chair's feet would show through its top face.
fn inset(room: Vec3, local: Vec3) -> Vec3 {
    room + Vec3::splat(0.001) + local * 0.9996
}

fn jitter(rng: &mut Pcg64, r: f32) -> Vec3 {
    v(rng.random_range(-r..r), rng.random_range(-r..r), 0.0)
}

fn living_room(m: &mut Model, rng: &mut Pcg64, o: Vec3) {
    let p = |x: f32, y: f32, z: f32| inset(o, v(x, y, z));
    push_box(m.object("living/rug"), p(1.8, 1.4, 0.0), p(4.2, 3.0, 0.01));
    // Sofa against the south wall, three cushions.
    let sofa = m.object("living/sofa");
    push_box(sofa, p(1.4, 0.05, 0.0), p(3.6, 0.95, 0.42));
    push_box(sofa, p(1.4, 0.05, 0.42), p(3.6, 0.27, 0.9));
    push_box(sofa, p(1.4, 0.05, 0.42), p(1.6, 0.95, 0.62));
    push_box(sofa, p(3.4, 0.05, 0.42), p(3.6, 0.95, 0.62));
    for k in 0..3 {
        let x = 1.62 + 0.59 * k as f32;
        push_box(
            m.object(format!("living/cushion_{k}")),
            p(x, 0.3, 0.42),
            p(x + 0.57, 0.92, 0.52),
        );
    }
    // Coffee table with cups, a vase and magazines.
    let ct = p(2.5, 2.1, 0.0) + jitter(rng, 0.1);
    table(
        m.object("living/coffee_table"),
        ct,
        Vec2::new(1.1, 0.6),
        0.42,
    );
    for k in 0..2 {
        let c = ct + v(-0.3 + 0.6 * k as f32, 0.1, 0.42) + jitter(rng, 0.05);
        push_cylinder(
            m.object(format!("living/cup_{k}")),
            c,
            Vec3::Z * 0.1,
            0.04,
            6,
        );
    }
    push_cylinder(
        m.object("living/vase"),
        ct + v(0.0, -0.1, 0.42),
        Vec3::Z * 0.3,
        0.07,
        8,
    );
    for k in 0..3 {
        let c = ct + v(0.25, -0.15, 0.42 + 0.012 * k as f32) + jitter(rng, 0.03);
        push_box(
            m.object(format!("living/magazine_{k}")),
            c,
            c + v(0.21, 0.28, 0.01),
        );
    }
    // TV stand and TV against the north wall.
    push_box(
        m.object("living/tv_stand"),
        p(1.7, 4.55, 0.0),
        p(3.3, 5.0, 0.5),
    );
    let tv = m.object("living/tv");
    push_box(tv, p(2.35, 4.7, 0.5), p(2.65, 4.85, 0.53));
    push_box(tv, p(2.48, 4.76, 0.53), p(2.52, 4.8, 0.6));
    push_box(tv, p(1.85, 4.74, 0.6), p(3.15, 4.8, 1.35));
    // Dining table with four chairs, plates, glasses and a bowl.
    let dt = p(5.0, 2.4, 0.0) + jitter(rng, 0.1);
    table(
        m.object("living/dining_table"),
        dt,
        Vec2::new(0.8, 1.2),
        0.75,
    );
    let seats = [(-0.6, -0.3), (-0.6, 0.3), (0.6, -0.3), (0.6, 0.3)];
    for (k, (dx, dy)) in seats.into_iter().enumerate() {
        let back = Vec2::new(f32::signum(dx), 0.0);
        chair(
            m.object(format!("living/chair_{k}")),
            dt + v(dx, dy, 0.0),
            back,
        );
        let plate = dt + v(dx * 0.45, dy, 0.75);
        push_cylinder(
            m.object(format!("living/plate_{k}")),
            plate,
            Vec3::Z * 0.02,
            0.11,
            8,
        );
        let glass = plate + v(-dx * 0.12, 0.15, 0.0);
        push_cylinder(
            m.object(format!("living/glass_{k}")),
            glass,
            Vec3::Z * 0.12,
            0.035,
            6,
        );
    }
    push_ellipsoid(
        m.object("living/bowl"),
        dt + v(0.0, 0.0, 0.8),
        v(0.12, 0.12, 0.05),
        3,
        6,
    );
    // Bookshelf against the west wall, five levels of books.
    let shelf = m.object("living/bookshelf");
    let (y0, y1, top) = (1.5, 2.7, 2.0);
    push_box(shelf, p(0.0, y0, 0.0), p(0.35, y0 + 0.03, top));
    push_box(shelf, p(0.0, y1 - 0.03, 0.0), p(0.35, y1, top));
    push_box(shelf, p(0.0, y0, 0.0), p(0.02, y1, top));
    for k in 0..6 {
        let z = 0.38 * k as f32;
        push_box(shelf, p(0.0, y0 + 0.03, z), p(0.35, y1 - 0.03, z + 0.03));
    }
    let mut n = 0;
    for k in 0..5 {
        let z = 0.38 * k as f32 + 0.03;
        let start = p(0.03, y0 + 0.04, z);
        books(
            m,
            rng,
            "living",
            &mut n,
            start,
            Vec2::Y,
            y1 - y0 - 0.08,
            0.33,
        );
    }
    // Sideboard along the shared wall with three ornaments.
    push_box(
        m.object("living/sideboard"),
        p(5.55, 0.3, 0.0),
        p(6.0, 2.0, 0.8),
    );
    for k in 0..3 {
        let c = p(5.77, 0.55 + 0.55 * k as f32, 0.8);
        push_ellipsoid(
            m.object(format!("living/ornament_{k}")),
            c + Vec3::Z * 0.1,
            Vec3::splat(0.08),
            3,
            6,
        );
    }
    plant(m.object("living/plant_0"), p(0.4, 4.6, 0.0), 1.0);
    plant(m.object("living/plant_1"), p(4.0, 0.35, 0.0), 0.8);
    lamp(m.object("living/floor_lamp"), p(0.6, 0.5, 0.0), 1.6);
    push_box(
        m.object("living/picture_0"),
        p(2.0, 0.0, 1.3),
        p(3.0, 0.02, 1.9),
    );
    push_box(
        m.object("living/picture_1"),
        p(0.0, 3.3, 1.2),
        p(0.02, 4.3, 1.8),
    );
    push_ellipsoid(
        m.object("living/ceiling_lamp"),
        p(3.0, 2.5, H - 0.15),
        v(0.25, 0.25, 0.12),
        3,
        6,
    );
}

fn bed_room(m: &mut Model, rng: &mut Pcg64, o: Vec3) {
    let p = |x: f32, y: f32, z: f32| inset(o, v(x, y, z));
    push_box(m.object("bedroom/rug"), p(1.0, 1.0, 0.0), p(2.0, 3.6, 0.01));
    // Bed with its head against the east wall.
    let bed = m.object("bedroom/bed");
    push_box(bed, p(1.95, 1.5, 0.0), p(3.95, 3.1, 0.3));
    push_box(bed, p(3.9, 1.5, 0.0), p(3.98, 3.1, 1.0));
    push_box(
        m.object("bedroom/mattress"),
        p(2.0, 1.55, 0.3),
        p(3.9, 3.05, 0.5),
    );
    push_box(
        m.object("bedroom/blanket"),
        p(2.0, 1.52, 0.5),
        p(3.2, 3.08, 0.55),
    );
    for k in 0..2 {
        let y = 1.65 + 0.72 * k as f32;
        push_box(
            m.object(format!("bedroom/pillow_{k}")),
            p(3.35, y, 0.5),
            p(3.85, y + 0.65, 0.62),
        );
    }
    for (k, y) in [0.95f32, 3.15].into_iter().enumerate() {
        push_box(
            m.object(format!("bedroom/nightstand_{k}")),
            p(3.5, y, 0.0),
            p(3.95, y + 0.45, 0.5),
        );
        lamp(
            m.object(format!("bedroom/lamp_{k}")),
            p(3.72, y + 0.22, 0.5),
            0.45,
        );
    }
    // Wardrobe against the north wall.
    let wardrobe = m.object("bedroom/wardrobe");
    push_box(wardrobe, p(0.2, 4.4, 0.0), p(1.8, 5.0, 2.1));
    push_box(wardrobe, p(0.22, 4.37, 0.05), p(0.99, 4.4, 2.05));
    push_box(wardrobe, p(1.01, 4.37, 0.05), p(1.78, 4.4, 2.05));
    // Desk against the south wall: chair, monitor, keyboard, books, lamp.
    let desk = p(1.0, 0.35, 0.0);
    table(m.object("bedroom/desk"), desk, Vec2::new(1.4, 0.7), 0.74);
    chair(
        m.object("bedroom/desk_chair"),
        desk + v(0.0, 0.65, 0.0) + jitter(rng, 0.08),
        Vec2::Y,
    );
    let monitor = m.object("bedroom/monitor");
    push_box(
        monitor,
        desk + v(-0.1, -0.2, 0.74),
        desk + v(0.1, -0.08, 0.76),
    );
    push_box(
        monitor,
        desk + v(-0.02, -0.16, 0.76),
        desk + v(0.02, -0.12, 0.9),
    );
    push_box(
        monitor,
        desk + v(-0.3, -0.17, 0.85),
        desk + v(0.3, -0.14, 1.2),
    );
    push_box(
        m.object("bedroom/keyboard"),
        desk + v(-0.22, 0.05, 0.74),
        desk + v(0.22, 0.2, 0.76),
    );
    let mut n = 0;
    books(
        m,
        rng,
        "bedroom",
        &mut n,
        desk + v(0.4, -0.3, 0.74),
        Vec2::X,
        0.25,
        0.25,
    );
    lamp(
        m.object("bedroom/desk_lamp"),
        desk + v(-0.55, -0.15, 0.74),
        0.4,
    );
    // A wall shelf above the desk.
    push_box(
        m.object("bedroom/wall_shelf"),
        p(0.2, 0.0, 1.5),
        p(1.8, 0.25, 1.53),
    );
    books(
        m,
        rng,
        "bedroom",
        &mut n,
        p(0.25, 0.02, 1.53),
        Vec2::X,
        1.5,
        0.3,
    );
    push_box(
        m.object("bedroom/picture"),
        p(3.98, 1.8, 1.3),
        p(4.0, 2.8, 1.8),
    );
    push_ellipsoid(
        m.object("bedroom/ceiling_lamp"),
        p(2.0, 2.5, H - 0.15),
        v(0.25, 0.25, 0.12),
        3,
        6,
    );
    push_cylinder(
        m.object("bedroom/basket"),
        p(2.4, 4.6, 0.0),
        Vec3::Z * 0.5,
        0.2,
        6,
    );
    plant(m.object("bedroom/plant"), p(3.6, 4.6, 0.0), 0.9);
    for k in 0..2 {
        let x = 1.2 + 0.18 * k as f32;
        push_box(
            m.object(format!("bedroom/shoe_{k}")),
            p(x, 3.8, 0.0),
            p(x + 0.1, 4.1, 0.1),
        );
    }
}
