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
