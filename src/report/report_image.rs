//! The report's pictures (issue 18): a view's ID buffer drawn in flat
//! shades, one per object, with the pixels of the objects a method did
//! not draw in red, so that what popping would look like is seen, not
//! read. The pixels are RGB bytes; `vis5d report` writes them as PNG.

use crate::render::IdBuffer;

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
