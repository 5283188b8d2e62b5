//! Storing trees: the three bitset codings of papers/003 sec. 6 and the
//! `.v5d` file format (specified in `notes/format.md`).
//!
//! Part of the runtime side: no builder dependency.

mod codec_bits;
mod codec_bounds;
mod codec_file;
mod codec_flags;
mod codec_ids;
mod codec_part;
mod codec_tree;

pub use codec_bits::{BitReader, BitWriter};
pub use codec_bounds::{BoundsGrid, UNKNOWN as UNKNOWN_BOUNDS};
pub use codec_file::{
    FileObject, MAGIC, MIN_FILE_LEN, MeshError, ReadLimits, V5dFile, VERSION, crc32,
    fingerprint_meshes, geometry_fingerprint, read_file, write_file,
};
pub(crate) use codec_file::{VarintError, get_varint, put_varint};
pub use codec_flags::{FlagError, ObjectFlags, flags_from_names};
pub use codec_ids::{
    IdError, MAX_ID_BYTES, apply_user_ids, default_ids, first_duplicate, is_valid_id, replace_ids,
};
pub use codec_part::{PART_MAGIC, PART_VERSION, V5dPart, read_part, write_part};
pub use codec_tree::{CodeSize, Coding, DecodeLimits, UnknownCoding, code_size, decode, encode};

/// The parameter key that names how a file's tree was made; a file
/// without it was sampled (`vis5d build`).
pub const METHOD_KEY: &str = "method";

/// [`METHOD_KEY`]'s value for a conservative tree (`vis5d build
/// --conservative`): every set holds every object some ray of its cell can
/// see.
pub const METHOD_CONSERVATIVE: &str = "conservative";

/// Whether the parameter text of a file (`key=value` lines) says its tree
/// is conservative.
pub fn params_say_conservative(params: &str) -> bool {
    params.lines().any(|line| {
        line.split_once('=')
            .is_some_and(|(k, v)| k.trim() == METHOD_KEY && v.trim() == METHOD_CONSERVATIVE)
    })
}

/// Why a `.v5d` file cannot be read. Messages say what is wrong; the
/// caller adds the file's name.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[non_exhaustive]
pub enum CodecError {
    /// The magic bytes are missing: this is some other kind of file.
    #[error("not a .v5d file (it does not start with the .v5d magic bytes)")]
    NotV5d,
    /// Written by another version of the format.
    #[error(
        "unsupported .v5d format version {0}: this vis5d reads versions 1 to {VERSION}; rebuild the file"
    )]
    Version(u16),
    /// The file ends early.
    #[error("truncated: {0}")]
    Truncated(String),
    /// The checksum does not match: the bytes were damaged.
    #[error(
        "checksum mismatch (stored {stored:08x}, computed {computed:08x}): the file is damaged; rebuild or copy it again"
    )]
    Checksum {
        /// The CRC-32 stored in the file.
        stored: u32,
        /// The CRC-32 of its bytes.
        computed: u32,
    },
    /// A field holds an impossible value.
    #[error("corrupt: {0}")]
    Corrupt(String),
    /// Decoding would take more memory than allowed.
    #[error("too large to decode: {0}")]
    TooLarge(String),
}
