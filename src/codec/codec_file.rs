//! The `.v5d` file: a header, the build parameters, the object table, the
//! coded tree and a checksum. The byte layout is specified in
//! `notes/format.md`; this file implements exactly that, little-endian.
//!
//! Reading is defensive: the size is checked before the magic, the magic
//! before the version, the checksum before anything is parsed, every length
//! against the bytes left, every count against what the bytes can hold and
//! against the decode budget ([`ReadLimits`]), before anything is
//! allocated.

use glam::{DVec3, Vec3};

use super::CodecError;
use super::codec_bounds::BoundsGrid;
use super::codec_flags::ObjectFlags;
use super::codec_tree::{Coding, DecodeLimits, decode, encode};
use crate::geom::cell::{Cell, DIMS};
use crate::geom::{Aabb, Frame, Up};
use crate::slices::TreeSlices;
use crate::tree::{LeafRecord, VisTree};

/// The first 8 bytes of every `.v5d` file: a non-ASCII byte, "V5D", CR LF,
/// EOF, LF (after PNG's: catches text-mode mangling and truncated
/// transfers).
pub const MAGIC: [u8; 8] = [0x89, b'V', b'5', b'D', b'\r', b'\n', 0x1a, b'\n'];

/// The format version this code writes. It reads this one, version 5 (no
/// object flags), version 4 (no up axis: +z), version 3 (no slices either), version 2 (no leaf records
/// either) and version 1 (which has no frame origin either: its trees are
/// in world coordinates).
pub const VERSION: u16 = 6;

/// The size of the fixed header of a file of `version`, before the
/// parameters: version 2 added the frame origin (three f64) and the grid
/// of the object bounds (six f32), version 5 the up axis (one byte).
const fn fixed_len(version: u16) -> usize {
    let v1 = 8 + 2 + 1 + 1 + 4 + 4 + 4 + 8 + 4 * 2 * DIMS + 4;
    match version {
        5.. => v1 + 3 * 8 + 1 + 6 * 4,
        2..=4 => v1 + 3 * 8 + 6 * 4,
        _ => v1,
    }
}

/// The fewest bytes an object's entry takes in a file of `version`: its
/// triangle count, (version 2) its bounds codes, its name's length,
/// (version 5) its id's length, (version 6) its flags.
const fn min_object_len(version: u16) -> usize {
    match version {
        6.. => 4 + 12 + 2 + 2 + 1,
        5 => 4 + 12 + 2 + 2,
        2..=4 => 4 + 12 + 2,
        _ => 4 + 2,
    }
}

/// What follows the object table in a file of `version`, at the least:
/// the tree's bit length, (version 3) the leaf records' byte length and
/// (version 4) the slices' byte length.
const fn min_tail_len(version: u16) -> usize {
    match version {
        4.. => 8 + 4 + 4,
        3 => 8 + 4,
        _ => 8,
    }
}

/// The smallest possible file of the version written: the fixed header,
/// empty parameters, no objects, the bit length, no tree bytes, no leaf
/// records, the checksum. (Version 1 and 2 files may be shorter.)
pub const MIN_FILE_LEN: usize = fixed_len(VERSION) + min_tail_len(VERSION) + 4;

/// One object of the file's object table.
#[derive(Clone, Debug, PartialEq)]
pub struct FileObject {
    /// The object's name in the scene.
    pub name: String,
    /// Its id, unique in the file ([`super::default_ids`], or one the
    /// user gave at build time; files before version 5: the default).
    pub id: String,
    /// Its triangle count (what drawing it costs).
    pub triangles: u32,
    /// Its bounding box in the tree's local coordinates, as stored:
    /// quantised outwards (it holds the object's box); `None` when the
    /// file does not say (version 1) and for an object of no triangles
    /// (an empty group of the model: no box).
    pub bounds: Option<Aabb>,
    /// Its flags, set at bake time (version 6; older files: none).
    pub flags: ObjectFlags,
}

/// Everything a `.v5d` file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct V5dFile {
    /// How the tree's sets are coded.
    pub coding: Coding,
    /// The fingerprint of the scene geometry the tree was built for
    /// ([`geometry_fingerprint`]).
    pub fingerprint: u64,
    /// Where the tree's local coordinates sit in the world (the identity
    /// for a version 1 file).
    pub frame: Frame,
    /// The build parameters, as `key=value` lines.
    pub params: String,
    /// The objects, in scene order.
    pub objects: Vec<FileObject>,
    /// The tree (its root cell and grid bits are stored in the header).
    pub tree: VisTree,
    /// The slices of the tree's leaves (papers/004), when it has them
    /// (version 4): cut into at most [`crate::slices::MAX_STORED_SLICES`]
    /// slices an axis (an index is then 3 bytes), one leaf row per leaf.
    pub slices: Option<TreeSlices>,
}

/// Bounds on what reading a file may allocate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// The most bytes the decoded tree's sets may take.
    pub max_decoded_bytes: usize,
    /// The most bytes a `.v5d` file read from disk may hold
    /// ([`crate::query::Pvs::load`]).
    pub max_file_bytes: u64,
}

impl Default for ReadLimits {
    /// 1 GiB of decoded sets: 60 times the largest tree measured
    /// (notes/format.md), and a bound on what a hostile file can ask for;
    /// files of up to 1 GiB.
    fn default() -> Self {
        Self {
            max_decoded_bytes: 1 << 30,
            max_file_bytes: 1 << 30,
        }
    }
}

/// The 64-bit FNV-1a hash of a scene's geometry: the number of objects,
/// each object's triangle count and the bits of every (local) coordinate,
/// in order, then the frame's origin when it is not zero and its up axis
/// when it is not z (so a scene near the origin, +z up, hashes as it did
/// before frames existed). Names are not included: renaming an object does
/// not change what is visible.
pub fn geometry_fingerprint<'a>(
    objects: impl IntoIterator<Item = &'a [[Vec3; 3]]>,
    frame: &Frame,
) -> u64 {
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(PRIME);
        }
    };
    eat(b"vis5d-geometry-1");
    let mut count = 0u64;
    for tris in objects {
        count += 1;
        eat(&(tris.len() as u64).to_le_bytes());
        for t in tris {
            for v in t {
                for c in v.to_array() {
                    eat(&c.to_bits().to_le_bytes());
                }
            }
        }
    }
    eat(&count.to_le_bytes());
    if !frame.at_world_origin() {
        eat(b"origin");
        for c in frame.origin.to_array() {
            eat(&c.to_bits().to_le_bytes());
        }
    }
    if frame.up != Up::Z {
        eat(b"up");
        eat(&[frame.up.axis() as u8]);
    }
    h
}

/// Why [`fingerprint_meshes`] cannot fingerprint an engine's buffers.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MeshError {
    /// An object's index count is not a multiple of three.
    #[error("object {object}: {count} indices do not make whole triangles")]
    Indices {
        /// The object's place in the list.
        object: usize,
        /// Its index count.
        count: usize,
    },
    /// An index names no vertex.
    #[error("object {object}: index {index} but only {vertices} vertices")]
    OutOfRange {
        /// The object's place in the list.
        object: usize,
        /// The index.
        index: u32,
        /// Its vertex count.
        vertices: usize,
    },
    /// A vertex of a triangle is NaN or infinite.
    #[error("object {object}: a vertex of a triangle is not finite")]
    NonFinite {
        /// The object's place in the list.
        object: usize,
    },
    /// No triangle has a non-zero area: the loaders refuse such a model.
    #[error("no triangle has a non-zero area")]
    Empty,
}

/// The geometry fingerprint that `vis5d build` stores for a model, from
/// the model as an engine holds it: per object, in the model's order, its
/// vertex positions in world coordinates and a triangle list of indices
/// into them; `up` is the build's `--up`. Equal to
/// `Scene::fingerprint` of the model loaded from OBJ, glTF or GLB alike
/// (compare it with [`crate::query::Pvs::fingerprint`] to know that a
/// `.v5d` was built for the geometry at hand).
///
/// Computed as the loaders do: triangles of zero area are left out
/// ([`crate::geom::zero_area`]), and an object left without triangles
/// (or given none) still counts, as an empty object (the loaders list
/// empty groups in their places); the frame of a model far from the
/// origin is chosen from the rest ([`Frame::for_bounds`]). The positions must be the ones the loader
/// reads, bit for bit: a glTF node's transform is applied by the loader
/// in f64 and rounded once, so an engine that composes transforms in f32
/// may differ in the last bit of a moved vertex.
pub fn fingerprint_meshes(objects: &[(&[[f32; 3]], &[u32])], up: Up) -> Result<u64, MeshError> {
    for (object, (positions, indices)) in objects.iter().enumerate() {
        if !indices.len().is_multiple_of(3) {
            return Err(MeshError::Indices {
                object,
                count: indices.len(),
            });
        }
        if let Some(&index) = indices.iter().find(|&&i| i as usize >= positions.len()) {
            return Err(MeshError::OutOfRange {
                object,
                index,
                vertices: positions.len(),
            });
        }
        if indices
            .iter()
            .any(|&i| !positions[i as usize].iter().all(|c| c.is_finite()))
        {
            return Err(MeshError::NonFinite { object });
        }
    }
    let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for t in objects.iter().flat_map(|&(p, i)| mesh_triangles(p, i)) {
        if !crate::geom::zero_area(&t) {
            for v in t {
                min = min.min(v);
                max = max.max(v);
            }
        }
    }
    if min.x > max.x {
        return Err(MeshError::Empty);
    }
    // As the loaders: local coordinates in the +z frame, zero areas
    // decided there, then the axes turned (exactly) for `up`.
    let z_up = Frame::for_bounds(min, max, Up::Z);
    let frame = Frame { up, ..z_up };
    let local: Vec<Vec<[Vec3; 3]>> = objects
        .iter()
        .map(|o| {
            mesh_triangles(o.0, o.1)
                .map(|t| t.map(|v| z_up.to_local(v)))
                .filter(|t| !crate::geom::zero_area(&t.map(|v| v.as_dvec3())))
                .map(|t| t.map(|v| frame.dir_to_local(v)))
                .collect()
        })
        .collect();
    Ok(geometry_fingerprint(
        local.iter().map(Vec::as_slice),
        &frame,
    ))
}

/// The triangles of an indexed mesh, corners in f64.
fn mesh_triangles<'a>(
    positions: &'a [[f32; 3]],
    indices: &'a [u32],
) -> impl Iterator<Item = [DVec3; 3]> + 'a {
    indices
        .chunks_exact(3)
        .map(move |t| [0, 1, 2].map(|k| DVec3::from_array(positions[t[k] as usize].map(f64::from))))
}

/// The CRC-32 (IEEE 802.3, as in zip and PNG) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut t = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
                k += 1;
            }
            t[i] = c;
            i += 1;
        }
        t
    };
    let mut c = !0u32;
    for &b in bytes {
        c = TABLE[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}

/// Writes `file` in the `.v5d` format. The tree must satisfy
/// [`VisTree::validate`].
pub fn write_file(file: &V5dFile) -> Vec<u8> {
    let tree = &file.tree;
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.push(file.coding.to_byte());
    out.push(tree.grid_bits() as u8);
    out.extend_from_slice(&(file.objects.len() as u32).to_le_bytes());
    out.extend_from_slice(&(tree.nodes().len() as u32).to_le_bytes());
    out.extend_from_slice(&(tree.leaf_count() as u32).to_le_bytes());
    out.extend_from_slice(&file.fingerprint.to_le_bytes());
    let root = tree.root_cell();
    for v in root.lo.iter().chain(&root.hi) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for c in file.frame.origin.to_array() {
        out.extend_from_slice(&c.to_le_bytes());
    }
    out.push(file.frame.up.axis() as u8);
    let grid = BoundsGrid::over(file.objects.iter().filter_map(|o| o.bounds.as_ref()));
    for v in grid
        .space
        .min
        .to_array()
        .iter()
        .chain(&grid.space.max.to_array())
    {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(file.params.len() as u32).to_le_bytes());
    out.extend_from_slice(file.params.as_bytes());
    for o in &file.objects {
        out.extend_from_slice(&o.triangles.to_le_bytes());
        for q in grid.quantise(o.bounds.as_ref()) {
            out.extend_from_slice(&q.to_le_bytes());
        }
        // At most 65535 bytes, cut at a character boundary.
        let mut end = o.name.len().min(u16::MAX as usize);
        while !o.name.is_char_boundary(end) {
            end -= 1;
        }
        let name = &o.name.as_bytes()[..end];
        out.extend_from_slice(&(name.len() as u16).to_le_bytes());
        out.extend_from_slice(name);
        // The id: length 0 when it is the name; else at most 65535 bytes,
        // cut at a character boundary.
        let id: &[u8] = if o.id == o.name || o.id.as_bytes() == name {
            &[]
        } else {
            let mut end = o.id.len().min(u16::MAX as usize);
            while !o.id.is_char_boundary(end) {
                end -= 1;
            }
            &o.id.as_bytes()[..end]
        };
        out.extend_from_slice(&(id.len() as u16).to_le_bytes());
        out.extend_from_slice(id);
        out.push(o.flags.bits());
    }
    let (bits, _) = encode(tree, file.coding);
    out.extend_from_slice(&bits.bit_len().to_le_bytes());
    out.extend_from_slice(&bits.into_bytes());
    let mut records = Vec::new();
    for r in tree.leaf_records().unwrap_or_default() {
        for v in [r.rejected, r.fewest_rays, r.undecided] {
            put_varint(&mut records, v);
        }
    }
    out.extend_from_slice(&(records.len() as u32).to_le_bytes());
    out.extend_from_slice(&records);
    let slices = file
        .slices
        .as_ref()
        .map(crate::slices::encode_section)
        .unwrap_or_default();
    out.extend_from_slice(&(slices.len() as u32).to_le_bytes());
    out.extend_from_slice(&slices);
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Why a LEB128 number cannot be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum VarintError {
    /// The bytes end in the middle of it.
    End,
    /// Its value is over 32 bits.
    TooBig,
    /// It runs over 5 bytes.
    TooLong,
}

/// Reads a LEB128 u32 at `*pos` of `bytes`, moving `pos` past it.
pub(crate) fn get_varint(bytes: &[u8], pos: &mut usize) -> Result<u32, VarintError> {
    let mut v: u64 = 0;
    for shift in (0..35).step_by(7) {
        let &b = bytes.get(*pos).ok_or(VarintError::End)?;
        *pos += 1;
        v |= u64::from(b & 0x7f) << shift;
        if b & 0x80 == 0 {
            return u32::try_from(v).map_err(|_| VarintError::TooBig);
        }
    }
    Err(VarintError::TooLong)
}

/// Appends `v` as LEB128: 7 bits a byte, low first, the high bit set on
/// every byte but the last.
pub(crate) fn put_varint(out: &mut Vec<u8>, mut v: u32) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Reads the leaf records of a file whose header says `leaves` leaves:
/// exactly `leaves` records of three LEB128 u32 each, filling `bytes`.
fn read_leaf_records(bytes: &[u8], leaves: usize) -> Result<Vec<LeafRecord>, CodecError> {
    // Each record takes at least 3 bytes: bound the count first.
    if leaves > bytes.len() / 3 {
        return Err(CodecError::Corrupt(format!(
            "{leaves} leaf records cannot fit in {} bytes",
            bytes.len()
        )));
    }
    let mut pos = 0;
    let mut next = |what: &str| -> Result<u32, CodecError> {
        get_varint(bytes, &mut pos).map_err(|e| {
            CodecError::Corrupt(match e {
                VarintError::End => format!("the leaf records end in the middle of {what}"),
                VarintError::TooBig => format!("a leaf record's {what} is over 32 bits"),
                VarintError::TooLong => format!("a leaf record's {what} is over 5 bytes"),
            })
        })
    };
    let mut records = Vec::with_capacity(leaves);
    for _ in 0..leaves {
        records.push(LeafRecord {
            rejected: next("rejected count")?,
            fewest_rays: next("fewest rays")?,
            undecided: next("undecided count")?,
        });
    }
    if pos != bytes.len() {
        return Err(CodecError::Corrupt(format!(
            "{} bytes are left over after the {leaves} leaf records",
            bytes.len() - pos
        )));
    }
    Ok(records)
}

/// A cursor over the file's bytes whose every read is checked.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], CodecError> {
        let left = self.bytes.len() - self.pos;
        if n > left {
            return Err(CodecError::Truncated(format!(
                "{what} needs {n} bytes at offset {} but {left} are left",
                self.pos
            )));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn u8(&mut self, what: &str) -> Result<u8, CodecError> {
        Ok(self.take(1, what)?[0])
    }

    fn u16(&mut self, what: &str) -> Result<u16, CodecError> {
        Ok(u16::from_le_bytes(
            self.take(2, what)?.try_into().expect("2 bytes"),
        ))
    }

    fn u32(&mut self, what: &str) -> Result<u32, CodecError> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().expect("4 bytes"),
        ))
    }

    fn u64(&mut self, what: &str) -> Result<u64, CodecError> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8 bytes"),
        ))
    }

    fn f64(&mut self, what: &str) -> Result<f64, CodecError> {
        Ok(f64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8 bytes"),
        ))
    }

    fn f32(&mut self, what: &str) -> Result<f32, CodecError> {
        Ok(f32::from_le_bytes(
            self.take(4, what)?.try_into().expect("4 bytes"),
        ))
    }

    fn left(&self) -> usize {
        self.bytes.len() - self.pos
    }
}

/// Reads a `.v5d` file.
pub fn read_file(bytes: &[u8], limits: ReadLimits) -> Result<V5dFile, CodecError> {
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        return Err(CodecError::NotV5d);
    }
    let smallest = |version| fixed_len(version) + min_tail_len(version) + 4;
    if bytes.len() < smallest(1) {
        return Err(CodecError::Truncated(format!(
            "{} bytes, but the smallest .v5d file has {}",
            bytes.len(),
            smallest(1)
        )));
    }
    let version = u16::from_le_bytes([bytes[8], bytes[9]]);
    if !(1..=VERSION).contains(&version) {
        return Err(CodecError::Version(version));
    }
    if bytes.len() < smallest(version) {
        return Err(CodecError::Truncated(format!(
            "{} bytes, but the smallest .v5d file of version {version} has {}",
            bytes.len(),
            smallest(version)
        )));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes(tail.try_into().expect("4 bytes"));
    let computed = crc32(body);
    if stored != computed {
        return Err(CodecError::Checksum { stored, computed });
    }
    parse_body(body, version, limits)
}

/// Parses everything before the checksum of a file of `version`.
fn parse_body(body: &[u8], version: u16, limits: ReadLimits) -> Result<V5dFile, CodecError> {
    let mut c = Cursor {
        bytes: body,
        pos: MAGIC.len() + 2,
    };
    let coding_byte = c.u8("the coding")?;
    let coding = Coding::from_byte(coding_byte)
        .ok_or_else(|| CodecError::Corrupt(format!("unknown coding {coding_byte}")))?;
    let grid_bits = c.u8("the grid bits")? as u32;
    if !(1..=16).contains(&grid_bits) {
        return Err(CodecError::Corrupt(format!(
            "grid bits {grid_bits} outside 1..=16"
        )));
    }
    let objects = c.u32("the object count")? as usize;
    let nodes = c.u32("the node count")? as usize;
    let leaves = c.u32("the leaf count")? as usize;
    if leaves == 0 || nodes as u64 != 2 * leaves as u64 - 1 {
        return Err(CodecError::Corrupt(format!(
            "{nodes} nodes and {leaves} leaves do not make a binary tree"
        )));
    }
    let fingerprint = c.u64("the fingerprint")?;
    let mut root = Cell {
        lo: [0.0; DIMS],
        hi: [0.0; DIMS],
    };
    for d in 0..DIMS {
        root.lo[d] = c.f32("the root cell")?;
    }
    for d in 0..DIMS {
        root.hi[d] = c.f32("the root cell")?;
    }
    if !(0..DIMS)
        .all(|d| root.lo[d].is_finite() && root.hi[d].is_finite() && root.lo[d] < root.hi[d])
    {
        return Err(CodecError::Corrupt(format!(
            "the root cell {:?} .. {:?} is not a box (finite, low < high)",
            root.lo, root.hi
        )));
    }
    let frame = if version >= 2 {
        let mut origin = [0.0; 3];
        for k in &mut origin {
            *k = c.f64("the frame origin")?;
        }
        let origin = DVec3::from_array(origin);
        if !origin.is_finite() {
            return Err(CodecError::Corrupt(format!(
                "the frame origin {origin} is not finite"
            )));
        }
        let up = if version >= 5 {
            let byte = c.u8("the up axis")?;
            Up::from_axis(byte as usize).ok_or_else(|| {
                CodecError::Corrupt(format!("up axis {byte} is not 0 (x), 1 (y) or 2 (z)"))
            })?
        } else {
            Up::Z
        };
        Frame { origin, up }
    } else {
        Frame::IDENTITY
    };
    let grid = if version >= 2 {
        let mut corners = [0.0f32; 6];
        for k in &mut corners {
            *k = c.f32("the bounds grid")?;
        }
        let grid = BoundsGrid {
            space: Aabb::new(
                Vec3::new(corners[0], corners[1], corners[2]),
                Vec3::new(corners[3], corners[4], corners[5]),
            ),
        };
        if !grid.is_valid() {
            return Err(CodecError::Corrupt(format!(
                "the bounds grid {corners:?} is not a box (finite, low <= high)"
            )));
        }
        Some(grid)
    } else {
        None
    };
    let params_len = c.u32("the parameter length")? as usize;
    let params = std::str::from_utf8(c.take(params_len, "the parameters")?)
        .map_err(|_| CodecError::Corrupt("the parameters are not UTF-8".into()))?
        .to_owned();
    // Each object takes at least 6 bytes (18 in version 2): bound the
    // count before allocating the table.
    if objects > c.left() / min_object_len(version) {
        return Err(CodecError::Truncated(format!(
            "{objects} objects cannot fit in the {} bytes left",
            c.left()
        )));
    }
    let words = objects.div_ceil(64);
    let per_node = words * 8 + 64;
    let max_nodes = limits.max_decoded_bytes / per_node.max(1);
    if nodes > max_nodes {
        return Err(CodecError::TooLarge(format!(
            "{nodes} nodes of {objects} objects would take more than {} bytes decoded",
            limits.max_decoded_bytes
        )));
    }
    let mut table = Vec::with_capacity(objects);
    for i in 0..objects {
        let triangles = c.u32("an object's triangle count")?;
        let bounds = match &grid {
            Some(grid) => {
                let mut q = [0u16; 6];
                for k in &mut q {
                    *k = c.u16("an object's bounds")?;
                }
                grid.dequantise(q)
                    .map_err(|e| CodecError::Corrupt(format!("object {i}: {e}")))?
            }
            None => None,
        };
        let len = c.u16("an object's name length")? as usize;
        let name = std::str::from_utf8(c.take(len, "an object's name")?)
            .map_err(|_| CodecError::Corrupt(format!("object {i}'s name is not UTF-8")))?;
        let id = if version >= 5 {
            let len = c.u16("an object's id length")? as usize;
            let id = std::str::from_utf8(c.take(len, "an object's id")?)
                .map_err(|_| CodecError::Corrupt(format!("object {i}'s id is not UTF-8")))?;
            if id.contains('\0') {
                return Err(CodecError::Corrupt(format!("object {i}'s id holds a NUL")));
            }
            if len == 0 { name } else { id }
        } else {
            ""
        };
        let flags = if version >= 6 {
            let bits = c.u8("an object's flags")?;
            ObjectFlags::from_bits(bits).ok_or_else(|| {
                CodecError::Corrupt(format!("object {i} has unknown flags {bits:#04x}"))
            })?
        } else {
            ObjectFlags::NONE
        };
        table.push(FileObject {
            name: name.to_owned(),
            id: id.to_owned(),
            triangles,
            bounds,
            flags,
        });
    }
    if version < 5 {
        let ids = super::default_ids(table.iter().map(|o| o.name.as_str()));
        for (o, id) in table.iter_mut().zip(ids) {
            o.id = id;
        }
    } else {
        let mut seen = std::collections::HashSet::with_capacity(table.len());
        if let Some(o) = table.iter().find(|o| !seen.insert(o.id.as_str())) {
            return Err(CodecError::Corrupt(format!(
                "two objects have the id {:?}",
                o.id
            )));
        }
    }
    let bits = c.u64("the tree's bit length")?;
    let tree_bytes = bits.div_ceil(8);
    // Version 3 has the leaf records' length (4 bytes) and the records
    // after the tree; version 4 the slices' length (4 bytes) and the
    // slices after those.
    let after = match version {
        4.. => 8,
        3 => 4,
        _ => 0,
    };
    if tree_bytes > (c.left() as u64).saturating_sub(after)
        || (version < 3 && tree_bytes != c.left() as u64)
    {
        return Err(CodecError::Corrupt(format!(
            "the tree has {bits} bits but {} bytes follow",
            c.left()
        )));
    }
    let bytes = c.take(tree_bytes as usize, "the tree")?;
    if bits % 8 != 0 && bytes.last().is_some_and(|&b| b >> (bits % 8) != 0) {
        return Err(CodecError::Corrupt(
            "the tree's padding bits are not zero".into(),
        ));
    }
    let tree = decode(
        bytes,
        bits,
        coding,
        root,
        grid_bits,
        objects,
        DecodeLimits { max_nodes: nodes },
    )?;
    if tree.nodes().len() != nodes || tree.leaf_count() != leaves {
        return Err(CodecError::Corrupt(format!(
            "the header says {nodes} nodes, the tree has {}",
            tree.nodes().len()
        )));
    }
    let records = if version >= 3 {
        let len = c.u32("the leaf records' length")? as usize;
        // Version 4: the slices' length (4 bytes) follows them.
        let fits = if version >= 4 {
            len.checked_add(4).is_some_and(|n| n <= c.left())
        } else {
            len == c.left()
        };
        if !fits {
            return Err(CodecError::Corrupt(format!(
                "the leaf records take {len} bytes but {} follow",
                c.left()
            )));
        }
        let bytes = c.take(len, "the leaf records")?;
        (len > 0)
            .then(|| read_leaf_records(bytes, leaves))
            .transpose()?
    } else {
        None
    };
    let slices = if version >= 4 {
        let len = c.u32("the slices' length")? as usize;
        if len != c.left() {
            return Err(CodecError::Corrupt(format!(
                "the slices take {len} bytes but {} follow",
                c.left()
            )));
        }
        let bytes = c.take(len, "the slices")?;
        if len > 0 {
            let counts: Vec<u32> = table.iter().map(|o| o.triangles).collect();
            let leaf_nodes: Vec<usize> = tree.leaves().iter().map(|l| l.node).collect();
            let holds =
                |leaf: usize, object: usize| tree.nodes()[leaf_nodes[leaf]].set.contains(object);
            Some(crate::slices::decode_section(
                bytes, &counts, leaves, &holds,
            )?)
        } else {
            None
        }
    } else {
        None
    };
    let tree = tree
        .with_leaf_records(records)
        .map_err(|_| CodecError::Corrupt("the leaf records do not match the leaves".into()))?;
    Ok(V5dFile {
        coding,
        fingerprint,
        frame,
        params,
        objects: table,
        tree,
        slices,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn long_names_are_cut_at_a_character_boundary() {
        let tree = VisTree::from_parts(
            Cell::all_directions(crate::geom::Aabb::new(Vec3::ZERO, Vec3::ONE)),
            4,
            1,
            vec![crate::tree::Node {
                split: None,
                set: crate::bitset::ObjectSet::full(1),
            }],
        );
        let file = V5dFile {
            coding: Coding::Leaves,
            fingerprint: 1,
            frame: Frame::IDENTITY,
            params: String::new(),
            objects: vec![FileObject {
                name: "é".repeat(40_000),
                id: "é".repeat(40_000),
                triangles: 1,
                bounds: None,
                flags: ObjectFlags::NEVER_OCCLUDER,
            }],
            tree,
            slices: None,
        };
        let back = read_file(&write_file(&file), ReadLimits::default()).unwrap();
        assert_eq!(back.objects[0].name, "é".repeat(32_767));
        assert_eq!(back.objects[0].id, back.objects[0].name);
        assert_eq!(back.objects[0].flags, ObjectFlags::NEVER_OCCLUDER);
    }

    #[test]
    fn an_empty_object_round_trips_without_a_box() {
        use crate::geom::Aabb;
        let mut set = crate::bitset::ObjectSet::new(3);
        set.insert(0);
        set.insert(2);
        let tree = VisTree::from_parts(
            Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::ONE)),
            4,
            3,
            vec![crate::tree::Node { split: None, set }],
        );
        let object = |name: &str, triangles, bounds| FileObject {
            name: name.into(),
            id: name.into(),
            triangles,
            bounds,
            flags: ObjectFlags::NONE,
        };
        let b = Aabb::new(Vec3::ZERO, Vec3::splat(0.5));
        for empty in [None, Some(Aabb::EMPTY)] {
            let file = V5dFile {
                coding: Coding::Leaves,
                fingerprint: 1,
                frame: Frame::IDENTITY,
                params: String::new(),
                objects: vec![
                    object("a", 2, Some(b)),
                    object("none", 0, empty),
                    object("c", 1, Some(Aabb::new(Vec3::splat(0.5), Vec3::ONE))),
                ],
                tree: tree.clone(),
                slices: None,
            };
            let bytes = write_file(&file);
            let back = read_file(&bytes, ReadLimits::default()).unwrap();
            assert_eq!(back.objects[1], object("none", 0, None));
            // The others' boxes, quantised outwards, on a grid of theirs.
            let got = back.objects[0].bounds.unwrap();
            assert!(got.min.cmple(b.min).all() && got.max.cmpge(b.max).all());
            assert_eq!(back.tree, file.tree);
            // Written again: the same bytes.
            assert_eq!(write_file(&back), bytes);
        }
    }

    #[test]
    fn fingerprint_sees_geometry_not_names() {
        let a = [[Vec3::ZERO, Vec3::X, Vec3::Y]];
        let b = [[Vec3::ZERO, Vec3::X, Vec3::Y * 1.000_001]];
        let f =
            |objs: &[&[[Vec3; 3]]]| geometry_fingerprint(objs.iter().copied(), &Frame::IDENTITY);
        assert_eq!(f(&[&a]), f(&[&a]));
        assert_ne!(f(&[&a]), f(&[&b]));
        assert_ne!(f(&[&a, &a]), f(&[&a]));
        assert_ne!(f(&[&a, &[]]), f(&[&a]));
        // The same local triangles elsewhere in the world.
        let far = Frame {
            origin: DVec3::new(1e6, 0.0, 0.0),
            up: Up::Z,
        };
        assert_ne!(geometry_fingerprint([&a[..]], &far), f(&[&a]));
        // The same local triangles built with another up axis.
        let y = Frame {
            origin: DVec3::ZERO,
            up: Up::Y,
        };
        let fy = geometry_fingerprint([&a[..]], &y);
        assert_ne!(fy, f(&[&a]));
        assert_ne!(
            fy,
            geometry_fingerprint([&a[..]], &Frame { up: Up::X, ..y })
        );
    }
}
