//! A shard's part of a build (`vis5d build --shard I/N`, read by `vis5d
//! merge`; notes/format.md, "Parts"): which shard of how many it is, the
//! fixed levels, the coding the build asked for, and each subtree it
//! built as a whole `.v5d` file of its own (the tree rooted at the
//! subtree's cell, with the build's fingerprint, frame, parameters and
//! objects), so that a part is checked as thoroughly as a `.v5d` is.
//!
//! Layout (little-endian): the magic `PART_MAGIC` (8 bytes); the version
//! (u32, [`PART_VERSION`]); the fixed levels, the shard and the shards
//! (u32 each); the coding asked for (u32: 0 the smallest, 1 leaves, 2
//! parent, 3 sibling); the number of subtrees (u32); per subtree its index
//! (u32), its file's length (u64) and the file; then the CRC-32 of every
//! byte before it (u32).

use super::{CodecError, Coding, ReadLimits, V5dFile, crc32, read_file, write_file};

/// The first bytes of a part.
pub const PART_MAGIC: [u8; 8] = *b"V5DPART\n";

/// The part format's version.
pub const PART_VERSION: u32 = 1;

/// What a shard built.
#[derive(Clone, Debug, PartialEq)]
pub struct V5dPart {
    /// The fixed levels of the build's top (2^k subtrees in all).
    pub top_levels: u32,
    /// Which shard this is (from 0).
    pub shard: u32,
    /// How many shards the build was dealt to.
    pub shards: u32,
    /// The coding the build asked for; `None`: the smallest for the whole
    /// tree, chosen when the parts are merged.
    pub coding: Option<Coding>,
    /// The subtrees it built: (index in the top's order, its file).
    pub subtrees: Vec<(u32, V5dFile)>,
}

fn coding_code(c: Option<Coding>) -> u32 {
    match c {
        None => 0,
        Some(Coding::Leaves) => 1,
        Some(Coding::Parent) => 2,
        Some(Coding::Sibling) => 3,
    }
}

/// The bytes of `part`.
pub fn write_part(part: &V5dPart) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&PART_MAGIC);
    for v in [
        PART_VERSION,
        part.top_levels,
        part.shard,
        part.shards,
        coding_code(part.coding),
        part.subtrees.len() as u32,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for (index, file) in &part.subtrees {
        let bytes = write_file(file);
        out.extend_from_slice(&index.to_le_bytes());
        out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        out.extend_from_slice(&bytes);
    }
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Reads a part written by [`write_part`], checking its magic, version,
/// checksum and every subtree's file (with `limits` each).
///
/// # Errors
/// [`CodecError::NotV5d`] for other files; the other variants as for a
/// `.v5d` (a subtree's error says which subtree).
pub fn read_part(bytes: &[u8], limits: ReadLimits) -> Result<V5dPart, CodecError> {
    if bytes.len() < PART_MAGIC.len() || bytes[..PART_MAGIC.len()] != PART_MAGIC {
        return Err(CodecError::NotV5d);
    }
    let head = PART_MAGIC.len() + 6 * 4;
    if bytes.len() < head + 4 {
        return Err(CodecError::Truncated(format!(
            "a part has at least {} bytes, this one {}",
            head + 4,
            bytes.len()
        )));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes(tail.try_into().expect("4 bytes"));
    let computed = crc32(body);
    if stored != computed {
        return Err(CodecError::Checksum { stored, computed });
    }
    let u32_at = |at: usize| u32::from_le_bytes(body[at..at + 4].try_into().expect("4 bytes"));
    let version = u32_at(8);
    if version != PART_VERSION {
        return Err(CodecError::Corrupt(format!(
            "part format version {version}; this vis5d reads version {PART_VERSION}"
        )));
    }
    let (top_levels, shard, shards, coding, count) =
        (u32_at(12), u32_at(16), u32_at(20), u32_at(24), u32_at(28));
    let coding = match coding {
        0 => None,
        1 => Some(Coding::Leaves),
        2 => Some(Coding::Parent),
        3 => Some(Coding::Sibling),
        c => return Err(CodecError::Corrupt(format!("coding {c} is none of 0-3"))),
    };
    if top_levels > 10 || shards == 0 || shard >= shards || u64::from(count) > 1 << top_levels {
        return Err(CodecError::Corrupt(format!(
            "shard {shard} of {shards} with {count} of the 2^{top_levels} subtrees"
        )));
    }
    let mut subtrees = Vec::with_capacity(count as usize);
    let mut at = head;
    for k in 0..count {
        if body.len() < at + 12 {
            return Err(CodecError::Truncated(format!("subtree {k} of {count}")));
        }
        let index = u32_at(at);
        let len = u64::from_le_bytes(body[at + 4..at + 12].try_into().expect("8 bytes"));
        at += 12;
        if ((body.len() - at) as u64) < len {
            return Err(CodecError::Truncated(format!(
                "subtree {index}'s file of {len} bytes"
            )));
        }
        let file = &body[at..at + len as usize];
        at += len as usize;
        let file = read_file(file, limits).map_err(|e| match e {
            CodecError::Corrupt(m) => CodecError::Corrupt(format!("subtree {index}: {m}")),
            CodecError::Truncated(m) => CodecError::Truncated(format!("subtree {index}: {m}")),
            CodecError::TooLarge(m) => CodecError::TooLarge(format!("subtree {index}: {m}")),
            other => CodecError::Corrupt(format!("subtree {index}: {other}")),
        })?;
        subtrees.push((index, file));
    }
    if at != body.len() {
        return Err(CodecError::Corrupt(format!(
            "{} bytes after the last subtree",
            body.len() - at
        )));
    }
    Ok(V5dPart {
        top_levels,
        shard,
        shards,
        coding,
        subtrees,
    })
}
