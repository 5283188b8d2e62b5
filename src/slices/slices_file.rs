//! The slices of a tree as a `.v5d` file stores them (version 4, the
//! section after the leaf records; `notes/format.md`, "Slices"): the
//! scene's pieces and slices, then per leaf the hidden slices of its
//! objects.

use glam::DVec3;

use super::{MAX_STORED_SLICES, ObjectSlices, SliceIndex, SlicedScene, TreeSlices};
use crate::codec::{CodecError, VarintError, get_varint, put_varint};

/// Writes the section's bytes (without its length). `slices` must satisfy
/// what [`decode`] checks: at most [`MAX_STORED_SLICES`] slices an axis,
/// every index within its piece's slices, objects increasing in a leaf.
pub(crate) fn encode(slices: &TreeSlices) -> Vec<u8> {
    let s = &slices.sliced;
    debug_assert!(
        s.slices <= MAX_STORED_SLICES,
        "{} slices cannot be stored",
        s.slices
    );
    let mut out = vec![s.slices as u8];
    for (o, pieces) in s.objects.iter().enumerate() {
        put_varint(&mut out, pieces.len() as u32);
        for p in pieces {
            for v in p.min.to_array().iter().chain(&p.max.to_array()) {
                out.extend_from_slice(&(*v as f32).to_le_bytes());
            }
            out.extend(p.counts.map(|c| c as u8));
        }
        let triangles: usize = pieces.iter().map(|p| p.lo.len()).sum();
        for t in 0..triangles {
            let (p, k) = s.place(o, t);
            if pieces.len() > 1 {
                put_varint(&mut out, p as u32);
            }
            out.extend_from_slice(&pieces[p].lo[k]);
            out.extend_from_slice(&pieces[p].hi[k]);
        }
    }
    for leaf in &slices.leaves {
        put_varint(&mut out, leaf.len() as u32);
        let mut next = 0u32;
        for (object, indices) in leaf {
            put_varint(&mut out, object - next);
            next = object + 1;
            for i in indices {
                out.extend_from_slice(&[i.x as i8 as u8, i.y as i8 as u8, i.z]);
            }
        }
    }
    out
}

/// A checked reader over the section's bytes.
struct Bytes<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Bytes<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], CodecError> {
        let out = self
            .bytes
            .get(self.pos..self.pos.saturating_add(n))
            .ok_or_else(|| {
                CodecError::Corrupt(format!("the slices end in the middle of {what}"))
            })?;
        self.pos += n;
        Ok(out)
    }

    fn u8(&mut self, what: &str) -> Result<u8, CodecError> {
        Ok(self.take(1, what)?[0])
    }

    fn varint(&mut self, what: &str) -> Result<u32, CodecError> {
        get_varint(self.bytes, &mut self.pos).map_err(|e| {
            CodecError::Corrupt(match e {
                VarintError::End => format!("the slices end in the middle of {what}"),
                VarintError::TooBig => format!("the slices' {what} is over 32 bits"),
                VarintError::TooLong => format!("the slices' {what} is over 5 bytes"),
            })
        })
    }

    fn left(&self) -> usize {
        self.bytes.len() - self.pos
    }
}

/// Reads the section: `triangles` is each object's triangle count (the
/// object table's), `leaf_sets` says whether a leaf (in preorder) holds an
/// object. Every field is checked; nothing is allocated beyond what the
/// bytes can hold.
pub(crate) fn decode(
    bytes: &[u8],
    triangles: &[u32],
    leaves: usize,
    leaf_holds: &dyn Fn(usize, usize) -> bool,
) -> Result<TreeSlices, CodecError> {
    let corrupt = |m: String| CodecError::Corrupt(m);
    let mut b = Bytes { bytes, pos: 0 };
    let n = usize::from(b.u8("the slice count")?);
    if !(1..=MAX_STORED_SLICES).contains(&n) {
        return Err(corrupt(format!(
            "{n} slices an axis (1 to {MAX_STORED_SLICES} can be stored)"
        )));
    }
    // Every triangle takes 6 bytes: bound the total before allocating.
    let total: u64 = triangles.iter().map(|&t| u64::from(t)).sum();
    if total.saturating_mul(6) > b.left() as u64 {
        return Err(corrupt(format!(
            "{total} triangles' slices cannot fit in {} bytes",
            b.left()
        )));
    }
    let mut objects = Vec::with_capacity(triangles.len());
    let mut place = Vec::with_capacity(triangles.len());
    for (o, &count) in triangles.iter().enumerate() {
        let count = count as usize;
        let pieces = b.varint("piece count")? as usize;
        if pieces == 0 || pieces > count.max(1) || pieces.saturating_mul(27) > b.left() {
            return Err(corrupt(format!(
                "object {o} has {pieces} pieces for {count} triangles"
            )));
        }
        let mut shells = Vec::with_capacity(pieces);
        for p in 0..pieces {
            let mut v = [0.0f64; 6];
            for x in &mut v {
                let raw = b.take(4, "a piece's box")?;
                *x = f64::from(f32::from_le_bytes(raw.try_into().expect("4 bytes")));
            }
            let (min, max) = (DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
            if !(min.is_finite() && max.is_finite() && min.cmple(max).all()) {
                return Err(corrupt(format!("object {o}'s piece {p} has no box")));
            }
            let mut counts = [0usize; 3];
            for c in &mut counts {
                *c = usize::from(b.u8("a piece's slice counts")?);
                if !(1..=n).contains(c) {
                    return Err(corrupt(format!(
                        "object {o}'s piece {p} has {c} slices along an axis (1 to {n})"
                    )));
                }
            }
            shells.push(ObjectSlices {
                min,
                max,
                counts,
                triangles: Vec::new(),
                lo: Vec::new(),
                hi: Vec::new(),
            });
        }
        let mut where_ = Vec::with_capacity(if pieces > 1 { count } else { 0 });
        for t in 0..count {
            let p = if pieces > 1 {
                b.varint("triangle's piece")? as usize
            } else {
                0
            };
            let shell = shells.get_mut(p).ok_or_else(|| {
                corrupt(format!(
                    "object {o}'s triangle {t} is in piece {p} of {pieces}"
                ))
            })?;
            let raw = b.take(6, "a triangle's slices")?;
            let (lo, hi) = ([raw[0], raw[1], raw[2]], [raw[3], raw[4], raw[5]]);
            if (0..3).any(|k| lo[k] > hi[k] || usize::from(hi[k]) >= shell.counts[k]) {
                return Err(corrupt(format!(
                    "object {o}'s triangle {t} has slices {lo:?}..={hi:?} of {:?}",
                    shell.counts
                )));
            }
            if pieces > 1 {
                where_.push((p as u32, shell.lo.len() as u32));
            }
            shell.triangles.push(t as u32);
            shell.lo.push(lo);
            shell.hi.push(hi);
        }
        if count > 0 && shells.iter().any(|s| s.lo.is_empty()) {
            return Err(corrupt(format!("object {o} has a piece of no triangles")));
        }
        objects.push(shells);
        place.push(where_);
    }
    let sliced = SlicedScene {
        slices: n,
        objects,
        place,
    };
    // Per leaf: at least one byte (its entry count) each.
    if leaves > b.left() {
        return Err(corrupt(format!(
            "{leaves} leaves' slices cannot fit in {} bytes",
            b.left()
        )));
    }
    let mut out = Vec::with_capacity(leaves);
    for leaf in 0..leaves {
        let entries = b.varint("leaf's entry count")? as usize;
        if entries > b.left() / 4 || entries > triangles.len() {
            return Err(corrupt(format!(
                "leaf {leaf} has {entries} objects with slices"
            )));
        }
        let mut row = Vec::with_capacity(entries);
        let mut next = 0u64;
        for _ in 0..entries {
            let object = next + u64::from(b.varint("object gap")?);
            let o = usize::try_from(object).unwrap_or(usize::MAX);
            if o >= triangles.len() || !leaf_holds(leaf, o) {
                return Err(corrupt(format!(
                    "leaf {leaf} has slices for object {object}, which it does not hold"
                )));
            }
            next = object + 1;
            let pieces = sliced.pieces(o);
            let mut indices = Vec::with_capacity(pieces.len());
            for (p, piece) in pieces.iter().enumerate() {
                let raw = b.take(3, "a slice index")?;
                let index = SliceIndex {
                    x: i16::from(raw[0] as i8),
                    y: i16::from(raw[1] as i8),
                    z: raw[2],
                };
                let fits = |k: i16, c: usize| usize::from(k.unsigned_abs()) <= c;
                if !(fits(index.x, piece.counts[0])
                    && fits(index.y, piece.counts[1])
                    && usize::from(index.z) <= piece.counts[2])
                {
                    return Err(corrupt(format!(
                        "leaf {leaf}'s index {index:?} for object {o}'s piece {p} is past its {:?} slices",
                        piece.counts
                    )));
                }
                indices.push(index);
            }
            row.push((o as u32, indices));
        }
        out.push(row);
    }
    if b.left() != 0 {
        return Err(corrupt(format!(
            "{} bytes are left over after the slices",
            b.left()
        )));
    }
    Ok(TreeSlices {
        sliced,
        leaves: out,
    })
}
