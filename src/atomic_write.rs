//! Writing files so that each is either complete or absent: the bytes go to
//! a hidden temporary file in the same folder (`.NAME.tmpPID`), which is
//! synced and then renamed over the target (a rename within a folder is
//! atomic), and the folder is synced so that the rename survives a crash.
//! A failed write removes its temporary file; one left by a killed process
//! is removed by the next write of the same name.
//!
//! Writes are refused where they would destroy something other than an
//! earlier output: a target that exists but is not a regular file (a
//! device node, a FIFO, a folder), and, with [`same_file`], a target that
//! is one of the command's inputs under another spelling.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Writes `bytes` to `path` atomically (module docs).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_all(&[(path, bytes)])
}

/// Writes several files, each atomically: every temporary file is written
/// and synced before the first rename, so a failure while writing leaves
/// every target as it was (a crash between two renames can still leave
/// some targets new and some old).
pub fn write_atomic_all(files: &[(&Path, &[u8])]) -> io::Result<()> {
    let mut temps: Vec<(PathBuf, &Path)> = Vec::with_capacity(files.len());
    let result = (|| {
        for &(path, bytes) in files {
            let tmp = prepare(path)?;
            temps.push((tmp.clone(), path));
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()?;
        }
        for (tmp, path) in &temps {
            std::fs::rename(tmp, path)?;
            sync_folder(path);
        }
        Ok(())
    })();
    if result.is_err() {
        for (tmp, _) in &temps {
            let _ = std::fs::remove_file(tmp);
        }
    }
    result
}

/// Whether `a` and `b` name the same existing file (through links,
/// `..`, or another spelling); false when either does not exist.
pub fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        match (a.canonicalize(), b.canonicalize()) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        }
    }
}

/// Checks that `path` may be replaced (absent, or a regular file) and
/// names a file; removes a temporary file of its name left by a process
/// that no longer runs; returns this process's temporary path.
fn prepare(path: &Path) -> io::Result<PathBuf> {
    if let Ok(m) = std::fs::metadata(path)
        && !m.is_file()
    {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "it exists and is not a regular file (a folder, a device or a FIFO): \
             refusing to replace it",
        ));
    }
    let dir = folder(path);
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "the path names no file"))?
        .to_string_lossy()
        .into_owned();
    let prefix = format!(".{name}.tmp");
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let file = e.file_name();
            let Some(pid) = file.to_str().and_then(|f| f.strip_prefix(&prefix)) else {
                continue;
            };
            if pid.parse::<u32>().is_ok_and(|p| !process_runs(p)) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
    Ok(dir.join(format!("{prefix}{}", std::process::id())))
}

/// The folder holding `path`.
fn folder(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Whether process `pid` runs (on Linux, from /proc; elsewhere assumed,
/// so that no live writer's file is ever removed).
fn process_runs(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    if cfg!(target_os = "linux") {
        Path::new("/proc").join(pid.to_string()).exists()
    } else {
        true
    }
}

/// Syncs the folder of `path` so that a rename into it is durable (best
/// effort: not every platform can open a folder).
fn sync_folder(path: &Path) {
    #[cfg(unix)]
    if let Ok(d) = std::fs::File::open(folder(path)) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = path;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vis5d-atomic-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn writes_whole_files_and_leaves_nothing_on_failure() {
        let dir = scratch("whole");
        let p = dir.join("out.bin");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        // A folder that does not exist: an error, and nothing written.
        assert!(write_atomic(&dir.join("no/such/out.bin"), b"x").is_err());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        // Several files; one bad target: none is written.
        let (a, b) = (dir.join("a"), dir.join("sub"));
        std::fs::create_dir(&b).unwrap();
        assert!(write_atomic_all(&[(&a, b"a"), (&b, b"b")]).is_err());
        assert!(!a.exists() && b.is_dir());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// `-o` onto a device node used to replace the node with a plain file.
    #[test]
    #[cfg(unix)]
    fn special_files_are_not_replaced() {
        let e = write_atomic(Path::new("/dev/null"), b"x").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        assert!(e.to_string().contains("not a regular file"), "{e}");
    }

    /// A killed write left `.NAME.tmpPID` behind for ever.
    #[test]
    fn stale_temporary_files_are_removed() {
        let dir = scratch("stale");
        let p = dir.join("out.bin");
        // No process has pid 4294967295 (above every pid_max).
        let stale = dir.join(".out.bin.tmp4294967295");
        std::fs::write(&stale, b"half").unwrap();
        write_atomic(&p, b"whole").unwrap();
        assert!(!stale.exists() || !cfg!(target_os = "linux"));
        assert_eq!(std::fs::read(&p).unwrap(), b"whole");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn same_file_sees_through_other_spellings() {
        let dir = scratch("same");
        let p = dir.join("model.obj");
        std::fs::write(&p, b"o x").unwrap();
        std::fs::create_dir(dir.join("x")).unwrap();
        assert!(same_file(&p, &dir.join("x/../model.obj")));
        assert!(same_file(&p, &p));
        assert!(!same_file(&p, &dir.join("other.obj")));
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(&p, dir.join("link.obj")).unwrap();
            assert!(same_file(&p, &dir.join("link.obj")));
            std::fs::hard_link(&p, dir.join("hard.obj")).unwrap();
            assert!(same_file(&p, &dir.join("hard.obj")));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
