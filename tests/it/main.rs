//! vis5d's integration tests: one binary, a module per capability.
//!
//! Scenes come from `scenes/` (committed, small) and, where present, from
//! `../shared/scenes/` (real scenes made by others; CI has them beside the
//! checkout). Every random generator is seeded.

mod bad_input;
mod build;
mod cli;
mod conservative;
mod flags;
mod gltf_load;
mod obj_load;
mod oracle;
mod procedural;
mod real_scenes;
mod report;
mod shard;
mod shrink;
mod slices;
mod sprt;
mod trace;
mod up_axis;
mod v5d;
mod view;

use std::path::{Path, PathBuf};

/// The project root.
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A committed scene of `scenes/`.
pub fn committed(name: &str) -> PathBuf {
    root().join("scenes").join(name)
}

/// The shared real-scene folder, `../shared/scenes`.
pub fn shared_scenes() -> PathBuf {
    root().join("..").join("shared").join("scenes")
}

/// Runs the `vis5d` binary in the project root.
pub fn vis5d(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_vis5d"))
        .args(args)
        .current_dir(root())
        .output()
        .unwrap()
}

/// Output bytes as text.
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Replays `tests/scene_corpus/KIND/`: each file is loaded as the fuzz
/// target loads it (from a folder that does not exist) and must load when
/// its name starts with "ok", be refused otherwise, and never panic.
pub fn replay_scene_corpus(kind: &str) {
    let dir = root().join("tests/scene_corpus").join(kind);
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let bytes = std::fs::read(&path).unwrap();
        let file = path.file_name().unwrap().to_string_lossy().into_owned();
        let name = std::path::Path::new("/nonexistent").join(&file);
        let loaded = vis5d::scene::load_bytes(&name, &bytes, &Default::default());
        if let Ok(scene) = &loaded {
            scene.validate().unwrap();
        }
        assert_eq!(
            loaded.is_ok(),
            file.starts_with("ok."),
            "{file}: {:?}",
            loaded.err()
        );
        n += 1;
    }
    assert!(n > 1, "no corpus in {}", dir.display());
}

/// Builds the committed machine's tree to `dir/m.v5d` with `--max-depth
/// depth` and returns its path.
pub fn machine_tree(dir: &Path, depth: u32) -> PathBuf {
    let v5d = dir.join("m.v5d");
    let depth = depth.to_string();
    let out = vis5d(&[
        "build",
        "scenes/machine.obj",
        "--max-depth",
        &depth,
        "-o",
        v5d.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    v5d
}

/// Builds a tree of `model` into `out` that drops visible objects: few
/// rays and quick verdicts (for tests that must see popping).
pub fn build_poor_tree(model: &str, out: &Path) {
    let out = vis5d(&[
        "build",
        model,
        "-o",
        out.to_str().unwrap(),
        "--reject",
        "0.95",
        "--max-rays",
        "8",
        "--s-thresh",
        "0.4",
        "--retest-rays",
        "0",
        "--edge-rays",
        "0",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
}

/// `vis5d ARGS` fails with exit status 2 and `message` on stderr.
pub fn assert_refused(args: &[&str], message: &str) {
    let out = vis5d(args);
    assert_eq!(out.status.code(), Some(2), "{args:?}");
    assert!(
        text(&out.stderr).contains(message),
        "{args:?}: {}",
        text(&out.stderr)
    );
}

/// Chromium's command, or `None` when it is not installed (the caller
/// skips its test), which fails when `VIS5D_REQUIRE_CHROMIUM` is set (CI
/// sets it).
pub fn chromium() -> Option<&'static str> {
    let found = ["chromium", "chromium-browser"].into_iter().find(|c| {
        std::process::Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    });
    if found.is_none() {
        assert!(
            std::env::var_os("VIS5D_REQUIRE_CHROMIUM").is_none(),
            "VIS5D_REQUIRE_CHROMIUM is set but chromium is not installed"
        );
        eprintln!("skipping: no chromium");
    }
    found
}
