//! The report's pictures (issue 18): a view's ID buffer drawn in flat
//! shades, one per object, with the pixels of the objects a method did
//! not draw in red, so that what popping would look like is seen, not
//! read; and per method, what it would draw at each pixel ([`Layers`],
//! [`drawn_picture`]): how many of its objects each pixel's ray passes
//! (overdraw) and where it pops. The pixels are RGB bytes; `vis5d report`
//! writes them as PNG.

use glam::Vec3;

use crate::bitset::ObjectSet;
use crate::render::{Camera, IdBuffer};
use crate::scene::Scene;
use crate::trace::{Ray, Tracer};
use crate::tree::VisTree;

/// What a pixel whose object was dropped is painted: pure red, which no
/// object's shade comes near ([`object_shade`] keeps its hues away from
/// red).
pub const DROPPED: [u8; 3] = [255, 0, 0];

/// What a pixel that sees nothing is painted.
pub const BACKGROUND: [u8; 3] = [32, 36, 40];

/// An RGB image, row by row from the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Picture {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Three bytes a pixel (red, green, blue), row by row from the top.
    pub rgb: Vec<u8>,
}

impl Picture {
    /// The colour of pixel `(i, j)` (column, row from the top).
    pub fn get(&self, i: u32, j: u32) -> [u8; 3] {
        let k = 3 * (j as usize * self.width as usize + i as usize);
        [self.rgb[k], self.rgb[k + 1], self.rgb[k + 2]]
    }

    /// The pixels of colour `c`.
    pub fn count(&self, c: [u8; 3]) -> u64 {
        self.rgb.chunks_exact(3).filter(|p| **p == c).count() as u64
    }

    /// The picture shrunk by a whole factor so that neither side passes
    /// `side` (each pixel the mean of the block it covers; the picture
    /// itself when it fits): a thumbnail. A red pixel stays visible: a
    /// block with any dropped pixel is painted [`DROPPED`].
    pub fn shrunk(&self, side: u32) -> Picture {
        let f = self.width.max(self.height).div_ceil(side.max(1)).max(1);
        if f == 1 {
            return self.clone();
        }
        let (w, h) = (self.width.div_ceil(f), self.height.div_ceil(f));
        let mut rgb = Vec::with_capacity(3 * (w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let (mut sum, mut n, mut dropped) = ([0u32; 3], 0u32, false);
                for j in y * f..((y + 1) * f).min(self.height) {
                    for i in x * f..((x + 1) * f).min(self.width) {
                        let p = self.get(i, j);
                        dropped |= p == DROPPED;
                        for (s, v) in sum.iter_mut().zip(p) {
                            *s += u32::from(v);
                        }
                        n += 1;
                    }
                }
                if dropped {
                    rgb.extend(DROPPED);
                } else {
                    rgb.extend(sum.map(|s| ((s + n / 2) / n) as u8));
                }
            }
        }
        Picture {
            width: w,
            height: h,
            rgb,
        }
    }
}

/// The picture of `ids`: each object in its shade ([`object_shade`]),
/// the objects of `dropped` (seen, not drawn) in [`DROPPED`], nothing in
/// [`BACKGROUND`].
pub fn picture(ids: &IdBuffer, dropped: &[u32]) -> Picture {
    let mut rgb = Vec::with_capacity(3 * (ids.width() * ids.height()) as usize);
    for (_, o) in ids.pixels() {
        rgb.extend(match o {
            None => BACKGROUND,
            Some(o) if dropped.contains(&o) => DROPPED,
            Some(o) => object_shade(o),
        });
    }
    Picture {
        width: ids.width(),
        height: ids.height(),
        rgb,
    }
}

/// Object `o`'s flat shade: a hue between orange and purple (never red),
/// spread by the golden ratio so that neighbours in the file differ, at a
/// lightness and saturation of its own.
pub fn object_shade(o: u32) -> [u8; 3] {
    // Hues 40 to 320 degrees: red (and the reds around it) is DROPPED's.
    let spread = (f64::from(o) * 0.618_033_988_749_895).fract();
    let hue = 40.0 + 280.0 * spread;
    let lightness = [0.55, 0.68, 0.45, 0.62][(o % 4) as usize];
    let saturation = [0.45, 0.30, 0.55][(o % 3) as usize];
    hsl(hue, saturation, lightness)
}

/// HSL (hue in degrees, saturation and lightness in [0, 1]) to RGB bytes.
fn hsl(hue: f64, s: f64, l: f64) -> [u8; 3] {
    let c = (1.0 - (2.0 * l - 1.0).abs()) * s;
    let h = hue / 60.0;
    let x = c * (1.0 - (h % 2.0 - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = l - c / 2.0;
    [r, g, b].map(|v| ((v + m) * 255.0).round().clamp(0.0, 255.0) as u8)
}

/// The most objects a pixel's [`Layers`] list (the farther ones are left
/// out; the pictures' scale ends at [`LAYER_SHADES`]' length anyway).
pub const MAX_LAYERS: usize = 64;

/// The most surfaces a pixel's ray passes before [`Layers`] stops (an
/// object of many triangles along one ray counts each).
const MAX_STEPS: usize = 256;

/// The longest side of a picture of what a method draws
/// ([`drawn_picture`]): these show counts, not shapes, and cost a ray
/// per surface a pixel passes.
pub const DRAWN_SIDE: u32 = 200;

/// Per pixel of a camera, every object its ray passes through, nearest
/// first (each once): what a renderer drawing a set of objects would
/// draw there, for any set ([`drawn_picture`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layers {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Where each pixel's objects start in `objects` (one more entry than
    /// pixels).
    starts: Vec<u32>,
    objects: Vec<u32>,
}

impl Layers {
    /// Casts each pixel's centre ray of `camera` on through every surface
    /// (the next hit from just beyond the last, by the exact tracer), up
    /// to [`MAX_LAYERS`] objects and 256 surfaces.
    pub fn render(tracer: &Tracer, camera: &Camera) -> Layers {
        use rayon::prelude::*;
        let rows: Vec<Vec<Vec<u32>>> = (0..camera.height)
            .into_par_iter()
            .map(|j| {
                (0..camera.width)
                    .map(|i| {
                        let ray = camera.pixel_ray(i, j);
                        let mut seen = Vec::new();
                        let mut tmin = ray.tmin;
                        for _ in 0..MAX_STEPS {
                            let Some(hit) = tracer.closest_hit(&ray.with_tmin(tmin)) else {
                                break;
                            };
                            if !seen.contains(&hit.object) {
                                seen.push(hit.object);
                                if seen.len() == MAX_LAYERS {
                                    break;
                                }
                            }
                            tmin = hit.t.next_up();
                        }
                        seen
                    })
                    .collect()
            })
            .collect();
        let mut starts = vec![0u32];
        let mut objects = Vec::new();
        for pixel in rows.into_iter().flatten() {
            objects.extend(pixel);
            starts.push(objects.len() as u32);
        }
        Layers {
            width: camera.width,
            height: camera.height,
            starts,
            objects,
        }
    }

    /// The objects along pixel `k` (row by row from the top), nearest
    /// first.
    pub fn pixel(&self, k: usize) -> &[u32] {
        &self.objects[self.starts[k] as usize..self.starts[k + 1] as usize]
    }
}

/// The shades of [`drawn_picture`]: one object drawn at a pixel (pale
/// yellow) to nine or more (deep purple), a viridis scale that keeps
/// clear of red.
pub const LAYER_SHADES: [[u8; 3]; 9] = [
    [253, 231, 37],
    [181, 222, 43],
    [110, 206, 88],
    [53, 183, 121],
    [31, 158, 137],
    [38, 130, 142],
    [49, 104, 142],
    [62, 73, 137],
    [72, 40, 120],
];

/// What a method drawing `set` draws, as a picture of `layers`' pixels:
/// each pixel tinted by how many objects of the set its ray passes
/// ([`LAYER_SHADES`]: one is what exact visibility draws, more is
/// overdraw), in [`DROPPED`] where the object seen there is not in the
/// set (it would pop), [`BACKGROUND`] where the ray meets nothing. With
/// the mean number of the set's objects a pixel that sees something
/// passes (its depth complexity; the dropped pixels count what the set
/// draws there too).
pub fn drawn_picture(layers: &Layers, set: &ObjectSet) -> (Picture, f64) {
    let n = (layers.width * layers.height) as usize;
    let mut rgb = Vec::with_capacity(3 * n);
    let (mut sum, mut hit) = (0u64, 0u64);
    for k in 0..n {
        let along = layers.pixel(k);
        let drawn = along.iter().filter(|&&o| set.contains(o as usize)).count();
        rgb.extend(match along.first() {
            None => BACKGROUND,
            Some(&o) if !set.contains(o as usize) => DROPPED,
            Some(_) => LAYER_SHADES[drawn.min(LAYER_SHADES.len()) - 1],
        });
        if !along.is_empty() {
            hit += 1;
            sum += drawn as u64;
        }
    }
    let picture = Picture {
        width: layers.width,
        height: layers.height,
        rgb,
    };
    (
        picture,
        if hit > 0 {
            sum as f64 / hit as f64
        } else {
            0.0
        },
    )
}

/// The map's outlines of the tree's cells (half blended over the pixel).
pub const OUTLINE: [u8; 3] = [16, 16, 24];

/// The map's eyes.
pub const EYE: [u8; 3] = [255, 255, 255];

/// A top-down map of a tree's view box ([`map`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Map {
    /// The picture, north (+y) up.
    pub picture: Picture,
    /// The height of the cut through the tree, in the tree's frame.
    pub height: f32,
    /// The distinct boxes of positions drawn: the leaves that reach that
    /// height, seen from above.
    pub cells: usize,
    /// The largest set among them.
    pub largest_set: usize,
    /// Whether the eyes are joined in order (a camera path).
    pub joined: bool,
}

/// A map of `tree`'s view box seen from above (down the scene's up axis,
/// local z), `side` pixels along its longer side: the scene beneath (the
/// top-down ray cast's objects, shaded darker), the leaves that reach
/// height `z` (the mean of `eyes`' heights, or the view box's middle)
/// outlined, each tinted blue the more objects its set holds (where
/// leaves of other directions overlap, the largest), and the `eyes` as
/// white dots, joined in order when `joined` (a camera path).
pub fn map(
    scene: &Scene,
    tracer: &Tracer,
    tree: &VisTree,
    eyes: &[Vec3],
    joined: bool,
    side: u32,
) -> Map {
    let space = tree.root_cell().space();
    let (lo, size) = (space.min, space.max - space.min);
    let side = side.max(2);
    let (w, h) = if size.x >= size.y {
        (
            side,
            ((side as f32 * size.y / size.x).round() as u32).max(1),
        )
    } else {
        (
            ((side as f32 * size.x / size.y).round() as u32).max(1),
            side,
        )
    };
    // Pixel (i, j), row 0 at the north (+y) edge, and back.
    let to_xy = |i: f32, j: f32| {
        Vec3::new(
            lo.x + size.x * i / w as f32,
            lo.y + size.y * (1.0 - j / h as f32),
            0.0,
        )
    };
    let to_pixel = |p: Vec3| {
        (
            ((p.x - lo.x) / size.x * w as f32).floor() as i64,
            ((1.0 - (p.y - lo.y) / size.y) * h as f32).floor() as i64,
        )
    };
    // The scene beneath, from above everything.
    let top = space.max.z.max(scene.bounds().max.z) + 1e-3 * space.diagonal().max(1.0);
    let rays: Vec<Ray> = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| {
            let p = to_xy(i as f32 + 0.5, j as f32 + 0.5);
            Ray::new(Vec3::new(p.x, p.y, top), Vec3::NEG_Z)
        })
        .collect();
    let mut rgb: Vec<u8> = tracer
        .closest_hits(&rays)
        .iter()
        .flat_map(|hit| match hit {
            None => BACKGROUND,
            Some(hit) => object_shade(hit.object).map(|c| (u16::from(c) * 3 / 5) as u8),
        })
        .collect();
    // The cut: the leaves reaching height z, by their boxes of positions.
    let z = if eyes.is_empty() {
        0.5 * (space.min.z + space.max.z)
    } else {
        (eyes.iter().map(|e| e.z).sum::<f32>() / eyes.len() as f32).clamp(space.min.z, space.max.z)
    };
    let mut boxes: Vec<([u32; 4], usize)> = Vec::new();
    for leaf in tree.leaves() {
        let c = &leaf.cell;
        let reaches = c.lo[2] <= z && (z < c.hi[2] || c.hi[2] >= space.max.z);
        if reaches {
            let key = [c.lo[0], c.lo[1], c.hi[0], c.hi[1]].map(f32::to_bits);
            boxes.push((key, tree.nodes()[leaf.node].set.count()));
        }
    }
    boxes.sort_unstable();
    // One entry a box, with its largest set.
    boxes.dedup_by(|b, a| {
        let same = a.0 == b.0;
        if same {
            a.1 = a.1.max(b.1);
        }
        same
    });
    let largest_set = boxes.iter().map(|b| b.1).max().unwrap_or(0);
    let mut tint = vec![0usize; (w * h) as usize];
    let pixel_range = |a: f32, b: f32, lo: f32, size: f32, n: u32| {
        let f = |v: f32| ((v - lo) / size * n as f32).round().clamp(0.0, n as f32) as u32;
        (f(a), f(b))
    };
    let mut outline = vec![false; (w * h) as usize];
    for (key, set) in &boxes {
        let [x0, y0, x1, y1] = key.map(f32::from_bits);
        let (i0, i1) = pixel_range(x0, x1, lo.x, size.x, w);
        // Rows count from the north edge.
        let (r0, r1) = pixel_range(y0, y1, lo.y, size.y, h);
        let (j0, j1) = (h - r1, h - r0);
        for j in j0..j1 {
            for i in i0..i1 {
                let k = (j * w + i) as usize;
                tint[k] = tint[k].max(*set);
                if i == i0 || j == j0 || i + 1 == i1 || j + 1 == j1 {
                    outline[k] = true;
                }
            }
        }
    }
    for (k, px) in rgb.chunks_exact_mut(3).enumerate() {
        if largest_set > 0 {
            let a = 0.5 * tint[k] as f32 / largest_set as f32;
            for (c, blue) in px.iter_mut().zip([30.0, 90.0, 220.0]) {
                *c = (f32::from(*c) * (1.0 - a) + blue * a).round() as u8;
            }
        }
        if outline[k] {
            // Half way to the outline's colour: the scene still shows.
            for (c, o) in px.iter_mut().zip(OUTLINE) {
                *c = ((u16::from(*c) + u16::from(o)) / 2) as u8;
            }
        }
    }
    let mut picture = Picture {
        width: w,
        height: h,
        rgb,
    };
    let pixels: Vec<(i64, i64)> = eyes.iter().map(|&e| to_pixel(e)).collect();
    if joined {
        for pair in pixels.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).max(1);
            for t in 0..=steps {
                let f = t as f64 / steps as f64;
                let p = (
                    a.0 + ((b.0 - a.0) as f64 * f).round() as i64,
                    a.1 + ((b.1 - a.1) as f64 * f).round() as i64,
                );
                if (0..i64::from(w)).contains(&p.0) && (0..i64::from(h)).contains(&p.1) {
                    let k = 3 * (p.1 as usize * w as usize + p.0 as usize);
                    picture.rgb[k..k + 3].copy_from_slice(&EYE);
                }
            }
        }
    }
    let mut dot = |p: (i64, i64)| {
        for (dj, di) in (-1..=1).flat_map(|dj| (-1..=1).map(move |di| (dj, di))) {
            let (i, j) = (p.0 + di, p.1 + dj);
            if (0..i64::from(w)).contains(&i) && (0..i64::from(h)).contains(&j) {
                let k = 3 * (j as usize * w as usize + i as usize);
                picture.rgb[k..k + 3].copy_from_slice(&EYE);
            }
        }
    };
    for &p in &pixels {
        dot(p);
    }
    Map {
        picture,
        height: z,
        cells: boxes.len(),
        largest_set,
        joined,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No object's shade is the dropped red, or near it, or the
    /// background.
    #[test]
    fn shades_stay_clear_of_red_and_the_background() {
        for o in 0..10_000 {
            let [r, g, b] = object_shade(o);
            assert_ne!([r, g, b], BACKGROUND);
            // Far from pure red: green or blue well up, or red well down.
            assert!(
                i32::from(g).max(i32::from(b)) > 60 || r < 200,
                "object {o}: {r} {g} {b}"
            );
        }
        // Neighbours differ.
        assert_ne!(object_shade(0), object_shade(1));
    }

    /// Red is exactly the dropped objects' pixels, dark grey exactly the
    /// pixels that see nothing, on a rendered view.
    #[test]
    fn red_paints_the_dropped_objects_pixels() {
        use crate::render::{Camera, random_views};
        use crate::scene::procedural::{SceneKind, generate};
        use crate::trace::Tracer;
        let scene = generate(SceneKind::City, 1, 1);
        let tracer = Tracer::new(&scene);
        let view = random_views(&scene.bounds(), 1, 90.0, 3)[0];
        let ids = IdBuffer::render(&tracer, &Camera::new(&view, 64, 48).unwrap());
        let seen = ids.object_pixels(scene.objects().len());
        assert!(seen.len() >= 2, "the view sees something");
        let pixels = 64 * 48;
        let whole = picture(&ids, &[]);
        assert_eq!((whole.width, whole.height), (64, 48));
        assert_eq!(whole.count(DROPPED), 0);
        assert_eq!(whole.count(BACKGROUND), pixels - ids.hit_pixels());
        let (a, b) = (seen[0], seen[seen.len() - 1]);
        let dropped = picture(&ids, &[a.0, b.0]);
        assert_eq!(dropped.count(DROPPED), a.1 + b.1);
        for ((i, j), o) in ids.pixels() {
            let red = dropped.get(i, j) == DROPPED;
            assert_eq!(red, o == Some(a.0) || o == Some(b.0), "pixel {i} {j}");
        }
    }

    /// Three walls one behind the other, the nearest small: each pixel's
    /// layers are the walls its ray crosses, and the pictures count the
    /// set's among them, red where the nearest is not in the set.
    #[test]
    fn layers_count_what_a_set_draws_along_each_ray() {
        use crate::query::View;
        use crate::render::Camera;
        let mut obj = String::new();
        for (k, (x, h)) in [(1.0, 0.2), (2.0, 5.0), (3.0, 5.0)].into_iter().enumerate() {
            obj += &format!(
                "o wall{k}\nv {x} {} {}\nv {x} {h} {}\nv {x} {h} {h}\nv {x} {} {h}\nf {} {} {}\nf {} {} {}\n",
                -h,
                -h,
                -h,
                -h,
                4 * k + 1,
                4 * k + 2,
                4 * k + 3,
                4 * k + 1,
                4 * k + 3,
                4 * k + 4
            );
        }
        let scene = crate::scene::load_obj_bytes("walls.obj", obj.as_bytes()).unwrap();
        let tracer = Tracer::new(&scene);
        let view = View::look(Vec3::ZERO, Vec3::X, Vec3::Z, 60f32.to_radians(), 1.0);
        let layers = Layers::render(&tracer, &Camera::new(&view, 32, 32).unwrap());
        let (centre, corner) = (16 * 32 + 16, 0);
        assert_eq!(layers.pixel(centre), &[0, 1, 2]);
        assert_eq!(layers.pixel(corner), &[1, 2]);
        let set = |objects: &[usize]| {
            let mut s = ObjectSet::new(3);
            for &o in objects {
                s.insert(o);
            }
            s
        };
        let at = |p: &Picture, k: usize| p.get((k % 32) as u32, (k / 32) as u32);
        let (all, mean) = drawn_picture(&layers, &set(&[0, 1, 2]));
        assert_eq!(at(&all, centre), LAYER_SHADES[2]);
        assert_eq!(at(&all, corner), LAYER_SHADES[1]);
        assert!(mean > 2.0 && mean < 3.0, "{mean}");
        assert_eq!(all.count(DROPPED), 0);
        let (front_culled, _) = drawn_picture(&layers, &set(&[1, 2]));
        assert_eq!(at(&front_culled, centre), DROPPED);
        assert_eq!(at(&front_culled, corner), LAYER_SHADES[1]);
        let (middle_culled, mean) = drawn_picture(&layers, &set(&[0, 2]));
        assert_eq!(at(&middle_culled, centre), LAYER_SHADES[1]);
        assert_eq!(at(&middle_culled, corner), DROPPED);
        assert!(mean > 1.0 && mean < 2.0, "{mean}");
        let (none, mean) = drawn_picture(&layers, &set(&[]));
        assert_eq!(none.count(DROPPED), 32 * 32);
        assert_eq!(mean, 0.0);
    }

    /// The nearest layer of each pixel is the object the ID buffer sees
    /// there (the same rays, the same exact tracer).
    #[test]
    fn the_nearest_layer_is_what_the_id_buffer_sees() {
        use crate::render::{Camera, random_views};
        use crate::scene::procedural::{SceneKind, generate};
        let scene = generate(SceneKind::City, 1, 1);
        let tracer = Tracer::new(&scene);
        let mut deeper = 0;
        for view in random_views(&scene.bounds(), 4, 90.0, 5) {
            let camera = Camera::new(&view, 48, 40).unwrap();
            let ids = IdBuffer::render(&tracer, &camera);
            let layers = Layers::render(&tracer, &camera);
            for (k, (_, o)) in ids.pixels().enumerate() {
                assert_eq!(layers.pixel(k).first().copied(), o, "pixel {k}");
                deeper += usize::from(layers.pixel(k).len() > 1);
            }
        }
        assert!(deeper > 100, "{deeper} rays pass more than one object");
    }

    /// The map: the view box's shape, every eye white where it is, the
    /// path drawn when joined, the cut's boxes and largest set those of
    /// the tree's leaves at the eyes' height.
    #[test]
    fn the_map_shows_the_cells_and_the_eyes() {
        use crate::builder::{BuildParams, build};
        use crate::scene::procedural::{SceneKind, generate};
        let scene = generate(SceneKind::City, 2, 1);
        let tracer = Tracer::new(&scene);
        let params = BuildParams {
            max_depth: 6,
            ..BuildParams::default()
        };
        let (tree, _) = build(&scene, &tracer, &params, &|_| {}).unwrap();
        let space = tree.root_cell().space();
        let at = |fx: f32, fy: f32| {
            let d = space.max - space.min;
            Vec3::new(
                space.min.x + fx * d.x,
                space.min.y + fy * d.y,
                space.min.z + 0.3 * d.z,
            )
        };
        let eyes = [at(0.25, 0.25), at(0.75, 0.5), at(0.5, 0.9)];
        let m = map(&scene, &tracer, &tree, &eyes, false, 96);
        let size = space.max - space.min;
        assert_eq!(m.picture.width.max(m.picture.height), 96);
        let ratio = m.picture.width as f32 / m.picture.height as f32;
        assert!((ratio - size.x / size.y).abs() < 0.05 * ratio, "{ratio}");
        assert!((m.height - eyes[0].z).abs() < 1e-3 * size.z);
        // Each eye's pixel (north up) is white.
        for e in eyes {
            let i = ((e.x - space.min.x) / size.x * m.picture.width as f32) as u32;
            let j = ((1.0 - (e.y - space.min.y) / size.y) * m.picture.height as f32) as u32;
            assert_eq!(m.picture.get(i, j), EYE, "eye {e}");
        }
        // The cut: the distinct boxes of the leaves at that height.
        let mut boxes = std::collections::BTreeMap::new();
        for leaf in tree.leaves() {
            let c = leaf.cell;
            if c.lo[2] <= m.height && (m.height < c.hi[2] || c.hi[2] >= space.max.z) {
                let key = [c.lo[0], c.lo[1], c.hi[0], c.hi[1]].map(f32::to_bits);
                let set = tree.nodes()[leaf.node].set.count();
                let e = boxes.entry(key).or_insert(0);
                *e = set.max(*e);
            }
        }
        assert!(boxes.len() >= 2, "a cut of one box tests little");
        assert_eq!(m.cells, boxes.len());
        assert_eq!(m.largest_set, *boxes.values().max().unwrap());
        // Joined, the path adds white pixels between the eyes.
        let path = map(&scene, &tracer, &tree, &eyes, true, 96);
        assert!(path.joined && !m.joined);
        assert!(path.picture.count(EYE) > m.picture.count(EYE) + 20);
    }

    #[test]
    fn a_thumbnail_keeps_every_red_block_red() {
        let mut rgb = Vec::new();
        for k in 0..(10 * 7) {
            rgb.extend(if k == 23 { DROPPED } else { object_shade(k) });
        }
        let p = Picture {
            width: 10,
            height: 7,
            rgb,
        };
        let small = p.shrunk(4);
        assert_eq!((small.width, small.height), (4, 3));
        assert_eq!(small.count(DROPPED), 1);
        // Pixel 23 is (3, 2): block (1, 0) of 3x3 blocks.
        assert_eq!(small.get(1, 0), DROPPED);
        assert_eq!(p.shrunk(10), p);
    }
}
