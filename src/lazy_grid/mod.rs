//! The lazy occlusion grid of Hey, Tobler & Purgathofer, *Real-time
//! occlusion culling with a lazy occlusion grid* (EGWR 2001, papers/002),
//! in its occlusion-buffer variant, in software: a from-point,
//! conservative, image-based culling baseline for one view.
//!
//! ## The method
//!
//! The image of the [`Camera`](crate::render::Camera) is covered by an occlusion buffer (one entry
//! per pixel) and, on top of it, a low-resolution grid of cells of
//! `cell_pixels` x `cell_pixels` pixels (the last column and row of cells
//! may be narrower). A bounding-volume hierarchy over the objects' boxes
//! (built once per scene by [`LazyGrid::new`]: the shared
//! [`BoxTree`], median splits of the box centres along the widest axis,
//! one object per leaf) is traversed front
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

//!
//! ## Files
//!
//! - `lazy_grid_buffer.rs`: the occlusion buffer and the conservative
//!   drawing of triangles (and pairs of triangles) into it;
//! - `lazy_grid_cells.rs`: the cells, their states, the Fig. 2 test, lazy
//!   and busy updates;
//! - `lazy_grid_traversal.rs`: the front-to-back traversal of the box
//!   hierarchy, [`LazyGrid::cull`];
//! - `lazy_grid_tests.rs`: tests against pixel rays, lazy against busy.

mod lazy_grid_buffer;
mod lazy_grid_cells;
#[cfg(test)]
mod lazy_grid_tests;
mod lazy_grid_traversal;

use crate::geom::{Aabb, BoxTree};
use crate::scene::Scene;
use lazy_grid_buffer::{Prim, pair_triangles};

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

/// The grid over one scene (its object-box hierarchy).
pub struct LazyGrid<'a> {
    scene: &'a Scene,
    /// The hierarchy of the objects' boxes.
    hierarchy: BoxTree,
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
            .field("nodes", &self.hierarchy.nodes().len())
            .field("near", &self.near)
            .finish()
    }
}

impl<'a> LazyGrid<'a> {
    /// Builds the object-box hierarchy of `scene` (median splits of the
    /// box centres along the widest axis, one object per leaf).
    pub fn new(scene: &'a Scene) -> Self {
        let boxes: Vec<Aabb> = scene.objects().iter().map(|o| o.bounds).collect();
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
            hierarchy: BoxTree::new(&boxes),
            prims,
            prim_start,
            paper_draw_order: false,
            near: 1e-5 * diag,
            depth_slack: 1e-6 * diag,
        }
    }
}
