//! glTF 2.0 loading (`.gltf` with embedded or side-by-side buffers, `.glb`),
//! with the `gltf` crate doing the JSON and GLB parsing.
//!
//! Object rule (issue #2): one object per node that has a mesh and is part
//! of the scene (the default scene, else the first; every root node when the
//! file has no scene), in node index order, with the node's world transform
//! applied. Named by the node name, else the mesh name, else `node<i>`.
//! Triangle lists, strips and fans are read; points and lines are skipped
//! and counted. A node whose mesh gives no triangle of non-zero area
//! (points or lines only) is an empty object, listed in its place (issue
//! 15: "empty groups are listed, not dropped").
//!
//! Ids and flags (issue 15): an object's node may say what vis5d should
//! call it and what it is to visibility, in its `extras`:
//! `"extras": {"vis5d": {"id": "door-17", "flags": ["never_occluder"]}}`.
//! Both keys are optional, other keys of `extras` are ignored, and only
//! the nodes that make objects are read (a parent's `vis5d` is not
//! inherited). The id replaces the object's default id in the `.v5d`
//! ([`super::Object::id`], [`Scene::ids`]; `vis5d build --ids` may still
//! replace it); the flags (`always_visible`, `never_occluder`:
//! [`super::ObjectFlags::NAMES`]) are the object's when loaded
//! (`vis5d build --flags` adds more). A `vis5d` value that is not such an
//! object, a key other than those two, a flag vis5d does not know, an id
//! that is empty, longer than [`crate::codec::MAX_ID_BYTES`] bytes or
//! holds a NUL, and two objects with one id are errors naming the file
//! and the node.
//!
//! The `gltf` crate's accessor reader assumes well-formed input (it
//! debug-asserts element sizes and computes ranges without overflow
//! checks), so every accessor is checked here first: type, count, stride and
//! byte range. Sparse accessors and accessors without a buffer view are
//! refused with a message saying so.

use std::path::Path;

use base64::Engine;
use glam::{DMat4, DVec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::{LoadOptions, ObjectFlags, Scene, SceneBuilder, SceneError, SceneFormat};

/// Parses glTF or GLB `bytes` read from `path`; side-by-side buffers are
/// read relative to `path`'s folder.
pub(super) fn load_gltf(
    path: &Path,
    bytes: &[u8],
    format: SceneFormat,
    options: &LoadOptions,
) -> Result<Scene, SceneError> {
    let err = |message: String| SceneError::Syntax {
        path: path.to_owned(),
        line: 0,
        message,
    };
    let gltf = parse(bytes).map_err(|e| err(format!("cannot parse the glTF: {e}")))?;
    let buffers = load_buffers(path, &gltf, options)?;
    let doc = &gltf.document;

    // World transforms of the nodes that are part of the scene, composed
    // in f64: georeferenced models put their large offset in a node's
    // translation, and its precision must survive until the scene's frame
    // is chosen.
    let n = doc.nodes().len();
    let mut world: Vec<Option<DMat4>> = vec![None; n];
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; n];
            for node in doc.nodes() {
                for c in node.children() {
                    is_child[c.index()] = true;
                }
            }
            doc.nodes().filter(|nd| !is_child[nd.index()]).collect()
        }
    };
    let precise = node_matrices_f64(bytes, n);
    let mut stack: Vec<(gltf::Node, DMat4)> =
        roots.into_iter().map(|r| (r, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        if world[node.index()].is_some() {
            return Err(err(format!(
                "node {} is reached twice in the node hierarchy (a cycle or a shared child)",
                node.index()
            )));
        }
        let local = match &precise {
            Some(matrices) => matrices[node.index()],
            None => {
                DMat4::from_cols_array_2d(&node.transform().matrix().map(|col| col.map(f64::from)))
            }
        };
        let m = parent * local;
        world[node.index()] = Some(m);
        stack.extend(node.children().map(|c| (c, m)));
    }

    let mut builder = SceneBuilder::new(format);
    let mut positions: Vec<DVec3> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    for node in doc.nodes() {
        let (Some(mesh), Some(m)) = (node.mesh(), world[node.index()]) else {
            continue;
        };
        let name = node
            .name()
            .or(mesh.name())
            .map_or_else(|| format!("node{}", node.index()), str::to_owned);
        let (id, flags) = node_extras(path, &node, &name)?;
        builder.begin_object_with(name.clone(), id, flags);
        builder.label_object(format!("node {} {name:?}", node.index()));
        for prim in mesh.primitives() {
            let mode = prim.mode();
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                builder.skip_non_triangle();
                continue;
            }
            let what = format!("mesh {} primitive {}", mesh.index(), prim.index());
            let pos = prim
                .get(&gltf::Semantic::Positions)
                .ok_or_else(|| err(format!("{what} has no POSITION attribute")))?;
            check_accessor(&pos, &[DataType::F32], Dimensions::Vec3, &buffers)
                .map_err(|m| err(format!("{what} POSITION: {m}")))?;
            if let Some(ix) = prim.indices() {
                check_accessor(
                    &ix,
                    &[DataType::U8, DataType::U16, DataType::U32],
                    Dimensions::Scalar,
                    &buffers,
                )
                .map_err(|m| err(format!("{what} indices: {m}")))?;
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            positions.clear();
            positions.extend(
                reader
                    .read_positions()
                    .ok_or_else(|| err(format!("{what} POSITION cannot be read")))?
                    .map(|p| m.transform_point3(DVec3::from_array(p.map(f64::from)))),
            );
            indices.clear();
            match reader.read_indices() {
                Some(ix) => indices.extend(ix.into_u32()),
                None => indices.extend(0..positions.len() as u32),
            }
            if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(SceneError::IndexOutOfRange {
                    path: path.to_owned(),
                    line: 0,
                    message: format!(
                        "{what} has index {bad} but only {} vertices",
                        positions.len()
                    ),
                });
            }
            for [a, b, c] in assemble(mode, &indices) {
                let t = [
                    positions[a as usize],
                    positions[b as usize],
                    positions[c as usize],
                ];
                builder
                    .push_triangle_f64(t)
                    .map_err(|bad| SceneError::NonFinite {
                        path: path.to_owned(),
                        line: 0,
                        object: name.clone(),
                        value: bad.0.to_string(),
                    })?;
            }
        }
    }
    // The buffers are no longer needed: free them before the builder
    // makes the scene's own triangles.
    drop(buffers);
    builder.finish(path)
}

/// The id and flags a node's `extras.vis5d` gives (module docs); `name`
/// is the object's, for messages.
fn node_extras(
    path: &Path,
    node: &gltf::Node,
    name: &str,
) -> Result<(Option<String>, ObjectFlags), SceneError> {
    let at = format!("node {} {name:?}: extras.vis5d", node.index());
    let syntax = |message: String| SceneError::Syntax {
        path: path.to_owned(),
        line: 0,
        message,
    };
    let Some(raw) = node.extras() else {
        return Ok((None, ObjectFlags::NONE));
    };
    let extras: serde_json::Value = serde_json::from_str(raw.get()).map_err(|e| {
        syntax(format!(
            "node {}: cannot read its extras: {e}",
            node.index()
        ))
    })?;
    let Some(ours) = extras.get("vis5d") else {
        return Ok((None, ObjectFlags::NONE));
    };
    let shape =
        "{\"id\": \"...\", \"flags\": [\"always_visible\", \"never_occluder\"]}, both optional";
    let ours = ours
        .as_object()
        .ok_or_else(|| syntax(format!("{at} must be an object {shape}, not {ours}")))?;
    if let Some(key) = ours.keys().find(|k| !matches!(k.as_str(), "id" | "flags")) {
        return Err(syntax(format!(
            "{at} has the key {key:?}: it may hold only {shape}"
        )));
    }
    let id = match ours.get("id") {
        None => None,
        Some(serde_json::Value::String(id)) if crate::codec::is_valid_id(id) => Some(id.clone()),
        Some(serde_json::Value::String(id)) => {
            return Err(SceneError::Id {
                path: path.to_owned(),
                message: format!(
                    "{at}.id {id:?} is empty, longer than {} bytes or holds a NUL byte",
                    crate::codec::MAX_ID_BYTES
                ),
            });
        }
        Some(other) => return Err(syntax(format!("{at}.id must be a string, not {other}"))),
    };
    let mut flags = ObjectFlags::NONE;
    if let Some(list) = ours.get("flags") {
        let list = list.as_array().ok_or_else(|| {
            syntax(format!(
                "{at}.flags must be a list of flag names, not {list}"
            ))
        })?;
        for f in list {
            let flag = f.as_str().and_then(ObjectFlags::from_name).ok_or_else(|| {
                syntax(format!(
                    "{at}.flags: unknown flag {f} (the flags are always_visible and never_occluder)"
                ))
            })?;
            flags = flags.union(flag);
        }
    }
    Ok((id, flags))
}

/// The triangles of a list, strip or fan (strip winding alternation is
/// irrelevant here: visibility does not cull back faces).
fn assemble(mode: Mode, ix: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::Triangles => ix.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        Mode::TriangleStrip => ix.windows(3).map(|t| [t[0], t[1], t[2]]).collect(),
        Mode::TriangleFan => ix.windows(2).skip(1).map(|t| [ix[0], t[0], t[1]]).collect(),
        _ => Vec::new(),
    }
}

/// Checks that the reader can read `acc` safely: an expected type, a
/// buffer view, no sparse storage, and a byte range inside the buffer.
fn check_accessor(
    acc: &gltf::Accessor,
    types: &[DataType],
    dims: Dimensions,
    buffers: &[Vec<u8>],
) -> Result<(), String> {
    let i = acc.index();
    if acc.dimensions() != dims || !types.contains(&acc.data_type()) || acc.normalized() {
        return Err(format!(
            "accessor {i} is {:?} {:?}{}, expected {dims:?} of {types:?}",
            acc.dimensions(),
            acc.data_type(),
            if acc.normalized() { " normalized" } else { "" }
        ));
    }
    if acc.sparse().is_some() {
        return Err(format!("accessor {i} is sparse, which vis5d does not read"));
    }
    let view = acc.view().ok_or_else(|| {
        format!("accessor {i} has no bufferView (zero-filled accessors are not read)")
    })?;
    let size = acc.size();
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return Err(format!(
            "accessor {i} has stride {stride} below its element size {size}"
        ));
    }
    let count = acc.count();
    if count == 0 {
        return Err(format!("accessor {i} has count 0"));
    }
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(size))
        .and_then(|x| x.checked_add(acc.offset()));
    if end.is_none_or(|e| e > view.length()) {
        return Err(format!("accessor {i} runs past the end of its bufferView"));
    }
    let data = buffers.get(view.buffer().index()).map_or(0, Vec::len);
    if view
        .offset()
        .checked_add(view.length())
        .is_none_or(|e| e > data)
    {
        return Err(format!(
            "bufferView {} runs past the end of buffer {} ({data} bytes)",
            view.index(),
            view.buffer().index()
        ));
    }
    Ok(())
}

/// The bytes of every buffer: the GLB binary chunk, a base64 `data:` URI,
/// or a file in the glTF's folder (read only as far as its `byteLength`;
/// outside the folder only with `options.allow_outside_paths`).
fn load_buffers(
    path: &Path,
    gltf: &gltf::Gltf,
    options: &LoadOptions,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let err = |message: String| SceneError::Syntax {
        path: path.to_owned(),
        line: 0,
        message,
    };
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                err(format!(
                    "buffer {i} refers to a GLB binary chunk that is missing"
                ))
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let (_, payload) = uri
                    .split_once(";base64,")
                    .ok_or_else(|| err(format!("buffer {i} has a data URI that is not base64")))?;
                base64::engine::general_purpose::STANDARD
                    .decode(payload)
                    .map_err(|e| err(format!("buffer {i} has invalid base64 data: {e}")))?
            }
            gltf::buffer::Source::Uri(uri) => {
                let folder = path.parent().unwrap_or(Path::new(""));
                let file = folder.join(percent_decode(uri));
                let outside = || SceneError::OutsidePath {
                    path: path.to_owned(),
                    buffer: i,
                    uri: uri.to_owned(),
                };
                if has_scheme(uri) {
                    // `file:`, `http:`: not a relative path in any case.
                    return Err(outside());
                }
                let cannot = |e: std::io::Error| {
                    err(format!(
                        "buffer {i} file {} cannot be read: {e}",
                        file.display()
                    ))
                };
                if !options.allow_outside_paths {
                    // Through links and `..` alike: where the file really is.
                    let real = file.canonicalize().map_err(cannot)?;
                    let home = if folder.as_os_str().is_empty() {
                        Path::new(".").canonicalize()
                    } else {
                        folder.canonicalize()
                    }
                    .map_err(cannot)?;
                    if !real.starts_with(&home) {
                        return Err(outside());
                    }
                }
                crate::input::read_regular_prefix(&file, buffer.length() as u64).map_err(cannot)?
            }
        };
        if data.len() < buffer.length() {
            return Err(err(format!(
                "buffer {i} holds {} bytes but declares byteLength {}",
                data.len(),
                buffer.length()
            )));
        }
        out.push(data);
    }
    Ok(out)
}

/// Parses and validates a glTF or GLB document. gltf's own validation
/// (`Gltf::from_slice`) indexes the accessor a primitive's `POSITION`
/// names without a bounds check and panics on a missing one (gltf-json
/// 1.4.1, `mesh.rs`): that reference is checked first, then the document
/// is validated with gltf-json's checks.
/// The local matrix of every node, read from the JSON in f64: gltf-json
/// parses `translation`, `rotation`, `scale` and `matrix` as f32, which
/// rounds a georeferenced translation (4,649,876.3 becomes 4,649,876.5).
/// `None` when the JSON cannot be read this way (then the f32 values
/// serve; the document has been validated by the time this matters).
fn node_matrices_f64(bytes: &[u8], nodes: usize) -> Option<Vec<DMat4>> {
    let json = if bytes.starts_with(b"glTF") {
        // GLB: a 12-byte header, then the JSON chunk (length, type, data).
        let len = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
        if bytes.get(16..20)? != b"JSON" {
            return None;
        }
        bytes.get(20..20usize.checked_add(len)?)?
    } else {
        bytes
    };
    let doc: serde_json::Value = serde_json::from_slice(json).ok()?;
    let list = match doc.get("nodes") {
        Some(v) => v.as_array()?.as_slice(),
        None => &[],
    };
    if list.len() != nodes {
        return None;
    }
    let numbers = |node: &serde_json::Value, key: &str, want: usize| -> Option<Option<Vec<f64>>> {
        let Some(v) = node.get(key) else {
            return Some(None);
        };
        let v: Vec<f64> = v
            .as_array()?
            .iter()
            .map(|x| x.as_f64())
            .collect::<Option<_>>()?;
        (v.len() == want && v.iter().all(|x| x.is_finite())).then_some(Some(v))
    };
    list.iter()
        .map(|node| {
            if let Some(m) = numbers(node, "matrix", 16)? {
                return Some(DMat4::from_cols_slice(&m));
            }
            let t = numbers(node, "translation", 3)?.unwrap_or(vec![0.0; 3]);
            let r = numbers(node, "rotation", 4)?.unwrap_or(vec![0.0, 0.0, 0.0, 1.0]);
            let s = numbers(node, "scale", 3)?.unwrap_or(vec![1.0; 3]);
            Some(DMat4::from_scale_rotation_translation(
                DVec3::from_slice(&s),
                glam::DQuat::from_xyzw(r[0], r[1], r[2], r[3]),
                DVec3::from_slice(&t),
            ))
        })
        .collect()
}

fn parse(bytes: &[u8]) -> Result<gltf::Gltf, String> {
    use gltf::json::validation::Validate;
    let gltf = gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| e.to_string())?;
    let root = gltf.document.as_json();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= root.accessors.len() {
                    return Err(format!(
                        "meshes[{m}].primitives[{p}].attributes.{} names accessor {}, \
                         but there are {}",
                        semantic.to_string(),
                        index.value(),
                        root.accessors.len()
                    ));
                }
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        errors.push(format!("{}: {error}", path()))
    });
    if !errors.is_empty() {
        return Err(format!("invalid glTF: {}", errors.join("; ")));
    }
    Ok(gltf)
}

/// Whether a URI starts with a scheme (`file:`, `http:`, ...; RFC 3986:
/// a letter, then letters, digits, `+`, `-` or `.`, then `:`).
fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            let mut c = scheme.chars();
            c.next().is_some_and(|f| f.is_ascii_alphabetic())
                && c.all(|x| x.is_ascii_alphanumeric() || matches!(x, '+' | '-' | '.'))
        }
        None => false,
    }
}

/// Decodes `%XX` escapes of a relative URI (glTF URIs are percent-encoded).
fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%'
            && i + 2 < b.len()
            && let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2]))
        {
            out.push((h * 16 + l) as u8);
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b.bin"), "a b.bin");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("%4"), "%4");
        assert_eq!(percent_decode("%zz"), "%zz");
    }

    #[test]
    fn strips_and_fans() {
        assert_eq!(
            assemble(Mode::TriangleStrip, &[0, 1, 2, 3]),
            [[0, 1, 2], [1, 2, 3]]
        );
        assert_eq!(
            assemble(Mode::TriangleFan, &[0, 1, 2, 3]),
            [[0, 1, 2], [0, 2, 3]]
        );
        assert_eq!(assemble(Mode::Triangles, &[0, 1, 2, 3]), [[0, 1, 2]]);
    }
}
