//! Sharded builds (issue 17): `vis5d build --top-levels K --shard I/N`
//! and `vis5d merge` give the very bytes of a single build, and parts of
//! other builds, missing, repeated or damaged parts are refused.

use std::path::{Path, PathBuf};

use crate::{committed, text, vis5d};

/// Builds `model` with `extra` flags to `out` (a `.v5d`, or a part with
/// `--shard`), failing the test on an error.
fn build(model: &Path, extra: &[&str], out: &Path) {
    let mut args = vec![
        "build",
        model.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = vis5d(&args);
    assert!(o.status.success(), "{args:?}: {}", text(&o.stderr));
}

/// The `n` parts of a build of `model` with `flags`, built into `dir`
/// (named after `stem`).
fn build_shards(model: &Path, flags: &[&str], n: u32, dir: &Path, stem: &str) -> Vec<PathBuf> {
    (0..n)
        .map(|i| {
            let part = dir.join(format!("{stem}.{i}of{n}.v5dpart"));
            let shard = format!("{i}/{n}");
            let mut args = flags.to_vec();
            args.extend(["--shard", &shard]);
            build(model, &args, &part);
            part
        })
        .collect()
}

/// `vis5d merge` of `parts` to `out`: its output.
fn merge(parts: &[PathBuf], out: &Path) -> std::process::Output {
    let mut args = vec!["merge".to_owned()];
    args.extend(parts.iter().map(|p| p.to_str().unwrap().to_owned()));
    args.extend(["-o".to_owned(), out.to_str().unwrap().to_owned()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    vis5d(&args)
}

#[test]
fn shards_merge_into_the_file_a_single_build_writes() {
    let dir = tempfile::tempdir().unwrap();
    for (name, levels) in [("apartment.obj", "3"), ("city.obj", "2")] {
        let model = committed(name);
        let whole = dir.path().join("whole.v5d");
        build(&model, &["--top-levels", levels], &whole);
        let want = std::fs::read(&whole).unwrap();
        for n in [1u32, 2, 3, 7] {
            let parts = build_shards(&model, &["--top-levels", levels], n, dir.path(), name);
            // In any order.
            let mut shuffled = parts.clone();
            shuffled.reverse();
            let merged = dir.path().join("merged.v5d");
            let o = merge(&shuffled, &merged);
            assert!(o.status.success(), "{}", text(&o.stderr));
            assert!(
                std::fs::read(&merged).unwrap() == want,
                "{name}, {n} shards: the merged file differs from the single build's"
            );
        }
    }
}

/// A scene of more objects than `--subtree-objects` fixes its top
/// itself: its plain build is the one with those levels given, and its
/// shards, given no levels, merge into it.
#[test]
fn a_scene_of_many_objects_shards_without_being_told() {
    let dir = tempfile::tempdir().unwrap();
    // The city's 211 objects, at most 60 a subtree: 2 levels.
    let model = committed("city.obj");
    let (told, plain) = (dir.path().join("told.v5d"), dir.path().join("plain.v5d"));
    build(&model, &["--top-levels", "2"], &told);
    build(&model, &["--subtree-objects", "60"], &plain);
    let want = std::fs::read(&told).unwrap();
    assert!(
        std::fs::read(&plain).unwrap() == want,
        "the top the scene fixes is not the one --top-levels 2 fixes"
    );
    let parts = build_shards(&model, &["--subtree-objects", "60"], 3, dir.path(), "city");
    let merged = dir.path().join("merged.v5d");
    let o = merge(&parts, &merged);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        std::fs::read(&merged).unwrap() == want,
        "the merged file differs"
    );
    // Fewer objects than that: one root, the bytes of a build without.
    let one = dir.path().join("one.v5d");
    build(&model, &["--subtree-objects", "211"], &one);
    let default = dir.path().join("default.v5d");
    build(&model, &[], &default);
    assert!(std::fs::read(&one).unwrap() == std::fs::read(&default).unwrap());
}

#[test]
fn merge_refuses_what_is_not_one_whole_build() {
    let dir = tempfile::tempdir().unwrap();
    let model = committed("apartment.obj");
    let part = |shard: &str, seed: &str| {
        let p = dir
            .path()
            .join(format!("{}-{seed}.v5dpart", shard.replace('/', "of")));
        build(
            &model,
            &[
                "--top-levels",
                "2",
                "--max-depth",
                "6",
                "--shard",
                shard,
                "--seed",
                seed,
            ],
            &p,
        );
        p
    };
    let (a, b, c) = (part("0/3", "1"), part("1/3", "1"), part("2/3", "1"));
    let out = dir.path().join("out.v5d");
    let refused = |parts: &[PathBuf], says: &str| {
        let o = merge(parts, &out);
        let err = text(&o.stderr);
        assert!(!o.status.success(), "{parts:?} merged");
        assert!(err.contains(says), "{parts:?}: {err}");
        assert!(!out.exists(), "a refused merge wrote {}", out.display());
    };
    refused(&[a.clone(), b.clone()], "shard 2 of 3 is missing");
    refused(
        &[a.clone(), a.clone(), b.clone(), c.clone()],
        "shard 0 is given twice",
    );
    // A shard of the same split but another seed: another build.
    let other = part("2/3", "9");
    refused(&[a.clone(), b.clone(), other], "parts of different builds");
    // Another split of the same build.
    let halves = part("1/2", "1");
    refused(&[a.clone(), halves], "parts of different builds");
    // A damaged part, and a .v5d given as a part.
    let mut bytes = std::fs::read(&c).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    let damaged = dir.path().join("damaged.v5dpart");
    std::fs::write(&damaged, &bytes).unwrap();
    refused(&[a.clone(), b.clone(), damaged.clone()], "damaged");
    std::fs::write(&damaged, &bytes[..100]).unwrap();
    refused(&[a.clone(), b.clone(), damaged], "damaged.v5dpart");
    let whole = dir.path().join("whole.v5d");
    build(&model, &["--top-levels", "2", "--max-depth", "6"], &whole);
    refused(
        &[a.clone(), b.clone(), whole],
        "not a part of a sharded build",
    );
    // Shards that do not exist are refused before any work.
    let o = vis5d(&[
        "build",
        model.to_str().unwrap(),
        "--shard",
        "3/3",
        "--dry-run",
    ]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("shards count from 0"));
    // All three, in order: merged.
    let o = merge(&[a, b, c], &out);
    assert!(o.status.success(), "{}", text(&o.stderr));
}

/// The checkpoints a folder holds.
fn checkpoints(dir: &Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    let name = p.file_name().unwrap().to_str().unwrap();
                    name.starts_with("subtree-") && name.ends_with(".v5d")
                })
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    out
}

/// `vis5d build --checkpoint`: a build killed (SIGKILL) after its first
/// subtree is saved leaves no output; run again, it takes the saved
/// subtrees and writes the bytes of an uninterrupted build. Damaged and
/// foreign checkpoints are refused.
#[test]
fn a_killed_build_resumes_from_its_checkpoints_to_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let model = committed("apartment.obj");
    let model_str = model.to_str().unwrap();
    let whole = dir.path().join("whole.v5d");
    let flags = ["--top-levels", "3", "--threads", "1"];
    build(&model, &flags, &whole);
    let want = std::fs::read(&whole).unwrap();

    let ck = dir.path().join("ck");
    let ck_str = ck.to_str().unwrap();
    let out = dir.path().join("out.v5d");
    let out_str = out.to_str().unwrap();
    let mut args = vec!["build", model_str, "-o", out_str, "--checkpoint", ck_str];
    args.extend_from_slice(&flags);
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vis5d"))
        .args(&args)
        .current_dir(crate::root())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    while checkpoints(&ck).is_empty() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the build ended before saving a checkpoint"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let saved = checkpoints(&ck).len();
    assert!((1..8).contains(&saved), "{saved} of 8 subtrees saved");
    assert!(!out.exists(), "a killed build left its output");

    let o = vis5d(&args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let said = text(&o.stderr);
    assert!(
        said.contains(&format!("resuming: {saved} subtrees")),
        "{said}"
    );
    assert!(
        std::fs::read(&out).unwrap() == want,
        "the resumed build differs from the uninterrupted one"
    );
    assert_eq!(checkpoints(&ck).len(), 8);

    // Another build's checkpoints (another seed) are refused.
    let mut other = args.clone();
    other.extend_from_slice(&["--seed", "2"]);
    let o = vis5d(&other);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("a checkpoint of another build"),
        "{}",
        text(&o.stderr)
    );
    // And a damaged one.
    let first = &checkpoints(&ck)[0];
    let mut bytes = std::fs::read(first).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x10;
    std::fs::write(first, &bytes).unwrap();
    let o = vis5d(&args);
    assert!(!o.status.success());
    let err = text(&o.stderr);
    assert!(
        err.contains("a damaged checkpoint") && err.contains("subtree-"),
        "{err}"
    );
}
