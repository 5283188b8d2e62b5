//! The grid of cells over the occlusion buffer (papers/002 sec. 3.1 and
//! Fig. 2): cell states, the four-pass occlusion test of a box's
//! rectangle, and the lazy and busy updates after drawing.

use super::GridStats;
use super::lazy_grid_buffer::OcclusionBuffer;

/// An inclusive rectangle of pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Rect {
    pub(super) x0: u32,
    pub(super) y0: u32,
    pub(super) x1: u32,
    pub(super) y1: u32,
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

/// The grid of one view: `cp` x `cp` pixel cells over a `w` x `h` image.
pub(super) struct CellGrid {
    w: u32,
    h: u32,
    cp: u32,
    cells_x: u32,
    cells: Vec<Cell>,
    /// Scratch lists of the occlusion test.
    internal: Vec<u32>,
    border: Vec<u32>,
}

impl CellGrid {
    /// Every cell completely free.
    pub(super) fn new(w: u32, h: u32, cp: u32) -> Self {
        let cells_x = w.div_ceil(cp);
        let cells_y = h.div_ceil(cp);
        Self {
            w,
            h,
            cp,
            cells_x,
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
    fn update_cell(&mut self, k: u32, buffer: &OcclusionBuffer, stats: &mut GridStats) {
        stats.pixel_queries += 1;
        stats.cell_updates += 1;
        let r = self.cell_rect(k);
        let (mut any_free, mut all_free, mut zfar) = (false, true, f32::NEG_INFINITY);
        for y in r.y0..=r.y1 {
            for &d in buffer.row(y, r.x0, r.x1) {
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
    pub(super) fn is_occluded(
        &mut self,
        rect: &Rect,
        znear: f32,
        buffer: &OcclusionBuffer,
        stats: &mut GridStats,
    ) -> bool {
        let mut internal = std::mem::take(&mut self.internal);
        let mut border = std::mem::take(&mut self.border);
        internal.clear();
        border.clear();
        let occluded = self.test_cells(rect, znear, buffer, stats, &mut internal, &mut border);
        self.internal = internal;
        self.border = border;
        occluded
    }

    fn test_cells(
        &mut self,
        rect: &Rect,
        znear: f32,
        buffer: &OcclusionBuffer,
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
            self.update_cell(k, buffer, stats);
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
                let hit = buffer.row(y, r.x0, r.x1).iter().find(|&&d| d >= znear);
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
    pub(super) fn mark_outdated(&mut self, rect: &Rect) {
        for k in self.cells_of(rect) {
            let c = &mut self.cells[k as usize];
            if !c.full {
                c.occ = Occ::Outdated;
            }
        }
    }

    /// Busy: the non-full cells of `rect` are updated now.
    pub(super) fn update_busy(
        &mut self,
        rect: &Rect,
        buffer: &OcclusionBuffer,
        stats: &mut GridStats,
    ) {
        for k in self.cells_of(rect) {
            if !self.cells[k as usize].full {
                self.update_cell(k, buffer, stats);
            }
        }
    }
}
