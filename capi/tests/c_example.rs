//! `examples/c/query.c`, compiled with the system C compiler against
//! `include/vis5d.h` and libvis5d_c, runs on a `.v5d` file and answers as
//! the Rust API does.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::Vec3;
use vis5d::query::{Pvs, View};

mod common;

/// The folder cargo put libvis5d_c in (`target/<profile>`): two up from
/// this test's executable (`target/<profile>/deps/...`).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.parent().and_then(Path::parent).unwrap().to_owned()
}

#[test]
fn the_c_example_compiles_runs_and_agrees_with_rust() {
    let dir = tempfile::tempdir().unwrap();
    // A small tree of the procedural apartment.
    let bytes = common::small_file(8);
    let file = dir.path().join("apartment.v5d");
    std::fs::write(&file, &bytes).unwrap();

    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let lib = library_dir();
    // `cargo test` builds the crate as an rlib only: build the shared
    // library (the same profile and target folder; cargo has released
    // its lock while the tests run).
    let release = lib.file_name().is_some_and(|n| n == "release");
    let mut cargo = Command::new(env!("CARGO"));
    cargo
        .current_dir(&root)
        .args(["build", "-p", "vis5d-capi", "--lib"])
        .env("CARGO_TARGET_DIR", lib.parent().unwrap());
    if release {
        cargo.arg("--release");
    }
    let status = cargo.status().expect("cargo runs");
    assert!(status.success(), "cargo build -p vis5d-capi failed");
    assert!(
        lib.join("libvis5d_c.so").exists() || lib.join("libvis5d_c.dylib").exists(),
        "no libvis5d_c in {}",
        lib.display()
    );
    let exe = dir.path().join("query");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let built = Command::new(&cc)
        .args(["-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(root.join("include"))
        .arg(root.join("examples/c/query.c"))
        .arg("-L")
        .arg(&lib)
        .args(["-lvis5d_c", "-lm"])
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("cannot run the C compiler {cc}: {e}"));
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    let run = Command::new(&exe).arg(&file).output().unwrap();
    let out = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // The first camera: from the middle of the view box along +x (the
    // apartment is Z-up), 60 degrees vertical, 16:9; its answer listed.
    let pvs = Pvs::from_bytes(&bytes).unwrap();
    let b = pvs.view_box();
    let eye = ((b.min.as_dvec3() + b.max.as_dvec3()) * 0.5).as_vec3();
    let view = View::look(eye, Vec3::X, Vec3::Z, 60f32.to_radians(), 16.0 / 9.0);
    let mut set = pvs.new_set();
    pvs.query_view_world(eye.as_dvec3(), &view, &mut set)
        .unwrap();
    let line = format!("camera 0 looking (1, 0, 0): {} objects", set.count());
    assert!(out.contains(&line), "{line} not in:\n{out}");
    for o in set.iter() {
        assert!(
            out.contains(&format!("\n  {}\n", pvs.object(o).unwrap().name())),
            "{out}"
        );
    }
    assert!(
        out.contains(&format!("{} objects, view box", pvs.object_count())),
        "{out}"
    );
    assert!(
        out.contains("a bitset of") && out.contains("refused"),
        "{out}"
    );
    // A missing file: exit 1 and the reason.
    let missing = Command::new(&exe)
        .arg(dir.path().join("missing.v5d"))
        .output()
        .unwrap();
    assert_eq!(missing.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("cannot read"));
}
