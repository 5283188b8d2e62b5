//! The front-to-back traversal of the object-box hierarchy (papers/002
//! sec. 4): boxes tested in order of their nearest depth, occluded
//! subtrees dropped, visible objects drawn into the occlusion buffer.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::lazy_grid_buffer::OcclusionBuffer;
use super::lazy_grid_cells::{CellGrid, Rect};
use super::{GridParams, GridStats, LazyGrid};
use crate::bitset::ObjectSet;
use crate::geom::{Aabb, BoxNode};
use crate::render::Camera;

/// Widening of a box's projected rectangle, in pixels (rounding of the
/// projection).
const RECT_MARGIN: f32 = 0.01;

/// What a box looks like from the camera.
#[derive(Clone, Copy, Debug)]
pub(super) struct Footprint {
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

impl LazyGrid<'_> {
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
        let mut buffer = OcclusionBuffer::new(camera);
        let mut grid = CellGrid::new(camera.width, camera.height, params.cell_pixels.max(1));
        let nodes = self.hierarchy.nodes();
        let Some(root) = nodes.first() else {
            return stats;
        };
        let mut tests = BinaryHeap::new();
        let mut draws: BinaryHeap<Entry> = BinaryHeap::new();
        if let Some(fp) = self.footprint(camera, root.bounds()) {
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
                let BoxNode::Object { object: o, .. } = nodes[e.node as usize] else {
                    unreachable!("only leaves are drawn")
                };
                let tris = self.scene.object_triangles(o as usize);
                stats.objects_drawn += 1;
                stats.triangles_drawn += tris.len() as u64;
                let prims = &self.prims[self.prim_start[o as usize] as usize
                    ..self.prim_start[o as usize + 1] as usize];
                for p in prims {
                    buffer.draw_prim(p, self.near, self.depth_slack);
                }
                if params.lazy {
                    grid.mark_outdated(&e.fp.rect);
                } else {
                    grid.update_busy(&e.fp.rect, &buffer, &mut stats);
                }
            } else {
                let e = tests.pop().expect("peeked");
                stats.boxes_tested += 1;
                let visible = e.fp.crosses_near
                    || !grid.is_occluded(&e.fp.rect, e.fp.znear, &buffer, &mut stats);
                if !visible {
                    continue;
                }
                match nodes[e.node as usize] {
                    BoxNode::Object { object: o, .. } => {
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
                    BoxNode::Inner { children, .. } => {
                        for c in children {
                            if let Some(fp) = self.footprint(camera, nodes[c as usize].bounds()) {
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
    pub(super) fn footprint(&self, cam: &Camera, b: &Aabb) -> Option<Footprint> {
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
