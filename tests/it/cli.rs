//! The `vis5d` binary: help, `info`, `scene`, and its error messages.

use crate::{text, vis5d};

#[test]
fn help_explains_the_commands() {
    let out = vis5d(&["--help"]);
    assert!(out.status.success());
    let help = text(&out.stdout);
    for word in ["info", "scene", "visibility"] {
        assert!(help.contains(word), "{help}");
    }
    let out = vis5d(&["scene", "--help"]);
    let help = text(&out.stdout);
    for word in [
        "apartment",
        "office",
        "city",
        "forest",
        "machine",
        "--replicate",
        "--seed",
    ] {
        assert!(help.contains(word), "{help}");
    }
}

#[test]
fn info_json_matches_the_library() {
    let out = vis5d(&["info", "scenes/apartment.obj", "--json"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let s = vis5d::scene::load(crate::committed("apartment.obj")).unwrap();
    assert_eq!(v["objects"], s.objects().len());
    assert_eq!(v["triangles"], s.triangles().len());
    assert_eq!(v["format"], "obj");
    assert_eq!(
        v["object_list"].as_array().unwrap().len(),
        s.objects().len()
    );
    assert_eq!(v["object_list"][0]["name"], s.objects()[0].name.as_str());
    assert_eq!(v["dropped_degenerate_triangles"], 0);
}

#[test]
fn info_text_reports_drops_empty_objects_and_duplicates() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("dups.obj");
    std::fs::write(
        &p,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\no a\nf 1 2 3\no a\nf 1 2 3\no b\nf 1 2 2\n",
    )
    .unwrap();
    let out = vis5d(&["info", p.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let t = text(&out.stdout);
    assert!(t.contains("objects          3"), "{t}");
    assert!(t.contains("dropped          1 zero-area triangles"), "{t}");
    assert!(
        t.contains("empty objects    1 without a triangle of non-zero area (listed, never visible): #2 \"b\""),
        "{t}"
    );
    assert!(t.contains("\"a\" x2"), "{t}");
    let out = vis5d(&["info", p.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["empty_objects"], serde_json::json!([2]));
    assert_eq!(v["object_list"][2]["triangles"], 0);
    assert_eq!(v["object_list"][2]["bounds"], serde_json::Value::Null);
}

#[test]
fn errors_name_the_file_and_fail() {
    for (args, want) in [
        (
            vec!["info", "nope.obj"],
            "error: nope.obj: cannot read the scene file",
        ),
        (
            vec!["info", "Cargo.toml"],
            "error: Cargo.toml: unknown scene format \"toml\"",
        ),
        (
            vec!["scene", "castle", "-o", "x.obj"],
            "unknown scene kind \"castle\"",
        ),
        (
            vec!["scene", "city", "-o", "x.txt"],
            "x.txt: the output must be an .obj file",
        ),
        (
            vec!["scene", "city", "-o", "no/such/dir/x.obj"],
            "no/such/dir/x.obj: cannot write the scene",
        ),
    ] {
        let out = vis5d(&args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: usage and runtime errors exit with 2"
        );
        let err = text(&out.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn scene_writes_the_committed_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.obj");
    let out = vis5d(&[
        "scene",
        "apartment",
        "--seed",
        "1",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        std::fs::read(&p).unwrap(),
        std::fs::read(crate::committed("apartment.obj")).unwrap()
    );
    // Nothing but the output is left in the folder (no temporary file).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn build_reports_and_dry_runs() {
    let out = vis5d(&[
        "build",
        "scenes/machine.obj",
        "--json",
        "--max-depth",
        "6",
        "--verify-views",
        "5",
        "--dry-run",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["objects"], 146);
    assert!(v["leaves"].as_u64().unwrap() > 1);
    assert!(v["depth"].as_u64().unwrap() <= 6);
    assert!(v["rays_cast"].as_u64().unwrap() > 0);
    assert!(v["decisions"]["proven_by_hit"].as_u64().unwrap() > 0);
    assert!(v["pixel_error"]["hit_pixels"].as_u64().unwrap() > 0);
    assert_eq!(v["written"], serde_json::Value::Null);
    let out = vis5d(&[
        "build",
        "scenes/machine.obj",
        "--max-depth",
        "4",
        "--dry-run",
    ]);
    assert!(out.status.success());
    let t = text(&out.stdout);
    for want in [
        "leaves",
        "proven by a hit",
        "invisible by SPRT",
        "tracing",
        "nothing written",
    ] {
        assert!(t.contains(want), "{t}");
    }
}

#[test]
fn build_refuses_bad_flags() {
    for (args, want) in [
        (
            vec!["build", "scenes/machine.obj", "--angular-leaves", "3"],
            "power of two",
        ),
        (
            vec!["build", "scenes/machine.obj", "--view-box", "0,0,0,1,1"],
            "expected 6 numbers",
        ),
        (
            vec!["build", "scenes/machine.obj", "--view-box", "1,1,1,0,0,0"],
            "x0 < x1",
        ),
        (
            vec!["build", "scenes/machine.obj", "--prior", "1"],
            "two numbers",
        ),
        (
            vec!["build", "scenes/machine.obj", "--s-thresh", "0.0001"],
            "before any ray hits",
        ),
        (vec!["build", "missing.obj"], "missing.obj: cannot read"),
    ] {
        let out = vis5d(&args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: usage and runtime errors exit with 2"
        );
        let err = text(&out.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn build_writes_next_to_the_model_and_stat_and_query_read_it() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("machine.obj");
    std::fs::copy(crate::committed("machine.obj"), &model).unwrap();
    let out = vis5d(&[
        "build",
        model.to_str().unwrap(),
        "--max-depth",
        "8",
        "--coding",
        "leaf",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v5d = dir.path().join("machine.v5d");
    assert!(text(&out.stdout).contains("wrote"), "{}", text(&out.stdout));
    assert!(v5d.exists());

    let out = vis5d(&["stat", v5d.to_str().unwrap(), "--json"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let s: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(s["coding"], "leaf");
    assert_eq!(s["objects"], 146);
    assert_eq!(s["coding_sizes"].as_array().unwrap().len(), 3);
    assert_eq!(
        s["file_bytes"].as_u64().unwrap(),
        std::fs::metadata(&v5d).unwrap().len()
    );
    let out = vis5d(&["stat", v5d.to_str().unwrap()]);
    assert!(
        text(&out.stdout).contains("sibling"),
        "{}",
        text(&out.stdout)
    );

    // One view: the outside of the casing, looking at its front.
    let q = [
        "query",
        v5d.to_str().unwrap(),
        "--pos",
        "0.6,0.01,0.45",
        "--dir",
        "0,1,0",
    ];
    let out = vis5d(&[&q[..], &["--json"]].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let names: Vec<String> = serde_json::from_slice(&out.stdout).unwrap();
    assert!(names.iter().any(|n| n == "casing/front"), "{names:?}");
    let out = vis5d(&q);
    assert_eq!(text(&out.stdout).lines().count(), names.len());
    // With the right scene, and with another one.
    let out = vis5d(&[&q[..], &["--scene", model.to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = vis5d(&[&q[..], &["--scene", "scenes/city.obj"]].concat());
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("another version of the scene"),
        "{}",
        text(&out.stderr)
    );
    // Many views at once.
    let views = dir.path().join("views.json");
    std::fs::write(
        &views,
        r#"[{"pos": [0.6, 0.01, 0.45], "dir": [0, 1, 0]}, {"pos": [0.6, 0.35, 0.45], "dir": [0, 0, 1], "fov": 60}]"#,
    )
    .unwrap();
    let out = vis5d(&[
        "query",
        v5d.to_str().unwrap(),
        "--views",
        views.to_str().unwrap(),
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let all: Vec<Vec<String>> = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(all.len(), 2);
    assert_eq!(all[0], names);
    // A box of positions sees at least what its centre sees.
    let out = vis5d(&[
        "query",
        v5d.to_str().unwrap(),
        "--box",
        "0.5,0.005,0.4,0.7,0.015,0.5",
        "--dir",
        "0,1,0",
        "--json",
    ]);
    let boxed: Vec<String> = serde_json::from_slice(&out.stdout).unwrap();
    assert!(names.iter().all(|n| boxed.contains(n)), "{boxed:?}");
}

#[test]
fn query_and_stat_refuse_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("junk.v5d");
    std::fs::write(&junk, b"definitely not a tree").unwrap();
    let views = dir.path().join("views.json");
    std::fs::write(&views, r#"[{"pos": [0, 0], "dir": [1, 0, 0]}]"#).unwrap();
    let j = junk.to_str().unwrap();
    for (args, want) in [
        (vec!["stat", j], "junk.v5d: not a .v5d file"),
        (
            vec!["query", j, "--pos", "0,0,0", "--dir", "1,0,0"],
            "junk.v5d: not a .v5d file",
        ),
        (vec!["stat", "nope.v5d"], "nope.v5d: cannot read"),
        (
            vec!["query", "nope.v5d", "--pos", "0,0"],
            "expected 3 numbers",
        ),
        (vec!["query", "nope.v5d", "--pos", "0,0,0"], "--dir"),
    ] {
        let out = vis5d(&args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: usage and runtime errors exit with 2"
        );
        assert!(
            text(&out.stderr).contains(want),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
    // A good file with bad views.
    let model = dir.path().join("m.obj");
    std::fs::copy(crate::committed("machine.obj"), &model).unwrap();
    assert!(
        vis5d(&["build", model.to_str().unwrap(), "--max-depth", "3"])
            .status
            .success()
    );
    let v5d = dir.path().join("m.v5d");
    let out = vis5d(&[
        "query",
        v5d.to_str().unwrap(),
        "--views",
        views.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("views.json"),
        "{}",
        text(&out.stderr)
    );
}

/// Stable ids (issue 15): repeated names get their occurrence, `--ids`
/// replaces default ids by the engine's, `query --ids` and
/// `Pvs::object_index` use them, and bad id files are refused by name.
#[test]
fn objects_have_stable_ids() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("crates.obj");
    let mut obj = String::new();
    let mut v = 0;
    for (name, x) in [
        ("floor", 0.0),
        ("crate", 2.0),
        ("crate", 4.0),
        ("lamp", 6.0),
    ] {
        obj.push_str(&format!("o {name}\n"));
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            obj.push_str(&format!("v {} {} 0\n", x + dx, dy));
        }
        obj.push_str(&format!(
            "f {} {} {}\nf {} {} {}\n",
            v + 1,
            v + 2,
            v + 3,
            v + 1,
            v + 3,
            v + 4
        ));
        v += 4;
    }
    std::fs::write(&model, obj).unwrap();
    let ids = dir.path().join("ids.json");
    std::fs::write(&ids, r#"{"crate#2": "crate-blue", "lamp": "L-17"}"#).unwrap();
    let out = dir.path().join("crates.v5d");
    let (m, o, i) = (
        model.to_str().unwrap(),
        out.to_str().unwrap(),
        ids.to_str().unwrap(),
    );
    let built = vis5d(&["build", m, "-o", o, "--ids", i, "--max-depth", "4"]);
    assert!(built.status.success(), "{}", text(&built.stderr));
    let pvs = vis5d::query::Pvs::load(&out).unwrap();
    let got: Vec<&str> = pvs.objects().map(|o| o.id()).collect();
    assert_eq!(got, ["floor", "crate#1", "crate-blue", "L-17"]);
    assert_eq!(pvs.object_index("crate-blue"), Some(2));
    assert_eq!(pvs.object_index("crate#2"), None);
    // From above, looking down: every object.
    let args = [
        "query",
        o,
        "--pos",
        "3.5,0.5,5",
        "--dir",
        "0,0,-1",
        "--fov",
        "150",
    ];
    let q = vis5d(&[&args[..], &["--json", "--ids"]].concat());
    assert!(q.status.success(), "{}", text(&q.stderr));
    let rows: serde_json::Value = serde_json::from_slice(&q.stdout).unwrap();
    assert_eq!(rows[2]["id"], "crate-blue");
    assert_eq!(rows[2]["name"], "crate");
    assert_eq!(rows[2]["index"], 2);
    // Plain --json keeps its list of names.
    let q = vis5d(&[&args[..], &["--json"]].concat());
    let names: Vec<String> = serde_json::from_slice(&q.stdout).unwrap();
    assert_eq!(names, ["floor", "crate", "crate", "lamp"]);
    // Without --ids, the defaults.
    let plain = dir.path().join("plain.v5d");
    let built = vis5d(&[
        "build",
        m,
        "-o",
        plain.to_str().unwrap(),
        "--max-depth",
        "4",
    ]);
    assert!(built.status.success(), "{}", text(&built.stderr));
    let pvs = vis5d::query::Pvs::load(&plain).unwrap();
    let got: Vec<&str> = pvs.objects().map(|o| o.id()).collect();
    assert_eq!(got, ["floor", "crate#1", "crate#2", "lamp"]);
    // Bad id files: refused before the build, naming the file.
    for (content, says) in [
        (r#"{"crate": "x"}"#, "no object has the id"),
        (r#"{"floor": "crate#1"}"#, "two objects would have the id"),
        (r#"{"floor": ""}"#, "empty"),
        (r#"["floor"]"#, "expected a JSON object"),
    ] {
        std::fs::write(&ids, content).unwrap();
        let bad = vis5d(&["build", m, "-o", o, "--ids", i, "--max-depth", "4"]);
        let err = text(&bad.stderr);
        assert!(
            !bad.status.success() && err.contains(says) && err.contains("ids.json"),
            "{content}: {err}"
        );
    }
}
