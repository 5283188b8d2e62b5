//! Writing a [`Scene`] as OBJ: one `o` group per object, vertices shared
//! within an object, coordinates in Rust's shortest round-trip notation (so
//! reading the file back gives the same `f32`s, and the same scene and seed
//! give the same bytes on every machine).

use std::collections::HashMap;
use std::io::{self, Write};
use std::path::Path;

use super::Scene;

/// Writes `scene` as OBJ text to `out`. `header` lines are written first as
/// `#` comments.
pub fn write_obj(scene: &Scene, header: &[String], out: &mut impl Write) -> io::Result<()> {
    for line in header {
        writeln!(out, "# {line}")?;
    }
    let mut base = 1u64;
    let mut local: HashMap<[u32; 3], u64> = HashMap::new();
    let mut verts = Vec::new();
    let mut faces: Vec<[u64; 3]> = Vec::new();
    for (i, object) in scene.objects().iter().enumerate() {
        let name: String = object
            .name
            .chars()
            .map(|c| if c.is_control() { '_' } else { c })
            .collect();
        writeln!(out, "o {name}")?;
        local.clear();
        verts.clear();
        faces.clear();
        for tri in scene.object_triangles(i) {
            faces.push(tri.map(|v| {
                *local
                    .entry(v.to_array().map(f32::to_bits))
                    .or_insert_with(|| {
                        verts.push(v);
                        base + verts.len() as u64 - 1
                    })
            }));
        }
        for v in &verts {
            writeln!(out, "v {} {} {}", v.x, v.y, v.z)?;
        }
        for [a, b, c] in &faces {
            writeln!(out, "f {a} {b} {c}")?;
        }
        base += verts.len() as u64;
    }
    out.flush()
}

/// Writes `scene` to the OBJ file `path` atomically: into a temporary file
/// beside it, renamed over `path` only when complete, so an interrupted
/// write never leaves a partial file.
pub fn write_obj_file(scene: &Scene, header: &[String], path: &Path) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "the path names no file"))?;
    let tmp = dir.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| {
        let mut w = io::BufWriter::new(std::fs::File::create(&tmp)?);
        write_obj(scene, header, &mut w)?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}
