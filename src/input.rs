//! Reading input files the way a careful tool must: only regular files
//! (a FIFO would block, a device such as `/dev/zero` would fill memory, a
//! folder is a mistake), and never more than a stated number of bytes.
//!
//! The file's kind is checked before it is opened (opening a FIFO blocks
//! until a writer comes), and the read stops one byte past the limit, so
//! that a file growing while it is read cannot exceed it either.

use std::io::{self, Read};
use std::path::Path;

/// Reads the regular file `path` whole, refusing anything else and any
/// file above `limit` bytes (with an error saying which).
pub fn read_regular(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let meta = regular(path)?;
    if meta.len() > limit {
        return Err(too_large(meta.len(), limit));
    }
    let file = std::fs::File::open(path)?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64, limit));
    }
    Ok(bytes)
}

/// Reads exactly the first `len` bytes of the regular file `path` (a
/// glTF buffer of `byteLength` bytes): the rest of the file, however
/// large, is not read; a shorter file is an error.
pub fn read_regular_prefix(path: &Path, len: u64) -> io::Result<Vec<u8>> {
    let meta = regular(path)?;
    if meta.len() < len {
        return Err(too_short(meta.len(), len));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    std::fs::File::open(path)?
        .take(len)
        .read_to_end(&mut bytes)?;
    if (bytes.len() as u64) < len {
        return Err(too_short(bytes.len() as u64, len));
    }
    Ok(bytes)
}

/// The metadata of `path` (links followed), when it is a regular file.
fn regular(path: &Path) -> io::Result<std::fs::Metadata> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file (a folder, a device or a FIFO): vis5d reads only regular files",
        ));
    }
    Ok(meta)
}

fn too_short(len: u64, declared: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::UnexpectedEof,
        format!("it holds {len} bytes, fewer than the {declared} declared"),
    )
}

fn too_large(len: u64, limit: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!("it is {len} bytes, above the limit of {limit} bytes"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_files_only_and_within_limits() {
        let dir = std::env::temp_dir().join(format!("vis5d-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("f.bin");
        std::fs::write(&p, b"0123456789").unwrap();
        assert_eq!(read_regular(&p, 10).unwrap(), b"0123456789");
        assert!(
            read_regular(&p, 9)
                .unwrap_err()
                .to_string()
                .contains("above the limit")
        );
        assert_eq!(read_regular_prefix(&p, 4).unwrap(), b"0123");
        assert!(read_regular_prefix(&p, 11).is_err());
        assert!(
            read_regular(&dir, 100)
                .unwrap_err()
                .to_string()
                .contains("regular")
        );
        #[cfg(unix)]
        {
            // A device would fill memory, read whole.
            let e = read_regular(Path::new("/dev/zero"), u64::MAX).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
            assert!(read_regular_prefix(Path::new("/dev/zero"), 4).is_err());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
