//! Writing a [`Scene`] as binary glTF 2.0 (GLB, glTF 2.0 specification sec. 4
//! "GLB File Format Specification"): one root node named `scene`, one
//! child node per object in object order, coordinates in world units.
//!
//! Layout, chosen so that loading the file back ([`super::load_bytes`]
//! with the scene's up axis) gives the same objects, in the same order,
//! with the same names, ids, flags and triangles:
//!
//! - Node 0, `scene`, has the world position of the scene's local origin
//!   ([`crate::geom::Frame::origin`]) as its `translation`, in f64: a
//!   georeferenced scene keeps its precision. Node `i + 1` is object `i`:
//!   its `name` is the object's, its `extras` are `{"index": i}` plus,
//!   when the object has an id or flags, `"vis5d": {"id": .., "flags":
//!   [..]}`, the keys the glTF loader reads (load_gltf.rs, issue 15).
//! - Mesh `i` is object `i`'s: one primitive, non-indexed triangles (mode
//!   4), three vertices per triangle in the triangle's corner order, one
//!   FLOAT VEC3 `POSITION` accessor with its `min` and `max`, one buffer
//!   view. Positions are the corners' world offsets from the origin, in
//!   f32: the local corners with the axes turned back to the world's
//!   ([`crate::geom::Frame::dir_to_world`], an exact permutation), so the
//!   root's translation puts them back in world coordinates.
//! - An empty object ([`super::Object::is_empty`]) gets a mesh of one
//!   point at the origin (mode 0), not a node without a mesh: the loader
//!   makes objects only of nodes with a mesh, and lists a node whose mesh
//!   is points as an empty object in its place (module docs of
//!   [`super`]), so indices survive the round trip. Loading counts each
//!   such point in [`super::LoadReport::skipped_non_triangles`].
//! - One buffer, the GLB `BIN` chunk, every view and chunk 4-byte aligned
//!   (every view is a multiple of 12 bytes long); the `JSON` chunk is
//!   padded with spaces. The bytes depend only on the scene (the JSON's
//!   keys are written in a fixed order).

use std::io::{self, Write};

use serde_json::{Map, Value, json};

use super::Scene;

/// The GLB header's magic, `glTF` little-endian.
const MAGIC: u32 = 0x4654_6C67;
/// The chunk type of the JSON chunk, `JSON`.
const CHUNK_JSON: u32 = 0x4E4F_534A;
/// The chunk type of the binary chunk, `BIN\0`.
const CHUNK_BIN: u32 = 0x004E_4942;
/// glTF's `componentType` for f32.
const FLOAT: u32 = 5126;
/// glTF's buffer view `target` for vertex attributes.
const ARRAY_BUFFER: u32 = 34962;
/// Bytes per vertex: three f32s.
const VERTEX_BYTES: u64 = 12;
/// Triangles converted per write to `out`.
const BATCH: usize = 4096;

/// Writes `scene` as a binary glTF 2.0 file (GLB) into `out`: one root
/// node `scene` translated to the world position of the scene's local
/// origin, under it one node per object, in object order, each with its
/// own mesh of non-indexed triangles in world units relative to that
/// origin (module docs). The same scene gives the same bytes.
///
/// # Errors
/// When `out` fails, or the file would pass GLB's 4 GiB limit (about 119
/// million triangles): then an [`io::ErrorKind::InvalidInput`] error and
/// nothing is written.
pub fn write_glb(scene: &Scene, out: &mut impl Write) -> io::Result<()> {
    let frame = scene.frame();
    let objects = scene.objects();

    // Per object: its vertex count, byte offset and the bounds of its
    // positions as written.
    let mut nodes = Vec::with_capacity(objects.len() + 1);
    let mut meshes = Vec::with_capacity(objects.len());
    let mut accessors = Vec::with_capacity(objects.len());
    let mut views = Vec::with_capacity(objects.len());
    let mut offset = 0u64;
    for (i, object) in objects.iter().enumerate() {
        let (count, mode, min, max) = if object.is_empty() {
            (1u64, 0u32, [0f32; 3], [0f32; 3])
        } else {
            let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
            for v in scene.object_triangles(i).iter().flatten() {
                let p = position(scene, *v);
                for k in 0..3 {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                }
            }
            (3 * object.triangle_count() as u64, 4, min, max)
        };
        let length = count * VERTEX_BYTES;
        let mut extras = Map::new();
        extras.insert("index".into(), json!(i));
        let mut ours = Map::new();
        if let Some(id) = &object.id {
            ours.insert("id".into(), json!(id));
        }
        if !object.flags.is_empty() {
            ours.insert(
                "flags".into(),
                json!(object.flags.names().collect::<Vec<_>>()),
            );
        }
        if !ours.is_empty() {
            extras.insert("vis5d".into(), Value::Object(ours));
        }
        nodes.push(json!({"name": object.name, "mesh": i, "extras": extras}));
        meshes.push(json!({
            "name": object.name,
            "primitives": [{"attributes": {"POSITION": i}, "mode": mode}],
        }));
        accessors.push(json!({
            "bufferView": i,
            "componentType": FLOAT,
            "count": count,
            "type": "VEC3",
            "min": min.map(f64::from),
            "max": max.map(f64::from),
        }));
        views.push(json!({
            "buffer": 0,
            "byteOffset": offset,
            "byteLength": length,
            "target": ARRAY_BUFFER,
        }));
        offset += length;
    }
    let bin_length = offset;
    let mut root = json!({"name": "scene", "translation": frame.origin.to_array()});
    if !objects.is_empty() {
        root["children"] = json!((1..=objects.len()).collect::<Vec<_>>());
    }
    nodes.insert(0, root);
    let mut doc = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("vis5d ", env!("CARGO_PKG_VERSION")),
        },
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
    });
    if !meshes.is_empty() {
        doc["meshes"] = Value::Array(meshes);
        doc["accessors"] = Value::Array(accessors);
        doc["bufferViews"] = Value::Array(views);
        doc["buffers"] = json!([{"byteLength": bin_length}]);
    }
    let mut text = serde_json::to_vec(&doc).map_err(io::Error::other)?;
    text.resize(text.len().next_multiple_of(4), b' ');

    // Every view is a multiple of 12 bytes, so the BIN chunk needs no
    // padding; it is kept for safety.
    let bin_padded = bin_length.next_multiple_of(4);
    let total = 12 + 8 + text.len() as u64 + if bin_length > 0 { 8 + bin_padded } else { 0 };
    let Ok(total) = u32::try_from(total) else {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "the scene makes a GLB of {total} bytes, more than the format's 4 GiB: \
                 write it as OBJ instead"
            ),
        ));
    };
    let mut head = Vec::with_capacity(20);
    head.extend_from_slice(&MAGIC.to_le_bytes());
    head.extend_from_slice(&2u32.to_le_bytes());
    head.extend_from_slice(&total.to_le_bytes());
    head.extend_from_slice(&(text.len() as u32).to_le_bytes());
    head.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.write_all(&head)?;
    out.write_all(&text)?;
    if bin_length > 0 {
        let mut buf = Vec::with_capacity(BATCH * 3 * VERTEX_BYTES as usize);
        buf.extend_from_slice(&(bin_padded as u32).to_le_bytes());
        buf.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        for (i, object) in objects.iter().enumerate() {
            if object.is_empty() {
                buf.extend_from_slice(&[0u8; VERTEX_BYTES as usize]);
                continue;
            }
            for batch in scene.object_triangles(i).chunks(BATCH) {
                for v in batch.iter().flatten() {
                    for c in position(scene, *v) {
                        buf.extend_from_slice(&c.to_le_bytes());
                    }
                }
                out.write_all(&buf)?;
                buf.clear();
            }
        }
        buf.resize(buf.len() + (bin_padded - bin_length) as usize, 0);
        out.write_all(&buf)?;
    }
    out.flush()
}

/// [`write_glb`] into a new `Vec<u8>`.
///
/// # Panics
/// When the scene passes GLB's 4 GiB limit ([`write_glb`]'s error).
pub fn glb_bytes(scene: &Scene) -> Vec<u8> {
    let mut bytes = Vec::new();
    if let Err(e) = write_glb(scene, &mut bytes) {
        panic!("cannot write the scene as GLB: {e}");
    }
    bytes
}

/// The position written for local corner `v`: its world offset from the
/// scene's origin, `frame.to_world(v) - origin` without the rounding of
/// adding and removing the origin in f64 (the axes are permuted, exactly).
fn position(scene: &Scene, v: glam::Vec3) -> [f32; 3] {
    scene.frame().dir_to_world(v).to_array()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use glam::{DVec3, Vec3};

    use super::*;
    use crate::geom::Up;
    use crate::scene::{LoadOptions, ObjectFlags, SceneBuilder, SceneFormat};

    fn committed(name: &str) -> Scene {
        crate::scene::load(format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap()
    }

    /// Two objects around an empty one, with ids and flags.
    fn handmade() -> Scene {
        let mut b = SceneBuilder::new(SceneFormat::Procedural);
        b.begin_object("floor");
        b.push_triangle([Vec3::ZERO, Vec3::X, Vec3::Y]).unwrap();
        b.push_triangle([Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y])
            .unwrap();
        b.begin_object_with(
            "marker",
            Some("marker-1".into()),
            ObjectFlags::ALWAYS_VISIBLE,
        );
        b.begin_object_with(
            "glass \"pane\"",
            Some("pane".into()),
            ObjectFlags::NEVER_OCCLUDER,
        );
        b.push_triangle([
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(0.0, 0.5, 2.0),
            Vec3::new(1.0, 0.5, 0.1),
        ])
        .unwrap();
        let scene = b.finish(Path::new("handmade")).unwrap();
        assert!(scene.objects()[1].is_empty());
        scene
    }

    /// `scene` written as GLB and loaded back with its up axis.
    fn round_trip(scene: &Scene) -> Scene {
        let options = LoadOptions {
            up: scene.frame().up,
            ..LoadOptions::default()
        };
        let back = crate::scene::load_bytes("round-trip.glb", &glb_bytes(scene), &options).unwrap();
        back.validate().unwrap();
        back
    }

    /// The same objects, in order, with the same names, ids, flags and
    /// triangles, their world corners within `tolerance` world units.
    fn assert_same(a: &Scene, b: &Scene, tolerance: f64) {
        assert_eq!(a.frame().up, b.frame().up);
        assert_eq!(a.objects().len(), b.objects().len());
        for (i, (oa, ob)) in a.objects().iter().zip(b.objects()).enumerate() {
            assert_eq!(oa.name, ob.name, "object {i}");
            assert_eq!(oa.id, ob.id, "object {i}");
            assert_eq!(oa.flags, ob.flags, "object {i}");
            let (ta, tb) = (a.object_triangles(i), b.object_triangles(i));
            assert_eq!(ta.len(), tb.len(), "object {i} {:?}", oa.name);
            for (k, (x, y)) in ta.iter().zip(tb).enumerate() {
                for (p, q) in x.iter().zip(y) {
                    let d = (a.frame().to_world(*p) - b.frame().to_world(*q)).length();
                    assert!(d <= tolerance, "object {i} triangle {k}: {p} vs {q}, {d}");
                }
            }
        }
    }

    fn diagonal(scene: &Scene) -> f64 {
        f64::from(scene.bounds().size().length())
    }

    #[test]
    fn scenes_round_trip_through_the_gltf_loader() {
        let apartment = committed("apartment.obj");
        let y_up = crate::scene::load_with(
            format!("{}/scenes/city.obj", env!("CARGO_MANIFEST_DIR")),
            &LoadOptions {
                up: Up::Y,
                ..LoadOptions::default()
            },
            &mut |_, _| {},
        )
        .unwrap();
        assert_eq!(y_up.frame().up, Up::Y);
        for scene in [committed("city.obj"), apartment, y_up, handmade()] {
            let back = round_trip(&scene);
            assert_same(&scene, &back, 1e-5 * diagonal(&scene));
            assert_eq!(back.report().dropped_degenerate, 0);
            assert_eq!(
                back.empty_objects().collect::<Vec<_>>(),
                scene.empty_objects().collect::<Vec<_>>()
            );
            // Near the origin the loaded scene is the very same: writing it
            // again gives the same bytes.
            assert_eq!(back.frame(), scene.frame());
            assert_eq!(back.fingerprint(), scene.fingerprint());
            assert_eq!(glb_bytes(&back), glb_bytes(&scene));
        }
    }

    /// The chunks of a GLB, checked against the spec's layout: (JSON, BIN).
    fn chunks(bytes: &[u8]) -> (serde_json::Value, &[u8]) {
        let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        assert_eq!(&bytes[..4], b"glTF");
        assert_eq!(word(4), 2);
        assert_eq!(word(8) as usize, bytes.len());
        assert_eq!(bytes.len() % 4, 0);
        let json_len = word(12) as usize;
        assert_eq!(word(16), CHUNK_JSON);
        assert_eq!(json_len % 4, 0);
        let text = &bytes[20..20 + json_len];
        let json: serde_json::Value = serde_json::from_slice(text).unwrap();
        let at = 20 + json_len;
        let bin_len = word(at) as usize;
        assert_eq!(word(at + 4), CHUNK_BIN);
        assert_eq!(bin_len % 4, 0);
        assert_eq!(at + 8 + bin_len, bytes.len());
        (json, &bytes[at + 8..])
    }

    #[test]
    fn glb_layout_is_well_formed() {
        for scene in [handmade(), committed("apartment.obj")] {
            let bytes = glb_bytes(&scene);
            assert_eq!(bytes, glb_bytes(&scene), "deterministic");
            let (json, bin) = chunks(&bytes);
            assert_eq!(json["asset"]["version"], "2.0");
            assert_eq!(
                json["asset"]["generator"],
                concat!("vis5d ", env!("CARGO_PKG_VERSION"))
            );
            assert_eq!(json["scene"], 0);
            assert_eq!(json["scenes"], json!([{"nodes": [0]}]));
            let buffer = json["buffers"][0]["byteLength"].as_u64().unwrap() as usize;
            assert!(buffer <= bin.len() && bin.len() - buffer < 4);
            let nodes = json["nodes"].as_array().unwrap();
            assert_eq!(nodes.len(), scene.objects().len() + 1);
            assert_eq!(nodes[0]["name"], "scene");
            assert_eq!(
                nodes[0]["children"],
                json!((1..=scene.objects().len()).collect::<Vec<_>>())
            );
            for (i, o) in scene.objects().iter().enumerate() {
                let node = &nodes[i + 1];
                assert_eq!(node["name"], o.name.as_str());
                assert_eq!(node["extras"]["index"], i);
                assert_eq!(node["extras"]["vis5d"]["id"].as_str(), o.id.as_deref());
                let m = node["mesh"].as_u64().unwrap() as usize;
                let prim = &json["meshes"][m]["primitives"][0];
                assert_eq!(prim["mode"], if o.is_empty() { 0 } else { 4 });
                let acc =
                    &json["accessors"][prim["attributes"]["POSITION"].as_u64().unwrap() as usize];
                assert_eq!(acc["componentType"], FLOAT);
                assert_eq!(acc["type"], "VEC3");
                let count = acc["count"].as_u64().unwrap() as usize;
                assert_eq!(
                    count,
                    if o.is_empty() {
                        1
                    } else {
                        3 * o.triangle_count()
                    }
                );
                let view = &json["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
                let start = view["byteOffset"].as_u64().unwrap() as usize;
                let len = view["byteLength"].as_u64().unwrap() as usize;
                assert_eq!(start % 4, 0);
                assert_eq!(len, 12 * count);
                assert!(start + len <= buffer);
                // min and max bound the data and are reached.
                let data: Vec<f32> = bin[start..start + len]
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                    .collect();
                for k in 0..3 {
                    let axis = data.iter().skip(k).step_by(3);
                    let lo = axis.clone().copied().fold(f32::INFINITY, f32::min);
                    let hi = axis.copied().fold(f32::NEG_INFINITY, f32::max);
                    // As f32: serde_json parses without `float_roundtrip`,
                    // to within an f64 step.
                    assert_eq!(acc["min"][k].as_f64().map(|x| x as f32), Some(lo));
                    assert_eq!(acc["max"][k].as_f64().map(|x| x as f32), Some(hi));
                }
            }
            // The gltf crate's own validation accepts it.
            gltf::Gltf::from_slice(&bytes).unwrap();
        }
    }

    #[test]
    fn far_scenes_keep_their_world_positions() {
        for scene in [committed("apartment.obj"), handmade()] {
            for up in [Up::Z, Up::Y] {
                let far = scene
                    .clone()
                    .with_up(up)
                    .translated(DVec3::new(1e6, 2e6, 0.0), Path::new("far"))
                    .unwrap();
                assert!(!far.frame().at_world_origin(), "{:?}", far.frame());
                let (json, _) = chunks(&glb_bytes(&far));
                assert_eq!(
                    json["nodes"][0]["translation"],
                    json!(far.frame().origin.to_array())
                );
                let back = round_trip(&far);
                assert_same(&far, &back, 1e-3);
                // And where the original scene was, moved.
                for (t, u) in scene.triangles().iter().zip(back.triangles()) {
                    for (p, q) in t.iter().zip(u) {
                        let want = scene.frame().to_world(*p) + DVec3::new(1e6, 2e6, 0.0);
                        let d = (back.frame().to_world(*q) - want).length();
                        assert!(d <= 1e-3, "{p} vs {q}: {d}");
                    }
                }
            }
        }
    }
}
