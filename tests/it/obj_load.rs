//! OBJ loading through the public API: files on disk, error messages.

use std::io::Write;

use vis5d::scene::{self, SceneError};

fn write(dir: &tempfile::TempDir, name: &str, text: &[u8]) -> std::path::PathBuf {
    let path = dir.path().join(name);
    std::fs::File::create(&path)
        .unwrap()
        .write_all(text)
        .unwrap();
    path
}

#[test]
fn committed_scenes_load_and_validate() {
    for name in ["apartment", "office", "city", "forest", "machine"] {
        let s = scene::load(crate::committed(&format!("{name}.obj"))).unwrap();
        s.validate().unwrap();
        assert!(s.objects().len() > 50, "{name}");
        assert_eq!(s.report().dropped_degenerate, 0, "{name}");
        assert!(s.report().duplicate_names.is_empty(), "{name}");
    }
}

#[test]
fn missing_file_and_unknown_extension() {
    let e = scene::load("no/such/scene.obj").unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }));
    let msg = e.to_string();
    assert!(
        msg.starts_with("no/such/scene.obj: cannot read the scene file"),
        "{msg}"
    );

    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "scene.stl", b"solid x\n");
    let msg = scene::load(&p).unwrap_err().to_string();
    assert!(
        msg.contains("scene.stl: unknown scene format \"stl\""),
        "{msg}"
    );
    assert!(msg.contains(".obj, .gltf and .glb"), "{msg}");

    let p = write(&dir, "noext", b"v 0 0 0\n");
    let msg = scene::load(&p).unwrap_err().to_string();
    assert!(msg.contains("unknown scene format \"\""), "{msg}");
}

#[test]
fn extension_is_case_insensitive() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "UPPER.OBJ", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let s = scene::load(&p).unwrap();
    assert_eq!(s.objects()[0].name, "UPPER");
}

#[test]
fn garbage_is_an_error_not_a_panic() {
    // Binary noise, a truncated file, a file of only comments.
    let dir = tempfile::tempdir().unwrap();
    let noise: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    for (name, text) in [
        ("noise.obj", noise.as_slice()),
        ("cut.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2".as_slice()),
        ("comments.obj", b"# only\n# comments\n".as_slice()),
        ("empty.obj", b"".as_slice()),
    ] {
        let p = write(&dir, name, text);
        let msg = scene::load(&p).unwrap_err().to_string();
        assert!(msg.starts_with(&p.display().to_string()), "{name}: {msg}");
    }
}

/// One input per outcome of the OBJ fuzz target's corpus
/// (`fuzz/keep_outcomes.py`), each named after it: `ok.obj` loads, every
/// other is refused; none panics.
#[test]
fn fuzz_corpus_loads_or_is_refused_without_panicking() {
    crate::replay_scene_corpus("obj");
}

/// The four objects of the empty-group tests, as (name, triangles): a box
/// "a", "empty" (no triangles), "degenerate" (one triangle of zero area)
/// and a box "b" two units further along x.
pub(crate) fn four_objects() -> Vec<(&'static str, Vec<[glam::Vec3; 3]>)> {
    use glam::Vec3;
    use vis5d::scene::procedural::shapes::push_box;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    push_box(&mut a, Vec3::ZERO, Vec3::ONE);
    push_box(&mut b, Vec3::new(3.0, 0.0, 0.0), Vec3::new(4.0, 1.0, 1.0));
    let flat = [
        Vec3::new(2.0, 0.5, 0.5),
        Vec3::new(2.5, 0.5, 0.5),
        Vec3::new(2.2, 0.5, 0.5),
    ];
    vec![
        ("a", a),
        ("empty", vec![]),
        ("degenerate", vec![flat]),
        ("b", b),
    ]
}

/// [`four_objects`] as OBJ text: `o` groups, the empty one without faces.
fn four_objects_obj() -> String {
    let mut text = String::new();
    let mut base = 1;
    for (name, tris) in four_objects() {
        text += &format!("o {name}\n");
        for t in &tris {
            for v in t {
                text += &format!("v {} {} {}\n", v.x, v.y, v.z);
            }
            text += &format!("f {} {} {}\n", base, base + 1, base + 2);
            base += 3;
        }
    }
    text
}

/// A model of [`four_objects`] (OBJ or glTF) loads with the empty objects
/// in their places; they are never visible: not to either oracle, in no
/// set of a sampled or a conservative tree (flagged always visible or
/// not), in no query answer; the `.v5d` lists them (no triangles, no box)
/// and `vis5d check` finds no violation.
pub(crate) fn empty_objects_are_listed_and_never_visible(model: &std::path::Path) {
    use glam::Vec3;
    use serde_json::Value;
    use vis5d::geom::Aabb;
    use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
    use vis5d::shrink::{ShrinkOracle, ShrinkParams};
    let s = scene::load(model).unwrap();
    s.validate().unwrap();
    let listed: Vec<(&str, usize)> = s
        .objects()
        .iter()
        .map(|o| (o.name.as_str(), o.triangle_count()))
        .collect();
    assert_eq!(
        listed,
        [("a", 12), ("empty", 0), ("degenerate", 0), ("b", 12)]
    );
    assert_eq!(s.report().empty_objects, [1, 2]);
    assert!(s.objects()[1].is_empty() && s.objects()[2].is_empty());
    let seen = |set: &vis5d::bitset::ObjectSet| set.iter().collect::<Vec<_>>();
    // Both oracles, from between the boxes and from a cell that is not a
    // box (nothing proved).
    let between = Aabb::new(Vec3::new(1.5, 0.3, 0.3), Vec3::new(2.5, 0.7, 0.7));
    let not_a_box = Aabb::new(Vec3::NAN, Vec3::NAN);
    let oracle = Oracle::new(&s, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let shrink = ShrinkOracle::new(&s, ShrinkParams::default()).unwrap();
    for cell in [between, not_a_box] {
        assert_eq!(seen(&oracle.cell(&cell, None).visible), [0, 3], "extended");
        assert_eq!(seen(&shrink.cell(&cell).visible), [0, 3], "shrink");
    }
    let dir = tempfile::tempdir().unwrap();
    let p = |p: &std::path::Path| p.to_str().unwrap().to_owned();
    let v5d = dir.path().join("four.v5d");
    let flags = dir.path().join("flags.json");
    std::fs::write(&flags, r#"{"empty": ["always_visible"]}"#).unwrap();
    let always = vis5d::scene::ObjectFlags::ALWAYS_VISIBLE;
    let builds: [&[&str]; 3] = [
        &["--max-depth", "4"],
        &["--max-depth", "4", "--flags", &p(&flags), "--slices", "2"],
        &["--conservative", "--max-depth", "2", "--slices", "2"],
    ];
    for extra in builds {
        let (m, o) = (p(model), p(&v5d));
        let mut args = vec!["build", m.as_str(), "-o", o.as_str()];
        args.extend(extra);
        let out = crate::vis5d(&args);
        assert!(
            out.status.success(),
            "{extra:?}: {}",
            crate::text(&out.stderr)
        );
        let bytes = std::fs::read(&v5d).unwrap();
        let file = vis5d::codec::read_file(&bytes, Default::default()).unwrap();
        let table: Vec<(&str, u32, bool)> = file
            .objects
            .iter()
            .map(|o| (o.id.as_str(), o.triangles, o.bounds.is_some()))
            .collect();
        assert_eq!(
            table,
            [
                ("a", 12, true),
                ("empty", 0, false),
                ("degenerate", 0, false),
                ("b", 12, true)
            ],
            "{extra:?}"
        );
        assert_eq!(
            file.objects[1].flags.contains(always),
            extra.contains(&"--flags")
        );
        for node in file.tree.nodes() {
            assert!(!node.set.contains(1) && !node.set.contains(2), "{extra:?}");
        }
        assert!(file.tree.nodes()[0].set.contains(0) && file.tree.nodes()[0].set.contains(3));
        if let Some(slices) = &file.slices {
            assert!(slices.leaves.iter().flatten().all(|e| e.0 != 1 && e.0 != 2));
        }
        // Inside the view box and outside it (every object with
        // triangles in the frustum).
        for (pos, dir, want) in [
            ("2,0.5,0.5", "1,0,0", None),
            ("2,-3,0.5", "0,1,0", Some([0, 3])),
        ] {
            let out = crate::vis5d(&[
                "query", &o, "--pos", pos, "--dir", dir, "--fov", "120", "--json", "--ids",
            ]);
            assert!(out.status.success(), "{}", crate::text(&out.stderr));
            let rows: Value = serde_json::from_slice(&out.stdout).unwrap();
            let indices: Vec<u64> = rows
                .as_array()
                .unwrap()
                .iter()
                .map(|r| r["index"].as_u64().unwrap())
                .collect();
            assert!(
                !indices.contains(&1) && !indices.contains(&2),
                "{indices:?}"
            );
            if let Some(want) = want {
                assert_eq!(indices, want);
            }
        }
        let out = crate::vis5d(&["check", &m, &o, "--json"]);
        assert!(out.status.success(), "{}", crate::text(&out.stderr));
        let report: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(report["violations"], 0, "{extra:?}: {report}");
    }
}

/// Empty groups are listed, not dropped (issue 15): an OBJ group without
/// faces and one of zero-area faces only keep their places.
#[test]
fn empty_groups_are_listed_and_never_visible() {
    let dir = tempfile::tempdir().unwrap();
    let model = write(&dir, "four.obj", four_objects_obj().as_bytes());
    empty_objects_are_listed_and_never_visible(&model);
}
