//! Writing a [`Scene`] as OBJ: one `o` group per object, vertices shared
//! within an object, coordinates in world units in Rust's shortest
//! round-trip notation (so reading the file back gives the same scene, and
//! the same scene and seed give the same bytes on every machine): the
//! `f32`s themselves for a scene near the origin, the f64 world values
//! ([`crate::geom::Frame::world_text`]) for one far from it.

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
        let frame = scene.frame();
        for v in &verts {
            writeln!(out, "v {}", frame.world_text(*v).replace(',', " "))?;
        }
        for [a, b, c] in &faces {
            writeln!(out, "f {a} {b} {c}")?;
        }
        base += verts.len() as u64;
    }
    out.flush()
}

/// Writes `scene` to the OBJ file `path` atomically
/// ([`crate::atomic_write::write_atomic`]): never a partial file.
pub fn write_obj_file(scene: &Scene, header: &[String], path: &Path) -> io::Result<()> {
    let mut bytes = Vec::new();
    write_obj(scene, header, &mut bytes)?;
    crate::atomic_write::write_atomic(path, &bytes)
}
