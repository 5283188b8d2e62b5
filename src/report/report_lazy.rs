//! The lazy occlusion grid of Hey, Tobler & Purgathofer, *Real-time
//! occlusion culling with a lazy occlusion grid* (EGWR 2001, papers/002),
//! in its occlusion-buffer variant, in software: a from-point,
//! conservative, image-based culling baseline for one view.
//!
//! ## The method
//!
//! The image of the [`Camera`] is covered by an occlusion buffer (one entry
//! per pixel) and, on top of it, a low-resolution grid of cells of
//! `cell_pixels` x `cell_pixels` pixels (the last column and row of cells
//! may be narrower). A bounding-volume hierarchy over the objects' boxes
//! (built once per scene by [`LazyGrid::new`]: median splits of the box
//! centres along the widest axis, one object per leaf) is traversed front
//! to back (sec. 4): a list of boxes still to test, ordered by their
//! nearest depth `znear` (the depth of a box's nearest corner along the
//! viewing direction). The frontmost box is taken out and tested for
//! occlusion; an occluded box is dropped with its whole subtree; the
//! children of a visible inner box are listed, unless they lie outside the
//! view frustum (hierarchical view-frustum culling, done before any
//! occlusion test); a visible leaf puts its object into the answer and the
//! object is drawn into the occlusion buffer. Objects are drawn as soon as
//! they are found visible, as in the paper's simple traversal (Fig. 4);
//! the paper's two-list traversal for the occlusion-buffer variant
//! (Fig. 6: an object is drawn only once it lies in front of every box
//! still to test) is kept for comparison in the tests: with the depths
//! below it is not needed for conservativeness, and it culls less here,
//! because the large occluders of these scenes (walls, floors) lie in
//! front of little and so are drawn late.
//!
//! *Drawing* an object rasterises its triangles conservatively: a pixel is
//! marked only when its whole square lies inside the projected triangle (by
//! a margin of 1/1000 pixel; the edge functions are those of the planes
//! through the eye and the triangle's edges, in f64). A triangle that
//! reaches the near plane (depth `1e-5` scene diagonals) is clipped just in
//! front of it and its part there is drawn: that part is inside the
//! triangle, so this only marks pixels the triangle covers (drawing nothing
//! for such triangles, as a first version did, left the floor, walls and
//! ceiling around the eye out of the buffer and culled next to nothing). The only fusion of coverage is within pairs of triangles
//! of one object sharing an edge (paired once per scene, coplanar
//! neighbours first: the two halves of each quad): when the two lie on
//! opposite sides of the shared edge in the image, a pixel whose square is
//! inside the outer edges of both is covered by their union and is marked
//! too. Without it the diagonal of every quad would leave a line of free
//! pixels, and a wall would hardly ever fill a cell. Seams between other
//! triangles, and between objects, stay free.
//!
//! The image area of a box is the bounding rectangle of its projected
//! corners, widened to every pixel it touches. A box with a corner at or
//! behind the near plane (or holding the eye) is potentially visible
//! without a test, and its image area is the whole image.
//!
//! ## Cell states
//!
//! As in the paper's sec. 3.1 a cell is *completely free* (no pixel
//! occluded), *partially free* (at least one pixel free), or *outdated*
//! (something was drawn into its area since it was last looked at), with a
//! *full* flag (every pixel occluded) that overrides them: a full cell is
//! never set outdated again (drawing only ever occludes more). Initially
//! every cell is completely free. A full cell also keeps `zfar`, the
//! largest occluder depth of its pixels (see the deviation below).
//!
//! ## The occlusion test (Fig. 2)
//!
//! For a box's rectangle the cells it touches are *internal* (wholly inside
//! the rectangle) or *border* cells (partly inside). Four passes, the first
//! two on cell states alone, so that up-to-date cells are queried before
//! outdated ones:
//!
//! 1. internal cells without pixel query: a free (completely or partially)
//!    internal cell makes the box visible at once; a full cell that
//!    occludes the box (`zfar < znear`) is passed; outdated cells (and full
//!    cells whose `zfar` does not prove occlusion) are listed;
//! 2. border cells without pixel query: a completely free border cell makes
//!    the box visible; a full, occluding one is passed; the others
//!    (partially free, outdated, full but not nearer) are listed;
//! 3. the listed internal cells are updated lazily, each by a pixel-level
//!    query of the whole cell (it becomes completely free, partially free
//!    or full with a fresh `zfar`): the first one that does not occlude the
//!    box makes it visible, and the cells after it stay outdated;
//! 4. the listed border cells get a pixel-level query of the part of the
//!    rectangle inside the cell: one pixel there that does not occlude the
//!    box makes it visible (and an outdated cell with a free pixel there
//!    becomes partially free, as in the paper).
//!
//! If no pass finds the box visible it is occluded. Each pixel-level query
//! (of a cell, or of a cell's intersection with a rectangle: the unit of
//! the paper's `glReadPixels` calls counted in its Fig. 8, not the number
//! of pixels read) counts in [`GridStats::pixel_queries`]; whole-cell
//! updates also in [`GridStats::cell_updates`].
//!
//! ## Lazy and busy updates
//!
//! After an object is drawn, the cells of its box's rectangle are, in the
//! *lazy* mode ([`GridParams::lazy`]), only marked outdated (full ones are
//! left alone): they are updated when a later test needs them, if ever. In
//! the *busy* mode they are updated at once, each by a pixel-level query of
//! the whole cell, so that no cell is ever outdated (the paper's
//! comparison, its Fig. 8). Each pass above decides only what the pixels
//! would (a free cell state is always accurate: every cell drawn into is
//! outdated or updated), so both modes decide every test exactly as "every
//! pixel of the rectangle holds an occluder nearer than the box" would:
//! they cull the same objects and differ only in cost.
//!
//! ## Deviation: depths instead of one bit per pixel
//!
//! The paper's occlusion buffer holds one bit per pixel, which is exact
//! only when every object drawn before a box is tested lies entirely in
//! front of that box: its Fig. 6 traversal ensures this, but drawing in
//! box order (Fig. 4) does not, and even Fig. 6 fails at ties. To stay
//! conservative whatever the order, each pixel keeps instead a depth: the
//! least, over the triangles drawn whose image covers the pixel's square,
//! of the triangle's farthest depth over that square (the depth of its
//! plane at the square's farthest corner, at most its farthest vertex;
//! plus a slack of `1e-6` relative and `1e-6` scene diagonals; `+inf` for
//! a free pixel). A pixel occludes a box only when that depth is below the
//! box's nearest depth (`depth < znear`): only geometry entirely nearer
//! than the box over the whole pixel counts, so any ray through the pixel
//! meets it before the box. A box is culled only when every pixel of its
//! rectangle occludes it. A full cell keeps the largest depth of its pixels
//! (`zfar`, an upper bound, as depths only decrease), as in the paper's
//! z-buffer variant (sec. 3.2); a full cell whose `zfar` is not below the
//! box's `znear` is queried at pixel level rather than taken as free, which
//! keeps the test exact. The buffer costs one f32 per pixel instead of one
//! bit.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::DVec3;

use super::report_camera::Camera;
use crate::bitset::ObjectSet;
use crate::geom::Aabb;
use crate::scene::Scene;

/// Settings of the lazy occlusion grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridParams {
    /// The side of a grid cell, in pixels (the paper's 32; 0 counts as 1).
    pub cell_pixels: u32,
    /// Lazy update (the paper's method): after drawing, cells are only
    /// marked outdated. `false`: busy update, every cell in the drawn
    /// object's image area is updated at once by a pixel-level query.
    pub lazy: bool,
}

impl Default for GridParams {
    fn default() -> Self {
        Self {
            cell_pixels: 32,
            lazy: true,
        }
    }
}

/// What one view cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GridStats {
    /// Pixel-level occlusion queries: one per whole-cell update and one per
    /// border-cell query of a cell's intersection with a box's rectangle
    /// (the unit of the paper's Fig. 8, not the number of pixels read).
    pub pixel_queries: u64,
    /// Cell states refreshed by a pixel-level query of the whole cell (lazy
    /// updates in tests, and every update after a draw in busy mode).
    pub cell_updates: u64,
    /// Boxes of the hierarchy occlusion-tested (those inside the view
    /// frustum whose parent was found visible), near-plane boxes included.
    pub boxes_tested: u64,
    /// Objects drawn: the potentially visible ones.
    pub objects_drawn: u64,
    /// Triangles of the drawn objects (sent to the renderer), including
    /// those that drew nothing into the occlusion buffer.
    pub triangles_drawn: u64,
}

/// A node of the object-box hierarchy.
#[derive(Clone, Copy, Debug)]
enum NodeKind {
    /// A leaf: one object, whose box is the node's.
    Object(u32),
    /// Two children (indices into the node array).
    Inner(u32, u32),
}

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    kind: NodeKind,
}

/// The grid over one scene (its object-box hierarchy).
pub struct LazyGrid<'a> {
    scene: &'a Scene,
    /// The hierarchy, root first.
    nodes: Vec<Node>,
    /// What drawing rasterises, object by object: `prims[prim_start[o] ..
    /// prim_start[o + 1]]` are object `o`'s.
    prims: Vec<Prim>,
    prim_start: Vec<u32>,
    /// Draw an object only once it is in front of every box still to test
    /// (the paper's Fig. 6), instead of as soon as it is found visible
    /// (Fig. 4, the default). Set by tests to compare the two.
    paper_draw_order: bool,
    /// The near-plane depth: a box reaching it is visible without a test;
    /// drawing clips triangles at twice it.
    near: f32,
    /// Added to an occluder's depth before it is stored (rounding of the
    /// depths of boxes and triangles computed apart).
    depth_slack: f32,
}

impl std::fmt::Debug for LazyGrid<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LazyGrid")
            .field("objects", &self.scene.objects().len())
            .field("nodes", &self.nodes.len())
            .field("near", &self.near)
            .finish()
    }
}

/// Widening of a box's projected rectangle, in pixels (rounding of the
/// projection).
const RECT_MARGIN: f32 = 0.01;
/// How far inside a triangle's projection a pixel square must lie to be
/// marked occluded, in pixels.
const COVER_MARGIN: f64 = 1e-3;

/// An inclusive rectangle of pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rect {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Rect {
    fn intersect(&self, o: &Rect) -> Rect {
        Rect {
            x0: self.x0.max(o.x0),
            y0: self.y0.max(o.y0),
            x1: self.x1.min(o.x1),
            y1: self.y1.min(o.y1),
        }
    }

    fn contains_rect(&self, o: &Rect) -> bool {
        self.x0 <= o.x0 && self.y0 <= o.y0 && o.x1 <= self.x1 && o.y1 <= self.y1
    }
}

/// What a box looks like from the camera.
#[derive(Clone, Copy, Debug)]
struct Footprint {
    /// Smallest depth of a corner (may be negative).
    znear: f32,
    /// Largest depth of a corner.
    zfar: f32,
    /// The pixels the box's image may touch (the whole image when it
    /// reaches the near plane).
    rect: Rect,
    /// The box reaches the near plane or holds the eye: visible untested.
    crosses_near: bool,
}

/// An entry of the test or draw list: a min-heap on `key`, ties by node.
#[derive(Clone, Copy, Debug)]
struct Entry {
    key: f32,
    node: u32,
    fp: Footprint,
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .key
            .total_cmp(&self.key)
            .then(other.node.cmp(&self.node))
    }
}

impl<'a> LazyGrid<'a> {
    /// Builds the object-box hierarchy of `scene` (median splits of the
    /// box centres along the widest axis, one object per leaf).
    pub fn new(scene: &'a Scene) -> Self {
        let mut ids: Vec<u32> = (0..scene.objects().len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * ids.len());
        if !ids.is_empty() {
            build(scene, &mut nodes, &mut ids);
        }
        let diag = scene.bounds().diagonal().max(1e-3);
        let mut prims = Vec::with_capacity(scene.triangles().len());
        let mut prim_start = Vec::with_capacity(scene.objects().len() + 1);
        for o in 0..scene.objects().len() {
            prim_start.push(prims.len() as u32);
            pair_triangles(scene.object_triangles(o), &mut prims);
        }
        prim_start.push(prims.len() as u32);
        Self {
            scene,
            nodes,
            prims,
            prim_start,
            paper_draw_order: false,
            near: 1e-5 * diag,
            depth_slack: 1e-6 * diag,
        }
    }

    /// Culls for one camera: `out` gets the objects to draw (the
    /// potentially visible ones); returns the costs.
    ///
    /// # Panics
    /// When `out`'s capacity is below the scene's object count.
    pub fn cull(&self, camera: &Camera, params: &GridParams, out: &mut ObjectSet) -> GridStats {
        assert!(
            out.capacity() >= self.scene.objects().len(),
            "the output set must range over the scene's {} objects",
            self.scene.objects().len()
        );
        out.clear();
        let mut stats = GridStats::default();
        let mut grid = Grid::new(camera, params.cell_pixels.max(1));
        let Some(root) = self.nodes.first() else {
            return stats;
        };
        let mut tests = BinaryHeap::new();
        let mut draws: BinaryHeap<Entry> = BinaryHeap::new();
        if let Some(fp) = self.footprint(camera, &root.bounds) {
            tests.push(Entry {
                key: fp.znear,
                node: 0,
                fp,
            });
        }
        loop {
            let take_draw = match (tests.peek(), draws.peek()) {
                (None, None) => break,
                (None, Some(_)) => true,
                (Some(_), None) => false,
                (Some(t), Some(d)) => d.key <= t.key,
            };
            if take_draw {
                let e = draws.pop().expect("peeked");
                let NodeKind::Object(o) = self.nodes[e.node as usize].kind else {
                    unreachable!("only leaves are drawn")
                };
                let tris = self.scene.object_triangles(o as usize);
                stats.objects_drawn += 1;
                stats.triangles_drawn += tris.len() as u64;
                let prims = &self.prims[self.prim_start[o as usize] as usize
                    ..self.prim_start[o as usize + 1] as usize];
                for p in prims {
                    grid.draw_prim(p, self.near, self.depth_slack);
                }
                if params.lazy {
                    grid.mark_outdated(&e.fp.rect);
                } else {
                    grid.update_busy(&e.fp.rect, &mut stats);
                }
            } else {
                let e = tests.pop().expect("peeked");
                stats.boxes_tested += 1;
                let visible =
                    e.fp.crosses_near || !grid.is_occluded(&e.fp.rect, e.fp.znear, &mut stats);
                if !visible {
                    continue;
                }
                match self.nodes[e.node as usize].kind {
                    NodeKind::Object(o) => {
                        out.insert(o as usize);
                        draws.push(Entry {
                            key: if self.paper_draw_order {
                                e.fp.zfar
                            } else {
                                f32::NEG_INFINITY
                            },
                            ..e
                        });
                    }
                    NodeKind::Inner(l, r) => {
                        for c in [l, r] {
                            if let Some(fp) = self.footprint(camera, &self.nodes[c as usize].bounds)
                            {
                                tests.push(Entry {
                                    key: fp.znear,
                                    node: c,
                                    fp,
                                });
                            }
                        }
                    }
                }
            }
        }
        stats
    }

    /// The box as seen from the camera, or `None` when it lies outside the
    /// view frustum (wholly behind the eye or outside a side plane) or
    /// covers no pixel.
    fn footprint(&self, cam: &Camera, b: &Aabb) -> Option<Footprint> {
        let corners = (0..8).map(|k| {
            glam::Vec3::new(
                if k & 1 == 0 { b.min.x } else { b.max.x },
                if k & 2 == 0 { b.min.y } else { b.max.y },
                if k & 4 == 0 { b.min.z } else { b.max.z },
            )
        });
        let mut zmin = f32::INFINITY;
        let mut zmax = f32::NEG_INFINITY;
        // Per frustum plane, the largest signed value over the corners.
        let mut side = [f32::NEG_INFINITY; 5];
        let mut scale = 0f32;
        for c in corners.clone() {
            let d = c - cam.eye;
            let (x, y, z) = (d.dot(cam.right), d.dot(cam.up), d.dot(cam.forward));
            zmin = zmin.min(z);
            zmax = zmax.max(z);
            let vals = [
                z * cam.tan_x + x,
                z * cam.tan_x - x,
                z * cam.tan_y + y,
                z * cam.tan_y - y,
                z,
            ];
            for (s, v) in side.iter_mut().zip(vals) {
                *s = s.max(v);
            }
            scale = scale.max(d.abs().max_element());
        }
        let tol = 1e-5 * scale * (1.0 + cam.tan_x.max(cam.tan_y));
        if side.iter().any(|&s| s < -tol) {
            return None;
        }
        let whole = Rect {
            x0: 0,
            y0: 0,
            x1: cam.width - 1,
            y1: cam.height - 1,
        };
        if zmin <= self.near || b.contains(cam.eye) {
            return Some(Footprint {
                znear: zmin,
                zfar: zmax,
                rect: whole,
                crosses_near: true,
            });
        }
        let (mut x0, mut y0) = (f32::INFINITY, f32::INFINITY);
        let (mut x1, mut y1) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
        for c in corners {
            let p = cam.to_image(c);
            x0 = x0.min(p.x);
            x1 = x1.max(p.x);
            y0 = y0.min(p.y);
            y1 = y1.max(p.y);
        }
        let span = |lo: f32, hi: f32, n: u32| -> Option<(u32, u32)> {
            let a = ((lo - RECT_MARGIN).floor() as i64).max(0);
            let b = ((hi + RECT_MARGIN).floor() as i64).min(n as i64 - 1);
            (a <= b).then_some((a as u32, b as u32))
        };
        let (rx0, rx1) = span(x0, x1, cam.width)?;
        let (ry0, ry1) = span(y0, y1, cam.height)?;
        Some(Footprint {
            znear: zmin,
            zfar: zmax,
            rect: Rect {
                x0: rx0,
                y0: ry0,
                x1: rx1,
                y1: ry1,
            },
            crosses_near: false,
        })
    }
}

/// Builds the subtree over `ids` at the end of `nodes`; returns its index.
fn build(scene: &Scene, nodes: &mut Vec<Node>, ids: &mut [u32]) -> u32 {
    let objects = scene.objects();
    let bounds = ids
        .iter()
        .fold(Aabb::EMPTY, |b, &o| b.union(&objects[o as usize].bounds));
    let me = nodes.len() as u32;
    if let [o] = ids {
        nodes.push(Node {
            bounds,
            kind: NodeKind::Object(*o),
        });
        return me;
    }
    nodes.push(Node {
        bounds,
        kind: NodeKind::Inner(0, 0),
    });
    let centres = Aabb::from_points(ids.iter().map(|&o| objects[o as usize].bounds.center()));
    let axis = centres.size().max_position();
    let mid = ids.len() / 2;
    ids.select_nth_unstable_by(mid, |&a, &b| {
        let (ca, cb) = (
            objects[a as usize].bounds.center()[axis],
            objects[b as usize].bounds.center()[axis],
        );
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    let (left, right) = ids.split_at_mut(mid);
    let l = build(scene, nodes, left);
    let r = build(scene, nodes, right);
    nodes[me as usize].kind = NodeKind::Inner(l, r);
    me
}

/// The state of a cell (sec. 3.1); `full` overrides it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Occ {
    CompletelyFree,
    /// At least one pixel is free.
    PartiallyFree,
    Outdated,
}

#[derive(Clone, Copy, Debug)]
struct Cell {
    occ: Occ,
    full: bool,
    /// When full: an upper bound of its pixels' occluder depths.
    zfar: f32,
}

/// The occlusion buffer and the grid of one view.
struct Grid {
    w: u32,
    h: u32,
    cp: u32,
    cells_x: u32,
    /// Per pixel, row by row from the top: the smallest farthest depth of
    /// the triangles covering it (`+inf`: free).
    depth: Vec<f32>,
    cells: Vec<Cell>,
    internal: Vec<u32>,
    border: Vec<u32>,
    /// The camera frame and tangents in f64, for rasterisation.
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_x: f64,
    tan_y: f64,
}

impl Grid {
    fn new(cam: &Camera, cp: u32) -> Self {
        let (w, h) = (cam.width, cam.height);
        let cells_x = w.div_ceil(cp);
        let cells_y = h.div_ceil(cp);
        Self {
            w,
            h,
            cp,
            cells_x,
            depth: vec![f32::INFINITY; w as usize * h as usize],
            cells: vec![
                Cell {
                    occ: Occ::CompletelyFree,
                    full: false,
                    zfar: f32::INFINITY,
                };
                cells_x as usize * cells_y as usize
            ],
            internal: Vec::new(),
            border: Vec::new(),
            eye: cam.eye.as_dvec3(),
            forward: cam.forward.as_dvec3(),
            right: cam.right.as_dvec3(),
            up: cam.up.as_dvec3(),
            tan_x: cam.tan_x as f64,
            tan_y: cam.tan_y as f64,
        }
    }

    /// The pixels of cell `k`.
    fn cell_rect(&self, k: u32) -> Rect {
        let (cx, cy) = (k % self.cells_x, k / self.cells_x);
        Rect {
            x0: cx * self.cp,
            y0: cy * self.cp,
            x1: ((cx + 1) * self.cp).min(self.w) - 1,
            y1: ((cy + 1) * self.cp).min(self.h) - 1,
        }
    }

    /// The indices of the cells `r` touches.
    fn cells_of(&self, r: &Rect) -> impl Iterator<Item = u32> + use<> {
        let (cp, cx) = (self.cp, self.cells_x);
        let (x0, x1) = (r.x0 / cp, r.x1 / cp);
        (r.y0 / cp..=r.y1 / cp).flat_map(move |y| (x0..=x1).map(move |x| y * cx + x))
    }

    /// A whole-cell pixel-level query: refreshes cell `k`'s state.
    fn update_cell(&mut self, k: u32, stats: &mut GridStats) {
        stats.pixel_queries += 1;
        stats.cell_updates += 1;
        let r = self.cell_rect(k);
        let (mut any_free, mut all_free, mut zfar) = (false, true, f32::NEG_INFINITY);
        for y in r.y0..=r.y1 {
            let row = (y * self.w) as usize;
            for &d in &self.depth[row + r.x0 as usize..=row + r.x1 as usize] {
                if d == f32::INFINITY {
                    any_free = true;
                } else {
                    all_free = false;
                    zfar = zfar.max(d);
                }
            }
        }
        let c = &mut self.cells[k as usize];
        if all_free {
            *c = Cell {
                occ: Occ::CompletelyFree,
                full: false,
                zfar: f32::INFINITY,
            };
        } else if any_free {
            *c = Cell {
                occ: Occ::PartiallyFree,
                full: false,
                zfar: f32::INFINITY,
            };
        } else {
            c.full = true;
            c.zfar = zfar;
        }
    }

    /// Fig. 2: whether every pixel of `rect` holds an occluder nearer than
    /// `znear`, deciding on cell states first and updating outdated cells
    /// lazily.
    fn is_occluded(&mut self, rect: &Rect, znear: f32, stats: &mut GridStats) -> bool {
        let mut internal = std::mem::take(&mut self.internal);
        let mut border = std::mem::take(&mut self.border);
        internal.clear();
        border.clear();
        let occluded = self.test_cells(rect, znear, stats, &mut internal, &mut border);
        self.internal = internal;
        self.border = border;
        occluded
    }

    fn test_cells(
        &mut self,
        rect: &Rect,
        znear: f32,
        stats: &mut GridStats,
        internal: &mut Vec<u32>,
        border: &mut Vec<u32>,
    ) -> bool {
        // internalCellIsFreeWithoutPixelquery
        for k in self.cells_of(rect) {
            if !rect.contains_rect(&self.cell_rect(k)) {
                continue;
            }
            let c = self.cells[k as usize];
            if c.full {
                if c.zfar >= znear {
                    internal.push(k);
                }
            } else if c.occ == Occ::Outdated {
                internal.push(k);
            } else {
                return false;
            }
        }
        // borderCellIsFreeWithoutPixelquery
        for k in self.cells_of(rect) {
            if rect.contains_rect(&self.cell_rect(k)) {
                continue;
            }
            let c = self.cells[k as usize];
            if c.full {
                if c.zfar >= znear {
                    border.push(k);
                }
            } else if c.occ == Occ::CompletelyFree {
                return false;
            } else {
                border.push(k);
            }
        }
        // internalCellIsFreeWithPixelquery: the lazy update.
        for &k in internal.iter() {
            self.update_cell(k, stats);
            let c = self.cells[k as usize];
            if !c.full || c.zfar >= znear {
                return false;
            }
        }
        // borderCellIsFreeWithPixelquery
        for &k in border.iter() {
            stats.pixel_queries += 1;
            let r = self.cell_rect(k).intersect(rect);
            for y in r.y0..=r.y1 {
                let row = (y * self.w) as usize;
                let hit = self.depth[row + r.x0 as usize..=row + r.x1 as usize]
                    .iter()
                    .find(|&&d| d >= znear);
                if let Some(&d) = hit {
                    let c = &mut self.cells[k as usize];
                    if d == f32::INFINITY && c.occ == Occ::Outdated {
                        c.occ = Occ::PartiallyFree;
                    }
                    return false;
                }
            }
        }
        true
    }

    /// Lazy: the non-full cells of `rect` become outdated.
    fn mark_outdated(&mut self, rect: &Rect) {
        for k in self.cells_of(rect) {
            let c = &mut self.cells[k as usize];
            if !c.full {
                c.occ = Occ::Outdated;
            }
        }
    }

    /// Busy: the non-full cells of `rect` are updated now.
    fn update_busy(&mut self, rect: &Rect, stats: &mut GridStats) {
        for k in self.cells_of(rect) {
            if !self.cells[k as usize].full {
                self.update_cell(k, stats);
            }
        }
    }

    /// Draws one primitive: a triangle, or a pair of triangles sharing an
    /// edge, whose union covers more (the pixels across the shared edge)
    /// when the two lie on opposite sides of that edge in the image. Each
    /// triangle is first clipped to the near plane.
    fn draw_prim(&mut self, p: &Prim, near: f32, slack: f32) {
        let clip_z = 2.0 * near as f64;
        match *p {
            Prim::Tri(t) => {
                let poly = Poly::clip(t.map(|q| q.as_dvec3() - self.eye), self.forward, clip_z);
                if let Some(half) = self.half_planes(&poly) {
                    self.fill(
                        &half.lines[..half.len],
                        &[half.plane],
                        half.zmax,
                        half.bbox,
                        slack,
                    );
                }
            }
            Prim::Pair([a, b, c, d]) => {
                let [a, b, c, d] = [a, b, c, d].map(|q| q.as_dvec3() - self.eye);
                let p1 = Poly::clip([a, b, c], self.forward, clip_z);
                let p2 = Poly::clip([a, b, d], self.forward, clip_z);
                let h1 = self.half_planes(&p1);
                let h2 = self.half_planes(&p2);
                // Opposite sides of the shared edge a-b (the in-front part
                // of a triangle lies on its third corner's side of the
                // plane through the eye and a-b): the union holds every
                // square inside the outer edges of both clipped triangles
                // (a point of it on c's side of a-b is in the first, one on
                // d's side in the second).
                let opposite = |n: DVec3, p: DVec3, q: DVec3| {
                    let (sp, sq) = (n.dot(p), n.dot(q));
                    sp != 0.0 && sq != 0.0 && (sp > 0.0) != (sq > 0.0)
                };
                let fused = match (&h1, &h2) {
                    (Some(h1), Some(h2)) => {
                        opposite(a.cross(b), c, d) && h1.shared.is_some() && h2.shared.is_some()
                    }
                    _ => false,
                };
                // Unclipped, and a, b on opposite sides of c-d too: the
                // image of the pair is a convex quadrilateral, which the
                // fused region is (up to the margin): no need for the
                // triangles one by one.
                let convex = fused && p1.len == 3 && p2.len == 3 && opposite(c.cross(d), a, b);
                if !convex {
                    for h in [&h1, &h2].into_iter().flatten() {
                        self.fill(&h.lines[..h.len], &[h.plane], h.zmax, h.bbox, slack);
                    }
                }
                if let (true, Some(h1), Some(h2)) = (fused, h1, h2) {
                    let mut lines = [(0.0, 0.0, 0.0); 8];
                    let mut len = 0;
                    for h in [&h1, &h2] {
                        for (k, &l) in h.lines[..h.len].iter().enumerate() {
                            if Some(k) != h.shared {
                                lines[len] = l;
                                len += 1;
                            }
                        }
                    }
                    let bbox = [
                        h1.bbox[0].min(h2.bbox[0]),
                        h1.bbox[1].max(h2.bbox[1]),
                        h1.bbox[2].min(h2.bbox[2]),
                        h1.bbox[3].max(h2.bbox[3]),
                    ];
                    let z = h1.zmax.max(h2.zmax);
                    self.fill(&lines[..len], &[h1.plane, h2.plane], z, bbox, slack);
                }
            }
        }
    }

    /// The image half-planes of a clipped (convex, planar, in front)
    /// polygon, its depth plane and farthest depth; `None` when it is
    /// empty or seen edge-on.
    fn half_planes(&self, poly: &Poly) -> Option<HalfPlanes> {
        if poly.len < 3 {
            return None;
        }
        let verts = &poly.verts[..poly.len];
        let centre = verts.iter().copied().sum::<DVec3>() / poly.len as f64;
        let (w, h) = (self.w as f64, self.h as f64);
        // Along the pixel ray through image point (x, y), whose direction
        // is D(x, y) = forward + right tan_x (2x/w - 1) + up tan_y (1 - 2y/h),
        // the sign of n . D is that of E(x, y) = a x + b y + c.
        let linear = |n: DVec3| {
            let (nf, nr, nu) = (n.dot(self.forward), n.dot(self.right), n.dot(self.up));
            let a = 2.0 * self.tan_x * nr / w;
            let b = -2.0 * self.tan_y * nu / h;
            (a, b, nf - self.tan_x * nr + self.tan_y * nu)
        };
        let mut out = HalfPlanes {
            lines: [(0.0, 0.0, 0.0); 4],
            len: poly.len,
            shared: None,
            plane: (0.0, 0.0, 0.0, 0.0),
            zmax: verts
                .iter()
                .map(|v| v.dot(self.forward))
                .fold(0.0, f64::max),
            bbox: [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ],
        };
        for v in verts {
            // The image point (as Camera::to_image; every corner is in
            // front of the near plane).
            let z = v.dot(self.forward);
            let x = (v.dot(self.right) / (z * self.tan_x) + 1.0) * 0.5 * w;
            let y = (1.0 - v.dot(self.up) / (z * self.tan_y)) * 0.5 * h;
            out.bbox = [
                out.bbox[0].min(x),
                out.bbox[1].max(x),
                out.bbox[2].min(y),
                out.bbox[3].max(y),
            ];
        }
        for k in 0..poly.len {
            // The plane through the eye and edge k, positive inside; over
            // the square [i, i+1] x [j, j+1] the least E is at the corner
            // picked by the signs of a and b.
            let mut n = verts[k].cross(verts[(k + 1) % poly.len]);
            let side = n.dot(centre);
            if side == 0.0 || !side.is_finite() {
                return None;
            }
            if side < 0.0 {
                n = -n;
            }
            let (a, b, c) = linear(n);
            let margin = COVER_MARGIN * (a * a + b * b).sqrt();
            out.lines[k] = (a, b, c + a.min(0.0) + b.min(0.0) - margin);
            if poly.labels[k] == 0 {
                out.shared = Some(k);
            }
        }
        // The depth plane n . p = k > 0: at (x, y) the depth is
        // k / (n . D(x, y)), and n . D is linear, so the farthest depth over
        // a square is k over the least n . D there (at a corner).
        let mut n = (verts[1] - verts[0]).cross(verts[2] - verts[0]);
        let mut k = n.dot(verts[0]);
        if k == 0.0 || !k.is_finite() {
            return None;
        }
        if k < 0.0 {
            n = -n;
            k = -k;
        }
        let (a, b, c) = linear(n);
        out.plane = (a, b, c + a.min(0.0) + b.min(0.0), k);
        Some(out)
    }

    /// Marks the pixels whose squares lie inside every half-plane `lines`
    /// (among those of the image box `bbox`: x from, x to, y from, y to)
    /// with the farthest depth of the `planes` over the square (at most
    /// `zmax`, the region's farthest depth).
    fn fill(
        &mut self,
        lines: &[(f64, f64, f64)],
        planes: &[(f64, f64, f64, f64)],
        zmax: f64,
        bbox: [f64; 4],
        slack: f32,
    ) {
        // The pixel rows and columns of the bounding box, a pixel wider.
        let span = |lo: f64, hi: f64, n: u32| {
            let a = (lo.floor() - 1.0).max(0.0);
            let b = (hi.floor() + 1.0).min(n as f64 - 1.0);
            (a, b)
        };
        let (bx0, bx1) = span(bbox[0], bbox[1], self.w);
        let (by0, by1) = span(bbox[2], bbox[3], self.h);
        if bx0 > bx1 || by0 > by1 {
            return;
        }
        let inside = |i: f64, j: f64| lines.iter().all(|&(a, b, c)| a * i + b * j + c > 0.0);
        for j in by0 as u32..=by1 as u32 {
            let jf = j as f64;
            let (mut lo, mut hi) = (bx0, bx1);
            for &(a, b, c) in lines {
                let rest = b * jf + c;
                if a > 0.0 {
                    lo = lo.max((-rest / a).floor());
                } else if a < 0.0 {
                    hi = hi.min((-rest / a).ceil());
                } else if rest <= 0.0 {
                    hi = lo - 1.0;
                }
            }
            // Rounding may put a span end one off: shrink it until both
            // ends pass. Each line's value is monotone along the row (in
            // floating point too), so every square between passes as well.
            while lo <= hi && !inside(lo, jf) {
                lo += 1.0;
            }
            while hi >= lo && !inside(hi, jf) {
                hi -= 1.0;
            }
            if lo > hi {
                continue;
            }
            let row = (j * self.w) as usize;
            let depths = &mut self.depth[row + lo as usize..=row + hi as usize];
            // The depth over each square (branch-free, for the
            // vectoriser): the farthest over the planes.
            let plane_row = |(a, b, c, k): (f64, f64, f64, f64)| (a, a * lo + b * jf + c, k);
            let p1 = plane_row(planes[0]);
            let p2 = plane_row(*planes.last().expect("one plane at least"));
            let depth_at = |(a, l0, k): (f64, f64, f64), i: f64| {
                let l = l0 + a * i;
                if l > 0.0 { (k / l).min(zmax) } else { zmax }
            };
            // Rounding: a relative margin besides the absolute slack.
            let store = |d: &mut f32, z: f64| *d = d.min((z * (1.0 + 1e-6)) as f32 + slack);
            if planes.len() == 1 {
                for (d, i) in depths.iter_mut().zip(0u32..) {
                    store(d, depth_at(p1, i as f64));
                }
            } else {
                for (d, i) in depths.iter_mut().zip(0u32..) {
                    store(d, depth_at(p1, i as f64).max(depth_at(p2, i as f64)));
                }
            }
        }
    }
}

/// A triangle clipped to the near plane: a convex polygon of up to four
/// corners (eye-relative), with for each edge (from corner k to k + 1) the
/// triangle edge it lies on (0: a-b, 1: b-c, 2: c-a; 3: the near plane).
struct Poly {
    verts: [DVec3; 4],
    labels: [u8; 4],
    len: usize,
}

impl Poly {
    /// Sutherland-Hodgman against `p . forward >= clip_z`.
    fn clip(t: [DVec3; 3], forward: DVec3, clip_z: f64) -> Poly {
        let mut out = Poly {
            verts: [DVec3::ZERO; 4],
            labels: [0; 4],
            len: 0,
        };
        let z = t.map(|v| v.dot(forward));
        let mut push = |v: DVec3, l: u8| {
            out.verts[out.len] = v;
            out.labels[out.len] = l;
            out.len += 1;
        };
        for k in 0..3 {
            let (s, e) = (k, (k + 1) % 3);
            let (s_in, e_in) = (z[s] >= clip_z, z[e] >= clip_z);
            let cut = || {
                let f = (clip_z - z[s]) / (z[e] - z[s]);
                let p = t[s] + (t[e] - t[s]) * f;
                // On the plane exactly (in front by construction).
                p + forward * (clip_z - p.dot(forward)).max(0.0)
            };
            match (s_in, e_in) {
                (true, true) => push(t[s], k as u8),
                (true, false) => {
                    push(t[s], k as u8);
                    push(cut(), 3);
                }
                (false, true) => push(cut(), k as u8),
                (false, false) => {}
            }
        }
        out
    }
}

/// A clipped triangle ready to fill.
#[derive(Clone, Copy, Debug)]
struct HalfPlanes {
    /// Per edge `(a, b, c)`: the square at `(i, j)` is inside the edge
    /// when `a i + b j + c > 0`.
    lines: [(f64, f64, f64); 4],
    len: usize,
    /// Which line lies on the triangle's edge a-b, if it survived clipping.
    shared: Option<usize>,
    /// The depth plane `(a, b, c, k)`: the farthest depth over the square
    /// at `(i, j)` is `k / (a i + b j + c)` when that is positive.
    plane: (f64, f64, f64, f64),
    /// The farthest corner's depth.
    zmax: f64,
    /// The image box of the corners: x from, x to, y from, y to.
    bbox: [f64; 4],
}

/// What drawing rasterises: a triangle, or two triangles `(a, b, c)` and
/// `(a, b, d)` of one object sharing the edge `a-b`.
#[derive(Clone, Copy, Debug)]
enum Prim {
    Tri([glam::Vec3; 3]),
    Pair([glam::Vec3; 4]),
}

/// Pairs an object's triangles that share an edge (same corner
/// coordinates), coplanar neighbours first (the two halves of a quad),
/// then any neighbour; the rest stay single.
fn pair_triangles(tris: &[[glam::Vec3; 3]], out: &mut Vec<Prim>) {
    use std::collections::HashMap;
    let key = |p: glam::Vec3| p.to_array().map(f32::to_bits);
    // The corners of an edge, as bits, in order: the triangles on it.
    type EdgeKey = ([u32; 3], [u32; 3]);
    let mut edges: HashMap<EdgeKey, Vec<u32>> = HashMap::new();
    for (t, tri) in tris.iter().enumerate() {
        for e in 0..3u8 {
            let (p, q) = (key(tri[e as usize]), key(tri[(e as usize + 1) % 3]));
            edges
                .entry((p.min(q), p.max(q)))
                .or_default()
                .push(t as u32);
        }
    }
    let normal = |t: &[glam::Vec3; 3]| {
        let [a, b, c] = t.map(|p| p.as_dvec3());
        (b - a).cross(c - a).normalize_or_zero()
    };
    let mut partner: Vec<Option<(u32, u8)>> = vec![None; tris.len()];
    for coplanar in [true, false] {
        for t in 0..tris.len() {
            if partner[t].is_some() {
                continue;
            }
            let nt = normal(&tris[t]);
            let mut best: Option<(f64, u32, u8)> = None;
            for e in 0..3u8 {
                let (p, q) = (key(tris[t][e as usize]), key(tris[t][(e as usize + 1) % 3]));
                for &u in &edges[&(p.min(q), p.max(q))] {
                    if u as usize == t || partner[u as usize].is_some() {
                        continue;
                    }
                    let cos = nt.dot(normal(&tris[u as usize])).abs();
                    if (!coplanar || cos > 0.9999) && best.is_none_or(|(b, _, _)| cos > b) {
                        best = Some((cos, u, e));
                    }
                }
            }
            if let Some((_, u, e)) = best {
                partner[t] = Some((u, e));
                partner[u as usize] = Some((t as u32, u8::MAX));
            }
        }
    }
    for (t, tri) in tris.iter().enumerate() {
        match partner[t] {
            None => out.push(Prim::Tri(*tri)),
            Some((_, u8::MAX)) => {} // emitted with its partner
            Some((u, e)) => {
                let e = e as usize;
                let (a, b, c) = (tri[e], tri[(e + 1) % 3], tri[(e + 2) % 3]);
                let other = &tris[u as usize];
                let d = *other
                    .iter()
                    .find(|&&p| key(p) != key(a) && key(p) != key(b))
                    .expect("a triangle sharing an edge has a third corner");
                out.push(Prim::Pair([a, b, c, d]));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::query::View;
    use crate::scene::{SceneBuilder, SceneFormat};
    use crate::trace::Tracer;
    use glam::Vec3;
    use rand::{RngExt, SeedableRng};

    fn scene_path(name: &str) -> String {
        format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"))
    }

    fn push_quad(b: &mut SceneBuilder, q: [Vec3; 4]) {
        b.push_triangle([q[0], q[1], q[2]]).unwrap();
        b.push_triangle([q[0], q[2], q[3]]).unwrap();
    }

    fn push_box(b: &mut SceneBuilder, lo: Vec3, hi: Vec3) {
        let c = |k: usize| {
            Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        };
        for q in [
            [0, 1, 3, 2],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 3, 7, 5],
        ] {
            push_quad(b, q.map(c));
        }
    }

    /// An occluder quad at x = 1 of half size `half` (in y and z), and a
    /// box behind it; the eye at the origin looks along +x.
    fn quad_and_box(half: f32, lo: Vec3, hi: Vec3) -> Scene {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("quad");
        push_quad(
            &mut b,
            [
                Vec3::new(1.0, -half, -half),
                Vec3::new(1.0, half, -half),
                Vec3::new(1.0, half, half),
                Vec3::new(1.0, -half, half),
            ],
        );
        b.begin_object("box");
        push_box(&mut b, lo, hi);
        b.finish(std::path::Path::new("test")).unwrap()
    }

    fn cull_all(scene: &Scene, cam: &Camera, lazy: bool) -> (ObjectSet, GridStats) {
        let grid = LazyGrid::new(scene);
        let mut out = ObjectSet::new(scene.objects().len());
        let params = GridParams {
            lazy,
            ..GridParams::default()
        };
        let stats = grid.cull(cam, &params, &mut out);
        (out, stats)
    }

    #[test]
    fn a_near_quad_hides_a_far_box_but_not_one_reaching_past_it() {
        let view = View::square(Vec3::ZERO, Vec3::X, 90.0);
        let cam = Camera::new(&view, 128, 128).unwrap();
        for lazy in [true, false] {
            // The quad covers the whole view; the box is small and far.
            let hidden = quad_and_box(5.0, Vec3::new(5.0, -0.1, -0.1), Vec3::new(5.2, 0.1, 0.1));
            let (out, stats) = cull_all(&hidden, &cam, lazy);
            assert!(out.contains(0), "the quad is visible");
            assert!(!out.contains(1), "the box behind it is culled: {stats:?}");
            assert!(stats.pixel_queries > 0);
            // A smaller quad: the box reaches past its edge.
            let kept = quad_and_box(0.3, Vec3::new(5.0, -0.1, -0.1), Vec3::new(5.2, 3.0, 0.1));
            let (out, _) = cull_all(&kept, &cam, lazy);
            assert!(out.contains(0) && out.contains(1), "the box is kept");
            // The box wholly behind the smaller quad (in its image) is culled.
            let small = quad_and_box(0.3, Vec3::new(5.0, -0.5, -0.5), Vec3::new(5.2, 0.5, 0.5));
            let (out, _) = cull_all(&small, &cam, lazy);
            assert!(out.contains(0) && !out.contains(1));
            // A box in front of the quad is not culled by it.
            let front = quad_and_box(5.0, Vec3::new(0.5, -0.1, -0.1), Vec3::new(0.6, 0.1, 0.1));
            let (out, _) = cull_all(&front, &cam, lazy);
            assert!(out.contains(0) && out.contains(1));
            // Behind the eye: frustum culled.
            let behind = quad_and_box(5.0, Vec3::new(-3.0, -0.1, -0.1), Vec3::new(-2.0, 0.1, 0.1));
            let (out, _) = cull_all(&behind, &cam, lazy);
            assert!(!out.contains(1));
        }
    }

    #[test]
    fn drawing_covers_only_whole_pixels() {
        let view = View::square(Vec3::ZERO, Vec3::X, 90.0);
        let cam = Camera::new(&view, 16, 16).unwrap();
        let scene = quad_and_box(
            0.53125,
            Vec3::new(5.0, -0.1, -0.1),
            Vec3::new(5.2, 0.1, 0.1),
        );
        let lazy = LazyGrid::new(&scene);
        assert!(
            matches!(lazy.prims[0], Prim::Pair(_)),
            "the quad's halves are paired"
        );
        let mut grid = Grid::new(&cam, 4);
        grid.draw_prim(&lazy.prims[0], 1e-5, 0.0);
        // The quad spans image x and y in [3.75, 12.25]: pixels 4..=11 are
        // inside (across the diagonal too), 3 and 12 only half.
        for j in 0..16u32 {
            for i in 0..16u32 {
                let covered = grid.depth[(j * 16 + i) as usize] < f32::INFINITY;
                let expect = (4..12).contains(&i) && (4..12).contains(&j);
                assert_eq!(covered, expect, "pixel ({i}, {j})");
            }
        }
    }

    fn random_cameras(scene: &Scene, seed: u64, n: usize, size: u32) -> Vec<Camera> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let b = scene.bounds();
        let mut cams = Vec::new();
        while cams.len() < n {
            let eye = b.lerp(Vec3::new(rng.random(), rng.random(), rng.random()));
            let z: f32 = rng.random_range(-1.0..1.0);
            let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let r = (1.0 - z * z).max(0.0).sqrt();
            let dir = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            if let Some(c) = Camera::new(&View::square(eye, dir, 90.0), size, size) {
                cams.push(c);
            }
        }
        cams
    }

    #[test]
    fn never_wrong_against_rays_and_lazy_equals_busy() {
        for (k, name) in ["apartment.obj", "city.obj", "office.obj"]
            .into_iter()
            .enumerate()
        {
            let scene = crate::scene::load(scene_path(name)).unwrap();
            let tracer = Tracer::new(&scene);
            let grid = LazyGrid::new(&scene);
            let n = scene.objects().len();
            let (mut lazy_out, mut busy_out) = (ObjectSet::new(n), ObjectSet::new(n));
            let (mut lazy_sum, mut busy_sum) = (GridStats::default(), GridStats::default());
            let (mut frustum, mut seen) = (0usize, 0usize);
            let views = random_cameras(&scene, 11 + k as u64, 20, 128);
            for cam in &views {
                let lazy = grid.cull(cam, &GridParams::default(), &mut lazy_out);
                let busy = grid.cull(
                    cam,
                    &GridParams {
                        lazy: false,
                        ..GridParams::default()
                    },
                    &mut busy_out,
                );
                assert_eq!(lazy_out, busy_out, "{name}: lazy and busy cull alike");
                assert_eq!(lazy.objects_drawn, lazy_out.count() as u64);
                let mut hit = ObjectSet::new(n);
                for h in tracer.closest_hits(&cam.pixel_rays()).into_iter().flatten() {
                    hit.insert(h.object as usize);
                    assert!(
                        lazy_out.contains(h.object as usize),
                        "{name}: object {} is seen from {cam:?} but culled",
                        h.object
                    );
                }
                seen += hit.count();
                frustum += scene
                    .objects()
                    .iter()
                    .filter(|o| grid.footprint(cam, &o.bounds).is_some())
                    .count();
                for (sum, s) in [(&mut lazy_sum, lazy), (&mut busy_sum, busy)] {
                    sum.pixel_queries += s.pixel_queries;
                    sum.cell_updates += s.cell_updates;
                    sum.boxes_tested += s.boxes_tested;
                    sum.objects_drawn += s.objects_drawn;
                    sum.triangles_drawn += s.triangles_drawn;
                }
            }
            let v = views.len() as f64;
            eprintln!(
                "{name}: {n} objects; mean per view: seen {:.1}, frustum {:.1}, drawn {:.1}; \
                 pixel queries lazy {:.1} busy {:.1}; cell updates lazy {:.1} busy {:.1}; \
                 boxes tested {:.1}; triangles drawn {:.1}",
                seen as f64 / v,
                frustum as f64 / v,
                lazy_sum.objects_drawn as f64 / v,
                lazy_sum.pixel_queries as f64 / v,
                busy_sum.pixel_queries as f64 / v,
                lazy_sum.cell_updates as f64 / v,
                busy_sum.cell_updates as f64 / v,
                lazy_sum.boxes_tested as f64 / v,
                lazy_sum.triangles_drawn as f64 / v,
            );
            assert!(
                lazy_sum.pixel_queries <= busy_sum.pixel_queries,
                "{name}: lazy {} > busy {} pixel queries",
                lazy_sum.pixel_queries,
                busy_sum.pixel_queries
            );
            if name != "city.obj" {
                assert!(
                    (lazy_sum.objects_drawn as f64) < 0.7 * frustum as f64,
                    "{name}: drawn {} vs frustum {}",
                    lazy_sum.objects_drawn,
                    frustum
                );
            }
        }
    }

    /// The paper's two-list traversal (Fig. 6) against drawing at once
    /// (Fig. 4): objects drawn and pixel queries per view (run with
    /// `--ignored --nocapture`).
    #[test]
    #[ignore]
    fn compare_traversals() {
        for name in ["apartment.obj", "city.obj", "office.obj"] {
            let scene = crate::scene::load(scene_path(name)).unwrap();
            let n = scene.objects().len();
            let mut out = ObjectSet::new(n);
            let views = random_cameras(&scene, 7, 100, 256);
            for paper in [true, false] {
                let mut grid = LazyGrid::new(&scene);
                grid.paper_draw_order = paper;
                let (mut d, mut q, mut f) = (0u64, 0u64, 0usize);
                for cam in &views {
                    let s = grid.cull(cam, &GridParams::default(), &mut out);
                    d += s.objects_drawn;
                    q += s.pixel_queries;
                    f += scene
                        .objects()
                        .iter()
                        .filter(|o| grid.footprint(cam, &o.bounds).is_some())
                        .count();
                }
                let v = views.len() as f64;
                eprintln!(
                    "{name} paper order (Fig. 6)={paper}: drawn {:.1} frustum {:.1} queries {:.1}",
                    d as f64 / v,
                    f as f64 / v,
                    q as f64 / v
                );
            }
        }
    }

    #[test]
    fn odd_sizes_and_both_traversals_are_never_wrong() {
        // Cells that do not divide the image, one-pixel cells, one cell
        // over the whole image, and the paper's two-list traversal.
        for name in ["apartment.obj", "machine.obj"] {
            let scene = crate::scene::load(scene_path(name)).unwrap();
            let tracer = Tracer::new(&scene);
            let mut grid = LazyGrid::new(&scene);
            let n = scene.objects().len();
            let (mut lazy, mut busy) = (ObjectSet::new(n), ObjectSet::new(n));
            for (k, cam) in random_cameras(&scene, 1234, 28, 100).iter().enumerate() {
                let cam = Camera {
                    height: 75 + k as u32 % 7,
                    ..*cam
                };
                let cell_pixels = [1, 5, 8, 16, 32, 64, 200][k % 7];
                grid.paper_draw_order = k % 2 == 0;
                grid.cull(
                    &cam,
                    &GridParams {
                        cell_pixels,
                        lazy: true,
                    },
                    &mut lazy,
                );
                grid.cull(
                    &cam,
                    &GridParams {
                        cell_pixels,
                        lazy: false,
                    },
                    &mut busy,
                );
                assert_eq!(lazy, busy, "{name}: view {k}");
                for h in tracer.closest_hits(&cam.pixel_rays()).into_iter().flatten() {
                    assert!(
                        lazy.contains(h.object as usize),
                        "{name}: view {k} misses {}",
                        h.object
                    );
                }
            }
        }
    }

    /// Time per view at 512 x 512 (run with `--ignored --nocapture`).
    #[test]
    #[ignore]
    fn time_per_view_512() {
        for name in ["apartment.obj", "city.obj", "office.obj"] {
            let scene = crate::scene::load(scene_path(name)).unwrap();
            let grid = LazyGrid::new(&scene);
            let mut out = ObjectSet::new(scene.objects().len());
            let views = random_cameras(&scene, 99, 200, 512);
            for lazy in [true, false] {
                let params = GridParams {
                    lazy,
                    ..GridParams::default()
                };
                let start = std::time::Instant::now();
                let (mut q, mut d) = (0u64, 0u64);
                for cam in &views {
                    let s = grid.cull(cam, &params, &mut out);
                    q += s.pixel_queries;
                    d += s.objects_drawn;
                }
                let per = start.elapsed().as_secs_f64() / views.len() as f64;
                eprintln!(
                    "{name} 512x512 lazy={lazy}: {:.3} ms per view, {:.1} pixel queries, {:.1} drawn",
                    per * 1e3,
                    q as f64 / views.len() as f64,
                    d as f64 / views.len() as f64
                );
            }
        }
    }
}
