//! The object table of a loaded file, as queries and engines read it: per
//! object a 16-byte row and its box (24 bytes, apart, for the frustum
//! cull to read alone, eight boxes to a [`Boxes8`]), and one string
//! holding the names and the ids (an id is stored only where it is not
//! the name, as it mostly is).

use glam::Vec3;

use super::Frustum;
use super::query_cull::{Boxes8, Cull, UNBOUNDED, corners, scene_box};
use crate::codec::{FileObject, ObjectFlags};
use crate::geom::Aabb;

/// One object of a loaded file ([`super::Pvs::object`],
/// [`super::Pvs::objects`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectInfo<'a> {
    name: &'a str,
    id: &'a str,
    triangles: u32,
    bounds: Option<Aabb>,
    flags: ObjectFlags,
}

impl<'a> ObjectInfo<'a> {
    /// The object's name in the scene (OBJ `o`/`g` name, glTF node or
    /// mesh name); names may repeat.
    pub fn name(&self) -> &'a str {
        self.name
    }

    /// Its id, unique in the file: the name where names are unique,
    /// `name#k` where they repeat, or the id given at build time
    /// ([`crate::codec::default_ids`]).
    pub fn id(&self) -> &'a str {
        self.id
    }

    /// Its triangle count (what drawing it costs).
    pub fn triangles(&self) -> u32 {
        self.triangles
    }

    /// Its bounding box in the tree's local coordinates, quantised
    /// outwards (it holds the object); `None` when the file does not say
    /// (version 1) or the object has no triangles.
    pub fn bounds(&self) -> Option<Aabb> {
        self.bounds
    }

    /// Its flags, set at bake time (always visible, never an occluder).
    pub fn flags(&self) -> ObjectFlags {
        self.flags
    }
}

/// One object's row.
#[derive(Clone, Copy, Debug)]
struct Row {
    /// Where its name ends in [`ObjectTable::text`] (it starts where the
    /// row before ends).
    name_end: u32,
    /// Where its id ends: the name's end when the id is the name.
    id_end: u32,
    triangles: u32,
    flags: ObjectFlags,
    /// Whether its box in [`ObjectTable::boxes`] is the object's.
    bounded: bool,
}

/// The objects of a loaded file (see the module docs).
#[derive(Clone, Debug)]
pub(crate) struct ObjectTable {
    text: String,
    rows: Vec<Row>,
    /// Per object, its box's corners, object i in group i / 8
    /// ([`Cull::keeps8`]): [`UNBOUNDED`] where the file gives none, or the
    /// object has no triangles, and past the last object.
    boxes: Vec<Boxes8>,
    /// The box of all the objects' boxes, when one has a box.
    scene: Option<Aabb>,
    /// The objects in the order of their ids, for [`ObjectTable::index`].
    by_id: Vec<u32>,
}

impl ObjectTable {
    /// The table of a file's objects. `None` when the names and ids pass
    /// 4 GiB.
    pub(crate) fn new(objects: &[FileObject]) -> Option<ObjectTable> {
        let mut text = String::new();
        let mut rows = Vec::with_capacity(objects.len());
        let mut boxes = vec![Boxes8::UNBOUNDED; objects.len().div_ceil(8)];
        for o in objects {
            text.push_str(&o.name);
            let name_end = u32::try_from(text.len()).ok()?;
            if o.id != o.name {
                text.push_str(&o.id);
            }
            // An empty box (no triangles) is kept as none: queries never
            // cull by it.
            let b = o.bounds.filter(|b| !b.is_empty());
            let i = rows.len();
            boxes[i / 8].set(i % 8, &b.as_ref().map_or(UNBOUNDED, corners));
            rows.push(Row {
                name_end,
                id_end: u32::try_from(text.len()).ok()?,
                triangles: o.triangles,
                flags: o.flags,
                bounded: b.is_some(),
            });
        }
        let scene = scene_box(
            objects
                .iter()
                .filter_map(|o| o.bounds.as_ref())
                .filter(|b| !b.is_empty()),
        );
        text.shrink_to_fit();
        let mut by_id: Vec<u32> = (0..objects.len() as u32).collect();
        by_id.sort_unstable_by(|&a, &b| objects[a as usize].id.cmp(&objects[b as usize].id));
        Some(ObjectTable {
            text,
            rows,
            boxes,
            scene,
            by_id,
        })
    }

    /// The number of objects.
    pub(crate) fn len(&self) -> usize {
        self.rows.len()
    }

    /// Object `i`.
    pub(crate) fn get(&self, i: usize) -> Option<ObjectInfo<'_>> {
        (i < self.rows.len()).then(|| self.at(i))
    }

    /// Object `i`, which must be in range.
    pub(crate) fn at(&self, i: usize) -> ObjectInfo<'_> {
        let row = &self.rows[i];
        let start = match i {
            0 => 0,
            _ => self.rows[i - 1].id_end,
        } as usize;
        let name = &self.text[start..row.name_end as usize];
        let id = match row.id_end == row.name_end {
            true => name,
            false => &self.text[row.name_end as usize..row.id_end as usize],
        };
        ObjectInfo {
            name,
            id,
            triangles: row.triangles,
            bounds: self.bounds(i),
            flags: row.flags,
        }
    }

    /// Object `i`'s bounds (`i` in range).
    #[inline]
    pub(crate) fn bounds(&self, i: usize) -> Option<Aabb> {
        let b = self.boxes[i / 8].get(i % 8);
        self.rows[i].bounded.then(|| Aabb {
            min: Vec3::new(b[0], b[1], b[2]),
            max: Vec3::new(b[3], b[4], b[5]),
        })
    }

    /// Object `i`'s triangle count (`i` in range).
    pub(crate) fn triangles(&self, i: usize) -> u32 {
        self.rows[i].triangles
    }

    /// The object whose id is `id`.
    pub(crate) fn index(&self, id: &str) -> Option<usize> {
        self.by_id
            .binary_search_by(|&o| self.at(o as usize).id.cmp(id))
            .ok()
            .map(|k| self.by_id[k] as usize)
    }

    /// Removes from `out` (a bitset over the objects) the objects whose
    /// boxes `frustum` cannot see ([`Cull`]); culls nothing when no object
    /// has a box (a version 1 file).
    pub(crate) fn cull(&self, frustum: &Frustum, out: &mut [u64]) {
        let Some(scene) = &self.scene else {
            return;
        };
        let cull = Cull::new(frustum, scene);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX.
            unsafe { cull_words_avx(&cull, &self.boxes, out) };
            return;
        }
        cull_words(&cull, &self.boxes, out, Cull::keeps8);
    }

    /// The bytes held.
    pub(crate) fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.text.capacity()
            + self.rows.capacity() * std::mem::size_of::<Row>()
            + self.boxes.capacity() * std::mem::size_of::<Boxes8>()
            + self.by_id.capacity() * 4
    }
}

/// Removes from `out` the objects whose boxes `cull` does not keep: each
/// byte of a word that holds an object tests its eight boxes at once with
/// `keeps8` (objects past `boxes` are kept).
#[inline(always)]
fn cull_words(
    cull: &Cull,
    boxes: &[Boxes8],
    out: &mut [u64],
    keeps8: impl Fn(&Cull, &Boxes8) -> u8,
) {
    for (word, boxes) in out.iter_mut().zip(boxes.chunks(8)) {
        // Only the bytes that hold an object: sparse answers (one
        // apartment of a block) cost what their objects cost.
        let (mut bits, mut kept) = (*word, 0);
        while bits != 0 {
            let shift = bits.trailing_zeros() & !7;
            bits &= !(0xff << shift);
            // A byte past the last group holds no object: kept as it is.
            kept |= boxes
                .get(shift as usize / 8)
                .map_or(0xff, |b| u64::from(keeps8(cull, b)))
                << shift;
        }
        *word &= kept;
    }
}

/// [`cull_words`] with [`Cull::keeps8_avx`], inlined.
///
/// # Safety
/// The CPU must have AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn cull_words_avx(cull: &Cull, boxes: &[Boxes8], out: &mut [u64]) {
    cull_words(cull, boxes, out, |c, b| c.keeps8_avx(b));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_ids_and_bounds_come_back() {
        let object = |name: &str, id: &str, bounds: Option<Aabb>| FileObject {
            name: name.into(),
            id: id.into(),
            triangles: name.len() as u32,
            bounds,
            flags: ObjectFlags::NONE,
        };
        let b = Aabb::new(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 4.0, 5.0));
        let objects = [
            object("crate", "crate#1", Some(b)),
            object("", "", None),
            object("crate", "crate#2", None),
            object("floor", "floor", Some(b)),
            object("ünï", "door-17", Some(b)),
        ];
        let table = ObjectTable::new(&objects).unwrap();
        assert_eq!(table.len(), 5);
        for (i, o) in objects.iter().enumerate() {
            let got = table.get(i).unwrap();
            assert_eq!(
                (
                    got.name(),
                    got.id(),
                    got.triangles(),
                    got.bounds(),
                    got.flags()
                ),
                (
                    o.name.as_str(),
                    o.id.as_str(),
                    o.triangles,
                    o.bounds,
                    o.flags
                )
            );
            assert_eq!(table.index(&o.id), Some(i));
        }
        assert_eq!(table.get(5), None);
        assert_eq!(table.index("crate"), None);
        // The ids equal to names are not stored twice.
        assert_eq!(
            table.text.len(),
            "cratecrate#1cratecrate#2floorünïdoor-17".len()
        );
    }
}
