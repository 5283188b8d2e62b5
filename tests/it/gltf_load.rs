//! glTF and GLB loading: node hierarchy and transforms, naming, buffers
//! embedded, beside the file and in the GLB chunk, and bad input.

use std::f32::consts::FRAC_1_SQRT_2;

use base64::Engine;
use glam::{Mat4, Quat, Vec3};
use serde_json::{Value, json};
use vis5d::scene::{self, Scene, SceneError};

/// One mesh of a test file: one primitive.
pub(crate) struct Mesh {
    pub name: Option<&'static str>,
    pub positions: Vec<[f32; 3]>,
    pub indices: Option<Vec<u32>>,
    /// glTF primitive mode (4 = triangles, 5 = strip, 6 = fan, 0 = points).
    pub mode: u32,
}

fn tri_mesh(name: Option<&'static str>) -> Mesh {
    Mesh {
        name,
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        indices: Some(vec![0, 1, 2, 0, 1, 3]),
        mode: 4,
    }
}

/// The glTF JSON (without `buffers[0].uri`) and the binary buffer for
/// `meshes`, `nodes` and `scenes`.
pub(crate) fn document(meshes: &[Mesh], nodes: Value, scenes: Value) -> (Value, Vec<u8>) {
    let mut bin = Vec::new();
    let (mut views, mut accessors, mut jmeshes) = (vec![], vec![], vec![]);
    for m in meshes {
        let offset = bin.len();
        for p in &m.positions {
            for c in p {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bin.len() - offset}));
        let finite: Vec<&[f32; 3]> = m
            .positions
            .iter()
            .filter(|p| p.iter().all(|c| c.is_finite()))
            .collect();
        let (mut min, mut max) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in finite {
            for k in 0..3 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        accessors.push(json!({
            "bufferView": views.len() - 1, "componentType": 5126, "count": m.positions.len(),
            "type": "VEC3", "min": min, "max": max
        }));
        let mut prim = json!({"attributes": {"POSITION": accessors.len() - 1}, "mode": m.mode});
        if let Some(ix) = &m.indices {
            let offset = bin.len();
            for i in ix {
                bin.extend_from_slice(&i.to_le_bytes());
            }
            views
                .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bin.len() - offset}));
            accessors.push(json!({
                "bufferView": views.len() - 1, "componentType": 5125, "count": ix.len(), "type": "SCALAR"
            }));
            prim["indices"] = json!(accessors.len() - 1);
        }
        let mut jm = json!({"primitives": [prim]});
        if let Some(n) = m.name {
            jm["name"] = json!(n);
        }
        jmeshes.push(jm);
    }
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": scenes,
        "nodes": nodes,
        "meshes": jmeshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    (doc, bin)
}

/// Writes `doc` with its buffer embedded as a data URI.
pub(crate) fn write_embedded(
    dir: &tempfile::TempDir,
    name: &str,
    mut doc: Value,
    bin: &[u8],
) -> std::path::PathBuf {
    let b64 = base64::engine::general_purpose::STANDARD.encode(bin);
    doc["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{b64}"));
    let path = dir.path().join(name);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

/// Writes `doc` and `bin` as a binary glTF.
fn write_glb(dir: &tempfile::TempDir, name: &str, doc: &Value, bin: &[u8]) -> std::path::PathBuf {
    let mut json = serde_json::to_vec(doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
    out.extend_from_slice(&bin);
    let path = dir.path().join(name);
    std::fs::write(&path, out).unwrap();
    path
}

/// A hierarchy: node 0 "parent" (translated, mesh "meshA"), its child node
/// 1 (unnamed, rotated and scaled, mesh "meshB"), its grandchild node 2
/// (unnamed, unnamed mesh), and node 3 with a mesh but outside the scene.
fn hierarchy() -> (Value, Vec<u8>) {
    let meshes = [
        tri_mesh(Some("meshA")),
        tri_mesh(Some("meshB")),
        tri_mesh(None),
        tri_mesh(Some("orphan")),
    ];
    let nodes = json!([
        {"name": "parent", "mesh": 0, "translation": [10.0, 0.0, 0.0], "children": [1]},
        {"mesh": 1, "rotation": [0.0, 0.0, FRAC_1_SQRT_2, FRAC_1_SQRT_2], "scale": [2.0, 2.0, 2.0], "children": [2]},
        {"mesh": 2, "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1]},
        {"name": "not_in_scene", "mesh": 3}
    ]);
    document(&meshes, nodes, json!([{"nodes": [0]}]))
}

fn expected_hierarchy_transforms() -> [Mat4; 3] {
    let parent = Mat4::from_translation(Vec3::new(10.0, 0.0, 0.0));
    let child = parent
        * Mat4::from_scale_rotation_translation(
            Vec3::splat(2.0),
            Quat::from_xyzw(0.0, 0.0, FRAC_1_SQRT_2, FRAC_1_SQRT_2),
            Vec3::ZERO,
        );
    let grandchild = child * Mat4::from_translation(Vec3::new(0.0, 0.0, 5.0));
    [parent, child, grandchild]
}

fn check_hierarchy(s: &Scene) {
    s.validate().unwrap();
    let names: Vec<&str> = s.objects().iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["parent", "meshB", "node2"]);
    let local = tri_mesh(None);
    for (o, m) in expected_hierarchy_transforms().iter().enumerate() {
        let tris = s.object_triangles(o);
        assert_eq!(tris.len(), 2);
        for (t, ix) in tris.iter().zip(local.indices.as_ref().unwrap().chunks(3)) {
            for (v, &i) in t.iter().zip(ix) {
                let want = m.transform_point3(Vec3::from_array(local.positions[i as usize]));
                assert!((*v - want).length() < 1e-5, "object {o}: {v} vs {want}");
            }
        }
    }
}

#[test]
fn hierarchy_transforms_and_names_embedded_buffer() {
    let dir = tempfile::tempdir().unwrap();
    let (doc, bin) = hierarchy();
    let s = scene::load(write_embedded(&dir, "h.gltf", doc, &bin)).unwrap();
    assert_eq!(s.format(), scene::SceneFormat::Gltf);
    check_hierarchy(&s);
}

#[test]
fn hierarchy_glb() {
    let dir = tempfile::tempdir().unwrap();
    let (mut doc, bin) = hierarchy();
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    let s = scene::load(write_glb(&dir, "h.glb", &doc, &bin)).unwrap();
    assert_eq!(s.format(), scene::SceneFormat::Glb);
    check_hierarchy(&s);
}

#[test]
fn buffer_in_a_file_beside_the_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let (mut doc, bin) = hierarchy();
    std::fs::write(dir.path().join("my buffer.bin"), &bin).unwrap();
    doc["buffers"][0]["uri"] = json!("my%20buffer.bin");
    let path = dir.path().join("side.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    check_hierarchy(&scene::load(&path).unwrap());

    std::fs::remove_file(dir.path().join("my buffer.bin")).unwrap();
    let msg = scene::load(&path).unwrap_err().to_string();
    assert!(
        msg.contains("side.gltf") && msg.contains("my buffer.bin"),
        "{msg}"
    );
}

#[test]
fn no_scene_means_every_root_node() {
    let dir = tempfile::tempdir().unwrap();
    let (mut doc, bin) = hierarchy();
    doc.as_object_mut().unwrap().remove("scene");
    doc.as_object_mut().unwrap().remove("scenes");
    let s = scene::load(write_embedded(&dir, "noscene.gltf", doc, &bin)).unwrap();
    let names: Vec<&str> = s.objects().iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["parent", "meshB", "node2", "not_in_scene"]);
}

#[test]
fn strips_fans_points_and_unindexed() {
    let dir = tempfile::tempdir().unwrap();
    let quad = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let meshes = [
        Mesh {
            name: Some("strip"),
            positions: quad.clone(),
            indices: None,
            mode: 5,
        },
        Mesh {
            name: Some("fan"),
            positions: quad.clone(),
            indices: Some(vec![0, 1, 3, 2]),
            mode: 6,
        },
        Mesh {
            name: Some("points"),
            positions: quad.clone(),
            indices: None,
            mode: 0,
        },
        Mesh {
            name: Some("list"),
            positions: quad[..3].to_vec(),
            indices: None,
            mode: 4,
        },
    ];
    let nodes = json!([{"mesh": 0}, {"mesh": 1}, {"mesh": 2}, {"mesh": 3}]);
    let (doc, bin) = document(&meshes, nodes, json!([{"nodes": [0, 1, 2, 3]}]));
    let s = scene::load(write_embedded(&dir, "modes.gltf", doc, &bin)).unwrap();
    let got: Vec<(&str, usize)> = s
        .objects()
        .iter()
        .map(|o| (o.name.as_str(), o.triangle_count()))
        .collect();
    assert_eq!(got, [("strip", 2), ("fan", 2), ("points", 0), ("list", 1)]);
    assert_eq!(s.report().skipped_non_triangles, 1);
    assert_eq!(s.report().empty_objects, [2]);
    // Both quads cover the unit square.
    assert!((s.objects()[0].area - 1.0).abs() < 1e-9 && (s.objects()[1].area - 1.0).abs() < 1e-9);
}

fn load_err(doc: Value, bin: &[u8]) -> (SceneError, String) {
    let dir = tempfile::tempdir().unwrap();
    let e = scene::load(write_embedded(&dir, "bad.gltf", doc, bin)).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("bad.gltf"), "{msg}");
    (e, msg)
}

#[test]
fn index_out_of_range() {
    let mut m = tri_mesh(Some("m"));
    m.indices = Some(vec![0, 1, 7]);
    let (doc, bin) = document(&[m], json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    let (e, msg) = load_err(doc, &bin);
    assert!(matches!(e, SceneError::IndexOutOfRange { .. }), "{msg}");
    assert!(msg.contains("index 7 but only 4 vertices"), "{msg}");
}

#[test]
fn non_finite_positions() {
    let mut m = tri_mesh(Some("m"));
    m.positions[1] = [f32::NAN, 0.0, 0.0];
    let (doc, bin) = document(
        &[m],
        json!([{"name": "bad node", "mesh": 0}]),
        json!([{"nodes": [0]}]),
    );
    let (e, msg) = load_err(doc, &bin);
    assert!(matches!(e, SceneError::NonFinite { .. }), "{msg}");
    assert!(msg.contains("\"bad node\""), "{msg}");
}

#[test]
fn malformed_documents() {
    let dir = tempfile::tempdir().unwrap();
    // Not JSON at all, and a truncated GLB.
    for (name, bytes) in [
        ("x.gltf", b"{ not json".to_vec()),
        ("x.glb", b"glTF\x02\0\0\0\xff\0\0\0".to_vec()),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let msg = scene::load(&p).unwrap_err().to_string();
        assert!(
            msg.contains(name) && msg.contains("cannot parse the glTF"),
            "{msg}"
        );
    }
    // A POSITION accessor of the wrong type.
    let (mut doc, bin) = document(
        &[tri_mesh(None)],
        json!([{"mesh": 0}]),
        json!([{"nodes": [0]}]),
    );
    doc["accessors"][0]["type"] = json!("VEC2");
    doc["accessors"][0]["min"] = json!([0.0, 0.0]);
    doc["accessors"][0]["max"] = json!([1.0, 1.0]);
    let (_, msg) = load_err(doc, &bin);
    assert!(msg.contains("POSITION"), "{msg}");
    // An accessor running past its view.
    let (mut doc, bin) = document(
        &[tri_mesh(None)],
        json!([{"mesh": 0}]),
        json!([{"nodes": [0]}]),
    );
    doc["accessors"][1]["count"] = json!(600);
    let (_, msg) = load_err(doc, &bin);
    assert!(msg.contains("runs past the end"), "{msg}");
    // A view running past its buffer.
    let (mut doc, bin) = document(
        &[tri_mesh(None)],
        json!([{"mesh": 0}]),
        json!([{"nodes": [0]}]),
    );
    doc["bufferViews"][1]["byteLength"] = json!(4096);
    doc["accessors"][1]["count"] = json!(600);
    let (_, msg) = load_err(doc, &bin);
    assert!(msg.contains("runs past the end"), "{msg}");
    // A buffer shorter than it says.
    let (mut doc, bin) = document(
        &[tri_mesh(None)],
        json!([{"mesh": 0}]),
        json!([{"nodes": [0]}]),
    );
    doc["buffers"][0]["byteLength"] = json!(bin.len() + 100);
    let (_, msg) = load_err(doc, &bin);
    assert!(msg.contains("declares byteLength"), "{msg}");
    // No meshes at all.
    let (doc, bin) = document(&[], json!([{"name": "empty"}]), json!([{"nodes": [0]}]));
    let (e, msg) = load_err(doc, &bin);
    assert!(matches!(e, SceneError::Empty { .. }), "{msg}");
}

/// A glTF whose buffer `uri` named `/etc/passwd` or `../../etc/passwd` was
/// loaded as geometry (and `/dev/stdin` hung): a model may name only
/// files inside its own folder unless the caller allows more, and only
/// regular files are read.
#[test]
fn buffers_outside_the_models_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (mut doc, bin) = hierarchy();
    let model_dir = dir.path().join("model");
    std::fs::create_dir(&model_dir).unwrap();
    std::fs::write(dir.path().join("outside.bin"), &bin).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(dir.path().join("outside.bin"), model_dir.join("link.bin")).unwrap();
    let path = model_dir.join("m.gltf");
    let outside = dir.path().join("outside.bin");
    let mut uris = vec![
        "../outside.bin".to_owned(),
        outside.to_str().unwrap().to_owned(),
        format!("file://{}", outside.display()),
        "/etc/passwd".to_owned(),
        "../../../../../../etc/passwd".to_owned(),
    ];
    if cfg!(unix) {
        uris.push("link.bin".to_owned());
    }
    for uri in &uris {
        doc["buffers"][0]["uri"] = json!(uri);
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        match scene::load(&path) {
            Err(SceneError::OutsidePath { buffer: 0, .. }) => {}
            other => panic!("{uri}: {other:?}"),
        }
    }
    // Allowed by the caller: a file outside loads; a device never does.
    let allow = scene::LoadOptions {
        allow_outside_paths: true,
        ..Default::default()
    };
    for uri in ["../outside.bin", "link.bin"] {
        doc["buffers"][0]["uri"] = json!(uri);
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        if cfg!(unix) || uri != "link.bin" {
            check_hierarchy(&scene::load_with(&path, &allow, &mut |_, _| {}).unwrap());
        }
    }
    for uri in ["/dev/stdin", "/dev/zero"] {
        doc["buffers"][0]["uri"] = json!(uri);
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        let msg = scene::load_with(&path, &allow, &mut |_, _| {})
            .unwrap_err()
            .to_string();
        assert!(msg.contains("regular file"), "{uri}: {msg}");
    }
}

/// A buffer file was read whole whatever its `byteLength` said: a 3 GB
/// side file cost 3 GB for a 72-byte buffer. Only the declared bytes are
/// read now (the side file here is sparse: it costs no disk).
#[test]
fn a_buffer_file_is_read_only_as_far_as_its_byte_length() {
    let dir = tempfile::tempdir().unwrap();
    let (mut doc, bin) = hierarchy();
    let side = dir.path().join("big.bin");
    std::fs::write(&side, &bin).unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&side)
        .unwrap()
        .set_len(3_000_000_000)
        .unwrap();
    doc["buffers"][0]["uri"] = json!("big.bin");
    let path = dir.path().join("m.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    check_hierarchy(&scene::load(&path).unwrap());
    // Shorter than declared: an error naming the buffer.
    std::fs::write(&side, &bin[..bin.len() / 2]).unwrap();
    let msg = scene::load(&path).unwrap_err().to_string();
    assert!(msg.contains("buffer 0") && msg.contains("fewer"), "{msg}");
}

/// A primitive whose POSITION named a missing accessor panicked inside
/// gltf-json's validation: now an error naming the reference.
#[test]
fn a_missing_position_accessor_is_an_error_not_a_panic() {
    let (mut doc, bin) = document(
        &[tri_mesh(Some("m"))],
        json!([{"mesh": 0}]),
        json!([{"nodes": [0]}]),
    );
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(5);
    let (e, msg) = load_err(doc.clone(), &bin);
    assert!(matches!(e, SceneError::Syntax { .. }), "{msg}");
    assert!(msg.contains("POSITION names accessor 5"), "{msg}");
    // Other dangling references are gltf-json's validation errors.
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(0);
    doc["nodes"][0]["mesh"] = json!(9);
    let (_, msg) = load_err(doc, &bin);
    assert!(msg.contains("invalid glTF"), "{msg}");
}

/// One input per outcome of the glTF/GLB fuzz target's corpus
/// (`fuzz/keep_outcomes.py`), each named after it: `ok.gltf` and `ok.glb`
/// load, every other is refused; none panics.
#[test]
fn fuzz_corpus_loads_or_is_refused_without_panicking() {
    crate::replay_scene_corpus("gltf");
}

/// A georeferenced glTF puts its large offset in a node's translation:
/// read and composed in f64 and held in a local frame, the mesh keeps the
/// precision of its f32 positions (in f32, 4,649,876.3 is 4,649,876.5; a
/// review found gltf-json's f32 translation moved the model so).
#[test]
fn a_georeferenced_node_translation_keeps_the_mesh_precise() {
    let dir = tempfile::tempdir().unwrap();
    let mut fine = tri_mesh(Some("fine"));
    for p in &mut fine.positions {
        *p = p.map(|c| c * 0.1); // a part 10 cm across
    }
    // Nested: the offset split between a parent and its child, as
    // exporters do.
    let nodes = json!([
        {"name": "site", "translation": [500_000.0, 4_649_000.0, 0.0], "children": [1]},
        {"name": "part", "mesh": 0, "translation": [123.7, 876.3, 12.1]}
    ]);
    let (mut doc, bin) = document(&[fine], nodes, json!([{"nodes": [0]}]));
    let s = scene::load(write_embedded(&dir, "geo.gltf", doc.clone(), &bin)).unwrap();
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    let glb = scene::load(write_glb(&dir, "geo.glb", &doc, &bin)).unwrap();
    assert_eq!(glb.triangles(), s.triangles());
    assert_eq!(glb.frame(), s.frame());
    s.validate().unwrap();
    let frame = s.frame();
    assert!(!frame.is_identity());
    let local = tri_mesh(None);
    for (t, ix) in s
        .object_triangles(0)
        .iter()
        .zip(local.indices.as_ref().unwrap().chunks(3))
    {
        for (v, &i) in t.iter().zip(ix) {
            let want =
                glam::DVec3::from_array(local.positions[i as usize].map(|c| f64::from(c * 0.1)))
                    + glam::DVec3::new(500_123.7, 4_649_876.3, 12.1);
            let got = frame.to_world(*v);
            assert!((got - want).length() < 1e-6, "{got} vs {want}");
        }
    }
}

/// The same triangles as OBJ and as GLB give one fingerprint, and an
/// engine gets it from its own vertex and index buffers
/// (`codec::fingerprint_meshes`): near the origin and far from it, +z and
/// +y up, with a triangle of zero area, an object of only that and an
/// object of no triangles (both empty objects, listed and counted).
#[test]
fn one_fingerprint_whatever_the_format_and_from_engine_buffers() {
    use vis5d::codec::{MeshError, fingerprint_meshes};
    use vis5d::geom::Up;
    let dir = tempfile::tempdir().unwrap();
    for (k, offset) in [[0.0f32, 0.0, 0.0], [600_000.5, -2_000.25, 31.0]]
        .into_iter()
        .enumerate()
    {
        let at = |p: [f32; 3]| [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]];
        // A box corner fan (shared vertices), a quad with a zero-area
        // triangle, and an object of a zero-area triangle only.
        type Object = (&'static str, Vec<[f32; 3]>, Vec<u32>);
        let objects: Vec<Object> = vec![
            (
                "fan",
                vec![
                    [0.0, 0.0, 0.0],
                    [1.5, 0.0, 0.0],
                    [0.0, 2.25, 0.0],
                    [0.0, 0.0, 0.75],
                ]
                .into_iter()
                .map(at)
                .collect(),
                vec![0, 1, 2, 0, 1, 3, 0, 2, 3],
            ),
            (
                "quad",
                vec![
                    [3.0, 0.0, 0.1],
                    [4.0, 0.0, 0.1],
                    [4.0, 1.0, 0.3],
                    [3.0, 1.0, 0.3],
                ]
                .into_iter()
                .map(at)
                .collect(),
                vec![0, 1, 2, 0, 2, 3, 0, 0, 1],
            ),
            (
                "sliver",
                vec![[5.0, 5.0, 5.0], [6.0, 6.0, 6.0], [7.0, 7.0, 7.0]]
                    .into_iter()
                    .map(at)
                    .collect(),
                vec![0, 1, 2],
            ),
            // No faces (OBJ), points only (glTF), no indices (engine).
            ("nothing", vec![at([8.0, 8.0, 8.0])], vec![]),
            (
                "last",
                vec![[0.0, 3.0, 0.0], [1.0, 3.0, 0.0], [0.0, 4.0, 0.5]]
                    .into_iter()
                    .map(at)
                    .collect(),
                vec![0, 1, 2],
            ),
        ];
        // OBJ text: the loader reads coordinates as f64, so each is printed
        // as the f64 of its f32 (the shortest decimal of exactly that
        // value): the same numbers as the GLB's.
        let mut obj = String::new();
        let mut base = 1;
        for (name, positions, indices) in &objects {
            obj += &format!("o {name}\n");
            for p in positions {
                let [x, y, z] = p.map(f64::from);
                obj += &format!("v {x} {y} {z}\n");
            }
            for t in indices.chunks(3) {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| i + base);
                obj += &format!("f {a} {b} {c}\n");
            }
            base += positions.len() as u32;
        }
        let obj_path = dir.path().join(format!("model{k}.obj"));
        std::fs::write(&obj_path, obj).unwrap();
        let meshes: Vec<Mesh> = objects
            .iter()
            .map(|(name, positions, indices)| Mesh {
                name: Some(name),
                positions: positions.clone(),
                indices: (!indices.is_empty()).then(|| indices.clone()),
                // No triangle: points.
                mode: if indices.is_empty() { 0 } else { 4 },
            })
            .collect();
        let nodes: Vec<Value> = (0..meshes.len())
            .map(|i| json!({"mesh": i, "name": objects[i].0}))
            .collect();
        let (doc, bin) = document(&meshes, json!(nodes), json!([{"nodes": [0, 1, 2, 3, 4]}]));
        let glb_path = write_glb(&dir, &format!("model{k}.glb"), &doc, &bin);
        let buffers: Vec<(&[[f32; 3]], &[u32])> = objects
            .iter()
            .map(|(_, p, i)| (p.as_slice(), i.as_slice()))
            .collect();
        for up in [Up::Z, Up::Y] {
            let options = scene::LoadOptions {
                up,
                ..Default::default()
            };
            let from_obj = scene::load_with(&obj_path, &options, &mut |_, _| {}).unwrap();
            let from_glb = scene::load_with(&glb_path, &options, &mut |_, _| {}).unwrap();
            let listed = |s: &Scene| -> Vec<(String, usize)> {
                s.objects()
                    .iter()
                    .map(|o| (o.name.clone(), o.triangle_count()))
                    .collect()
            };
            let want: Vec<(String, usize)> = [
                ("fan", 3),
                ("quad", 2),
                ("sliver", 0),
                ("nothing", 0),
                ("last", 1),
            ]
            .map(|(n, k)| (n.to_owned(), k))
            .into();
            assert_eq!(listed(&from_obj), want, "empty objects are listed");
            assert_eq!(listed(&from_glb), want);
            assert_eq!(from_obj.fingerprint(), from_glb.fingerprint(), "{k} {up:?}");
            assert_eq!(
                fingerprint_meshes(&buffers, up),
                Ok(from_obj.fingerprint()),
                "{k} {up:?}"
            );
            // An empty object counts: without it the indices shift.
            let mut without = buffers.clone();
            without.remove(3);
            assert_ne!(fingerprint_meshes(&without, up), Ok(from_obj.fingerprint()));
        }
        assert_eq!(
            k == 1,
            !scene::load(&obj_path).unwrap().frame().at_world_origin()
        );
    }
    // Bad buffers are named, not a panic.
    let p = [[0.0f32; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(
        fingerprint_meshes(&[(&p, &[0, 1])], Up::Z),
        Err(MeshError::Indices {
            object: 0,
            count: 2
        })
    );
    assert_eq!(
        fingerprint_meshes(&[(&p, &[0, 1, 2]), (&p, &[0, 1, 3])], Up::Z),
        Err(MeshError::OutOfRange {
            object: 1,
            index: 3,
            vertices: 3
        })
    );
    let nan = [[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(
        fingerprint_meshes(&[(&nan, &[0, 1, 2])], Up::Z),
        Err(MeshError::NonFinite { object: 0 })
    );
    assert_eq!(
        fingerprint_meshes(&[(&p, &[0, 0, 1])], Up::Z),
        Err(MeshError::Empty)
    );
}

/// Four objects: "door" (node 0) with a vis5d id and flag, two "crate"s
/// (nodes 1 and 2; the first's extras hold only other keys, the second a
/// flag), "wall" (node 3) with `extras` that are not an object.
fn with_extras() -> (Value, Vec<u8>) {
    let mut meshes = Vec::new();
    for k in 0..4 {
        let mut m = tri_mesh(None);
        for p in &mut m.positions {
            p[0] += 2.0 * k as f32;
        }
        meshes.push(m);
    }
    let nodes = json!([
        {"name": "door", "mesh": 0,
         "extras": {"vis5d": {"id": "door-17", "flags": ["never_occluder"]}, "author": "x"}},
        {"name": "crate", "mesh": 1, "extras": {"exporter": {"id": 5}}},
        {"name": "crate", "mesh": 2, "extras": {"vis5d": {"flags": ["always_visible"]}}},
        {"name": "wall", "mesh": 3, "extras": "just text"}
    ]);
    document(&meshes, nodes, json!([{"nodes": [0, 1, 2, 3]}]))
}

/// A glTF node's `extras.vis5d` gives the object's id and flags; other
/// extras are ignored, and a glTF without them loads as before.
#[test]
fn node_extras_give_ids_and_flags() {
    use vis5d::scene::ObjectFlags;
    let dir = tempfile::tempdir().unwrap();
    let (doc, bin) = with_extras();
    let s = scene::load(write_embedded(&dir, "x.gltf", doc, &bin)).unwrap();
    s.validate().unwrap();
    let got: Vec<(Option<&str>, ObjectFlags)> = s
        .objects()
        .iter()
        .map(|o| (o.id.as_deref(), o.flags))
        .collect();
    assert_eq!(
        got,
        [
            (Some("door-17"), ObjectFlags::NEVER_OCCLUDER),
            (None, ObjectFlags::NONE),
            (None, ObjectFlags::ALWAYS_VISIBLE),
            (None, ObjectFlags::NONE),
        ]
    );
    assert_eq!(s.ids(), ["door-17", "crate#1", "crate#2", "wall"]);
    // Without extras: no ids, no flags, the default ids.
    let (doc, bin) = hierarchy();
    let plain = scene::load(write_embedded(&dir, "h.gltf", doc, &bin)).unwrap();
    assert!(
        plain
            .objects()
            .iter()
            .all(|o| o.id.is_none() && o.flags == ObjectFlags::NONE)
    );
    assert_eq!(plain.ids(), ["parent", "meshB", "node2"]);
}

/// The model's ids and flags reach the `.v5d` of `build` and `build
/// --conservative`; `--ids` replaces them (its keys still the default
/// ids) and `--flags` adds to them.
#[test]
fn extras_ids_and_flags_reach_the_file_and_sidecars_override_and_add() {
    use vis5d::query::Pvs;
    use vis5d::scene::ObjectFlags;
    let dir = tempfile::tempdir().unwrap();
    let (doc, bin) = with_extras();
    let model = write_embedded(&dir, "x.gltf", doc, &bin);
    let s = |p: &std::path::Path| p.to_str().unwrap().to_owned();
    let v5d = dir.path().join("x.v5d");
    let table = |pvs: &Pvs| -> Vec<(String, ObjectFlags)> {
        pvs.objects()
            .map(|o| (o.id().to_owned(), o.flags()))
            .collect()
    };
    let (n, a) = (ObjectFlags::NEVER_OCCLUDER, ObjectFlags::ALWAYS_VISIBLE);
    let none = ObjectFlags::NONE;
    for method in [
        &["--max-depth", "2"][..],
        &["--conservative", "--max-depth", "1"],
    ] {
        let mut args = vec!["build".to_owned(), s(&model), "-o".into(), s(&v5d)];
        args.extend(method.iter().map(|a| a.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = crate::vis5d(&args);
        assert!(out.status.success(), "{}", crate::text(&out.stderr));
        let pvs = Pvs::load(&v5d).unwrap();
        let want = [
            ("door-17", n),
            ("crate#1", none),
            ("crate#2", a),
            ("wall", none),
        ]
        .map(|(i, f)| (i.to_owned(), f));
        assert_eq!(table(&pvs), want, "{method:?}");
        assert_eq!(pvs.object_index("door-17"), Some(0));
        // `query --json --ids` lists them (from outside the view box:
        // every object in the frustum).
        let out = crate::vis5d(&[
            "query",
            &s(&v5d),
            "--pos",
            "3.5,-3,0.5",
            "--dir",
            "0,1,0",
            "--fov",
            "120",
            "--json",
            "--ids",
        ]);
        assert!(out.status.success(), "{}", crate::text(&out.stderr));
        let rows: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(
            rows,
            json!([
                {"index": 0, "id": "door-17", "name": "door", "flags": ["never_occluder"]},
                {"index": 1, "id": "crate#1", "name": "crate"},
                {"index": 2, "id": "crate#2", "name": "crate", "flags": ["always_visible"]},
                {"index": 3, "id": "wall", "name": "wall"},
            ]),
            "{method:?}"
        );
    }
    // Sidecars: ids keyed by the default ids replace the model's; flags
    // are added to the model's.
    let ids = dir.path().join("ids.json");
    std::fs::write(&ids, r#"{"door": "D", "crate#1": "C1"}"#).unwrap();
    let flags = dir.path().join("flags.json");
    std::fs::write(
        &flags,
        r#"{"door": ["always_visible"], "wall": ["never_occluder"]}"#,
    )
    .unwrap();
    let build = |extra: &[&str]| {
        let mut args = vec!["build", model.to_str().unwrap(), "--max-depth", "2"];
        let out_path = s(&v5d);
        args.extend(["-o", &out_path]);
        args.extend(extra);
        crate::vis5d(&args)
    };
    let out = build(&["--ids", &s(&ids), "--flags", &s(&flags)]);
    assert!(out.status.success(), "{}", crate::text(&out.stderr));
    let want = [("D", n.union(a)), ("C1", none), ("crate#2", a), ("wall", n)]
        .map(|(i, f)| (i.to_owned(), f));
    assert_eq!(table(&Pvs::load(&v5d).unwrap()), want);
    // A sidecar key is a default id, not the model's id.
    std::fs::write(&ids, r#"{"door-17": "D"}"#).unwrap();
    let out = build(&["--ids", &s(&ids), "--dry-run"]);
    let err = crate::text(&out.stderr);
    assert!(
        !out.status.success() && err.contains("\"door-17\""),
        "{err}"
    );
    // Ids stay unique: a sidecar id that is a model's id is refused.
    std::fs::write(&ids, r#"{"wall": "door-17"}"#).unwrap();
    let out = build(&["--ids", &s(&ids), "--dry-run"]);
    let err = crate::text(&out.stderr);
    assert!(
        !out.status.success() && err.contains("two objects would have the id \"door-17\""),
        "{err}"
    );
}

/// Bad `extras.vis5d` values are load errors naming the file and the
/// node.
#[test]
fn bad_extras_are_errors_naming_the_file_and_the_node() {
    let long = "x".repeat(vis5d::codec::MAX_ID_BYTES + 1);
    let cases: Vec<(usize, Value, &str)> = vec![
        (2, json!(5), "must be an object"),
        (2, json!(["door"]), "must be an object"),
        (2, json!({"id": 3}), "id must be a string"),
        (2, json!({"id": null}), "id must be a string"),
        (
            2,
            json!({"flags": "never_occluder"}),
            "flags must be a list",
        ),
        (2, json!({"flags": ["glass"]}), "unknown flag \"glass\""),
        (2, json!({"flags": [1]}), "unknown flag 1"),
        (
            2,
            json!({"flag": ["never_occluder"]}),
            "has the key \"flag\"",
        ),
        (2, json!({"id": ""}), "is empty, longer than 1024 bytes"),
        (
            2,
            json!({"id": "a\u{0}b"}),
            "is empty, longer than 1024 bytes",
        ),
        (2, json!({"id": long}), "is empty, longer than 1024 bytes"),
        // Two objects with one id: another node's, or another object's
        // default id.
        (
            0,
            json!({"id": "door-17"}),
            "node 0 \"door\" and node 2 \"crate\" would both have the id \"door-17\"",
        ),
        (
            1,
            json!({"id": "wall"}),
            "node 1 \"crate\" and node 3 \"wall\" would both have the id \"wall\"",
        ),
    ];
    for (node, value, want) in cases {
        let (mut doc, bin) = with_extras();
        if node == 2 {
            doc["nodes"][2]["extras"]["vis5d"] = value.clone();
        } else {
            // Node 2 takes door's id; or node 1 takes wall's name.
            doc["nodes"][2]["extras"]["vis5d"] = json!({});
            doc["nodes"][node]["extras"] = json!({"vis5d": value});
            if node == 0 {
                doc["nodes"][0]["extras"] = json!({"vis5d": {"id": "door-17"}});
                doc["nodes"][2]["extras"] = json!({"vis5d": {"id": "door-17"}});
            }
        }
        let (e, msg) = load_err(doc, &bin);
        let at = if node == 2 {
            "node 2 \"crate\""
        } else {
            "node "
        };
        assert!(msg.contains(want) && msg.contains(at), "{value}: {msg}");
        assert!(
            matches!(e, SceneError::Syntax { .. } | SceneError::Id { .. }),
            "{e:?}"
        );
    }
}

/// Empty groups are listed, not dropped (issue 15): a glTF node whose mesh
/// is points only and one whose triangle has zero area keep their places.
#[test]
fn nodes_of_empty_meshes_are_listed_and_never_visible() {
    let objects = crate::obj_load::four_objects();
    let meshes: Vec<Mesh> = objects
        .iter()
        .map(|(name, tris)| {
            let positions: Vec<[f32; 3]> = if tris.is_empty() {
                vec![[2.0, 2.0, 2.0]]
            } else {
                tris.iter().flatten().map(|v| v.to_array()).collect()
            };
            Mesh {
                name: Some(name),
                positions,
                indices: None,
                // The empty one: a point.
                mode: if tris.is_empty() { 0 } else { 4 },
            }
        })
        .collect();
    let nodes: Vec<Value> = objects
        .iter()
        .enumerate()
        .map(|(i, (name, _))| json!({"mesh": i, "name": name}))
        .collect();
    let (doc, bin) = document(&meshes, json!(nodes), json!([{"nodes": [0, 1, 2, 3]}]));
    let dir = tempfile::tempdir().unwrap();
    let model = write_embedded(&dir, "four.gltf", doc, &bin);
    crate::obj_load::empty_objects_are_listed_and_never_visible(&model);
}
