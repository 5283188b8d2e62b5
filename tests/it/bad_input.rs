//! Bad and unusual input (issue 11): each test is named after the defect
//! it keeps fixed.

#[cfg(unix)]
use std::os::unix::fs::FileTypeExt;
use std::path::Path;

use crate::{text, vis5d};

/// Asserts that a run was refused as a usage or runtime error (exit 2,
/// no panic) with a message holding `want`.
fn refused(out: &std::process::Output, want: &str) {
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(want), "{want:?} not in {err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// Writes `obj` to `dir/name` and returns the path as a string.
fn write(dir: &Path, name: &str, contents: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path.to_str().unwrap().to_owned()
}

/// A scene in one plane (one triangle, a floor plan, a terrain of one
/// height) used to end in "the coded tree does not decode: the root cell
/// is not a box" after the whole build: the view box now gets a
/// thickness, and the tree is built, written, read back and queried.
#[test]
fn a_flat_scene_builds_a_tree_that_decodes() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = [
        (
            "triangle.obj",
            "o tri\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_owned(),
        ),
        (
            "plan.obj",
            "o a\nv 0 0 0\nv 4 0 0\nv 4 3 0\nv 0 3 0\nf 1 2 3 4\n\
             o b\nv 5 0 0\nv 9 0 0\nv 9 3 0\nv 5 3 0\nf 5 6 7 8\n"
                .to_owned(),
        ),
        (
            // A vertical wall: flat in y, far from the origin.
            "wall.obj",
            "o w\nv 500000 4000000 10\nv 500010 4000000 10\nv 500010 4000000 13\nf 1 2 3\n"
                .to_owned(),
        ),
    ];
    for (name, obj) in scenes {
        let model = write(dir.path(), name, &obj);
        let v5d = dir.path().join(name).with_extension("v5d");
        let out = vis5d(&["build", &model, "--max-depth", "4", "--json"]);
        assert!(out.status.success(), "{name}: {}", text(&out.stderr));
        let stat = vis5d(&["stat", v5d.to_str().unwrap()]);
        assert!(stat.status.success(), "{name}: {}", text(&stat.stderr));
        let pos = if name == "wall.obj" {
            "500005,4000000,11"
        } else {
            "0.2,0.2,0"
        };
        let dir_arg = if name == "wall.obj" {
            "0,1,0"
        } else {
            "0,0,-1"
        };
        let q = vis5d(&[
            "query",
            v5d.to_str().unwrap(),
            "--pos",
            pos,
            "--dir",
            dir_arg,
        ]);
        assert!(q.status.success(), "{name}: {}", text(&q.stderr));
        assert!(!text(&q.stdout).trim().is_empty(), "{name}: sees nothing");
    }
}

/// `vis5d build model.obj -o model.obj` overwrote the model with the tree,
/// also through another spelling of the same path; now refused before any
/// work, and the model is left as it was.
#[test]
fn build_refuses_to_write_over_its_model() {
    let dir = tempfile::tempdir().unwrap();
    let obj = std::fs::read_to_string(crate::committed("machine.obj")).unwrap();
    let model = write(dir.path(), "model.obj", &obj);
    std::fs::create_dir(dir.path().join("x")).unwrap();
    let other = dir.path().join("x/../model.obj");
    for output in [model.clone(), other.to_str().unwrap().to_owned()] {
        let out = vis5d(&["build", &model, "-o", &output, "--max-depth", "3"]);
        assert_eq!(out.status.code(), Some(2), "{output}");
        assert!(
            text(&out.stderr).contains("refusing to write the tree over the input"),
            "{}",
            text(&out.stderr)
        );
        assert_eq!(std::fs::read_to_string(&model).unwrap(), obj);
    }
}

/// `report -o DIR` where DIR holds one of the report's inputs under one of
/// the names it writes: refused before any work.
#[test]
fn report_refuses_to_write_over_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let views = write(
        dir.path(),
        "report.json",
        r#"[{"pos": [0.5, 0.4, 0.3], "dir": [1, 0, 0]}]"#,
    );
    let out = vis5d(&[
        "report",
        "scenes/machine.obj",
        "-o",
        dir.path().to_str().unwrap(),
        "--views",
        &views,
        "--no-oracle",
    ]);
    refused(&out, "refusing to write the report over the input");
    assert!(std::fs::read_to_string(&views).unwrap().contains("pos"));
}

/// `-o` onto a device node replaced the node with a plain file.
#[test]
#[cfg(unix)]
fn outputs_onto_special_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.obj");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo");
    let fifo = fifo.to_str().unwrap();
    for args in [
        vec!["build", "scenes/machine.obj", "-o", "/dev/null"],
        vec!["scene", "city", "-o", fifo],
    ] {
        let out = vis5d(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = text(&out.stderr);
        assert!(err.contains("not a regular file"), "{args:?}: {err}");
    }
    assert!(
        std::fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device()
    );
    assert!(std::fs::metadata(fifo).unwrap().file_type().is_fifo());
}

/// A FIFO given as the scene, the `.v5d` or the views file blocked for
/// ever, and `/dev/zero` filled memory: only regular files are read.
#[test]
#[cfg(unix)]
fn special_files_as_inputs_are_refused_not_waited_on() {
    let dir = tempfile::tempdir().unwrap();
    let mk = |name: &str| {
        let p = dir.path().join(name);
        let made = std::process::Command::new("mkfifo").arg(&p).status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        p.to_str().unwrap().to_owned()
    };
    let (obj, v5d, views) = (mk("scene.obj"), mk("tree.v5d"), mk("views.json"));
    let zero = dir.path().join("zero.obj");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let zero = zero.to_str().unwrap();
    let good = crate::machine_tree(dir.path(), 2);
    let good = good.to_str().unwrap();
    for args in [
        vec!["info", &obj],
        vec!["info", zero],
        vec!["build", zero, "--dry-run"],
        vec!["stat", &v5d],
        vec!["query", &v5d, "--pos", "0,0,0", "--dir", "1,0,0"],
        vec!["query", good, "--views", &views],
        vec!["report", "scenes/machine.obj", "-o", "r", "--views", &views],
    ] {
        let out = vis5d(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(
            text(&out.stderr).contains("not a regular file"),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
}

/// Coordinates of 1e30 or 3e38 panicked inside obvhs's BVH build, and
/// scenes far outside f32's comfortable range gave silently wrong sets:
/// such scenes are refused with a message when loaded.
#[test]
fn scenes_whose_size_f32_cannot_resolve_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let tri = |c: &str| {
        format!(
            "o a\nv 0 0 0\nv {c} 0 0\nv 0 {c} 0\nf 1 2 3\no b\nv 0 0 {c}\nv {c} 0 {c}\nv 0 {c} {c}\nf 4 5 6\n"
        )
    };
    for c in ["1e30", "3e38", "1e16", "1e-12"] {
        let model = write(dir.path(), &format!("s{c}.obj"), &tri(c));
        for cmd in ["info", "build"] {
            let out = vis5d(&[cmd, &model]);
            assert_eq!(out.status.code(), Some(2), "{cmd} {c}");
            let err = text(&out.stderr);
            assert!(err.contains("rescale the model"), "{cmd} {c}: {err}");
            assert!(!err.contains("panicked"), "{cmd} {c}: {err}");
        }
    }
    // Within the range: a kilometre-wide and a millimetre-wide scene.
    for c in ["1000", "0.001"] {
        let model = write(dir.path(), &format!("s{c}.obj"), &tri(c));
        let out = vis5d(&["build", &model, "--dry-run", "--max-depth", "3"]);
        assert!(out.status.success(), "{c}: {}", text(&out.stderr));
    }
}

/// A scene far from the origin (a georeferenced model in UTM coordinates)
/// built a hundred times slower than at the origin, because the tracer's
/// margins grew with the largest coordinate, and was resolved in f32 steps
/// of its world coordinates. It is now held in a local frame whose origin
/// the `.v5d` keeps: built as at the origin, queried in world coordinates.
#[test]
fn scenes_far_from_the_origin_build_as_they_do_at_the_origin() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let (near, far) = (path("near.obj"), path("far.obj"));
    let offset = [500_123.7, 4_649_876.3, 250.0];
    let offset_flag = format!("{},{},{}", offset[0], offset[1], offset[2]);
    assert!(vis5d(&["scene", "apartment", "-o", &near]).status.success());
    let out = vis5d(&["scene", "apartment", "--offset", &offset_flag, "-o", &far]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let build = |model: &str| {
        let out = vis5d(&[
            "build",
            model,
            "--max-depth",
            "5",
            "--verify-views",
            "10",
            "--json",
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let (n, f) = (build(&near), build(&far));
    assert!(n.get("frame_origin").is_none(), "{n}");
    let origin = f["frame_origin"]
        .as_array()
        .expect("a far scene has a frame");
    for (o, want) in origin.iter().zip(offset) {
        assert!((o.as_f64().unwrap() - want).abs() < 20.0, "{origin:?}");
    }
    // The same work and the same accuracy against rays as at the origin.
    let rays = |j: &serde_json::Value| j["rays_cast"].as_f64().unwrap();
    assert!(
        (rays(&f) / rays(&n) - 1.0).abs() < 0.1,
        "{} vs {}",
        rays(&f),
        rays(&n)
    );
    let error = |j: &serde_json::Value| j["pixel_error"]["fraction"].as_f64().unwrap();
    assert!(
        error(&f) <= 2.0 * error(&n) + 1e-4,
        "{} vs {}",
        error(&f),
        error(&n)
    );
    // Queried in world coordinates, the far tree answers what the near one
    // answers at the same place in the room.
    let query = |v5d: &str, model: &str, pos: [f64; 3]| {
        let pos = format!("{},{},{}", pos[0], pos[1], pos[2]);
        let out = vis5d(&[
            "query", v5d, "--pos", &pos, "--dir", "1,0.3,0", "--scene", model, "--json",
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        serde_json::from_slice::<Vec<String>>(&out.stdout).unwrap()
    };
    let eye = [2.0, 2.0, 1.5];
    let a = query(&path("near.v5d"), &near, eye);
    let b = query(
        &path("far.v5d"),
        &far,
        [0, 1, 2].map(|k| eye[k] + offset[k]),
    );
    let common = a.iter().filter(|x| b.contains(x)).count();
    // Positions outside the view box get every object: both eyes are in.
    assert!(
        a.len() < 174 && b.len() < 174,
        "{} and {} of 174",
        a.len(),
        b.len()
    );
    assert!(
        common as f64 >= 0.8 * a.len().max(b.len()) as f64,
        "near {a:?}\nfar {b:?}"
    );
    // The tree knows where its scene is: the near model is not its scene.
    let out = vis5d(&[
        "query",
        &path("far.v5d"),
        "--pos",
        "0,0,0",
        "--dir",
        "1,0,0",
        "--scene",
        &near,
    ]);
    refused(&out, "another");
}

/// Flags that asked for more than the machine has aborted on a failed
/// allocation (86 GB of cached rays, 45 GB of pixels), ran for ever, or
/// panicked; every numeric flag now has a range, and work whose size is
/// known is checked against the memory budget first.
#[test]
fn flags_that_would_exhaust_the_machine_are_refused() {
    let m = "scenes/machine.obj";
    for (args, want) in [
        (
            vec!["build", m, "--cache-rays", "4294967295"],
            "--cache-rays",
        ),
        (
            vec!["build", m, "--verify-resolution", "100000"],
            "--verify-resolution",
        ),
        (
            vec!["build", m, "--angular-leaves", "1048576"],
            "--angular-leaves",
        ),
        (
            vec!["build", m, "--verify-views", "4294967295"],
            "--verify-views",
        ),
        (vec!["build", m, "--grow", "1e38", "--dry-run"], "--grow"),
        (
            vec!["build", m, "--min-cell", "1e-30", "--dry-run"],
            "--min-cell",
        ),
        (vec!["build", m, "--max-rays", "0"], "--max-rays"),
        (
            vec!["check", m, "x.v5d", "--truth-rays", "4294967295"],
            "--truth-rays",
        ),
        (
            vec!["report", m, "-o", "r", "--random", "1000000000"],
            "--random",
        ),
        (
            vec!["report", m, "-o", "r", "--random", "18446744073709551615"],
            "--random",
        ),
        (
            vec!["scene", "forest", "--replicate", "100000", "-o", "f.obj"],
            "--replicate",
        ),
        // Known sizes against a memory budget.
        (
            vec![
                "build",
                m,
                "--dry-run",
                "--verify-views",
                "1",
                "--verify-resolution",
                "8192",
                "--max-memory",
                "100M",
            ],
            "would need about 3.0 GiB",
        ),
        (
            vec![
                "scene",
                "forest",
                "--replicate",
                "5000",
                "-o",
                "f.obj",
                "--max-memory",
                "1G",
            ],
            "--replicate would need",
        ),
        (
            vec![
                "report",
                m,
                "-o",
                "r",
                "--resolution",
                "8192",
                "--max-memory",
                "1G",
            ],
            "--resolution and --pictures would need",
        ),
        (
            vec!["info", m, "--max-memory", "64K"],
            "loading scenes/machine.obj would need",
        ),
    ] {
        let out = vis5d(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = text(&out.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // A tree that would never end is cut off by the node budget.
    let out = vis5d(&[
        "build",
        m,
        "--dry-run",
        "--max-depth",
        "64",
        "--split-threshold",
        "0",
        "--min-cell",
        "1e-6",
        "--min-angle",
        "1e-6",
        "--max-nodes",
        "3000",
    ]);
    refused(&out, "more than 3000 nodes");
    // Negative values parse without `=` (and are then refused or used).
    let out = vis5d(&[
        "build",
        m,
        "--dry-run",
        "--view-box",
        "-1,-1,-1,1,1,1",
        "--max-depth",
        "2",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = vis5d(&[
        "query", "x.v5d", "--pos", "0,0,0", "--dir", "1,0,0", "--fov", "-1",
    ]);
    assert!(text(&out.stderr).contains("--fov"), "{}", text(&out.stderr));
}

/// Object names with a newline or a terminal escape were printed raw,
/// forging lines of output or driving the terminal: text output escapes
/// control characters (JSON escapes them on its own).
#[test]
fn names_with_control_characters_are_printed_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let model = write(
        dir.path(),
        "evil.obj",
        "o red\u{1b}[31mwall\nv 0 0 0\nv 4 0 0\nv 4 0 3\nv 0 0 3\nf 1 2 3 4\n\
         o floor\nv 0 -2 0\nv 4 -2 0\nv 4 2 0\nf 5 6 7\n",
    );
    assert!(
        vis5d(&["build", &model, "--max-depth", "3"])
            .status
            .success()
    );
    let v5d = dir.path().join("evil.v5d");
    let query = |extra: &[&str]| {
        let mut args = vec![
            "query",
            v5d.to_str().unwrap(),
            "--pos",
            "2,-1,1",
            "--dir",
            "0,1,0",
        ];
        args.extend_from_slice(extra);
        vis5d(&args)
    };
    let stdout = text(&query(&[]).stdout);
    assert!(stdout.contains("red\\u{1b}[31mwall"), "{stdout:?}");
    assert!(!stdout.contains('\u{1b}'), "{stdout:?}");
    let names: Vec<String> = serde_json::from_slice(&query(&["--json"]).stdout).unwrap();
    assert!(names.iter().any(|n| n == "red\u{1b}[31mwall"), "{names:?}");
}

/// With `--json` a closed pipe (`vis5d ... | head`) was an error while
/// text mode exited 0; both exit 0 now. An unwritable stderr panicked.
#[test]
#[cfg(unix)]
fn a_closed_stdout_is_success_and_a_closed_stderr_no_panic() {
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let v5d = crate::machine_tree(dir.path(), 4);
    // Enough views that the answers overflow any pipe buffer.
    let one = r#"{"pos": [0.5, 0.4, 0.3], "dir": [1, 0.2, 0.1], "fov": 120}"#;
    let views = dir.path().join("views.json");
    std::fs::write(&views, format!("[{}]", vec![one; 20_000].join(","))).unwrap();
    for json in [false, true] {
        let mut args = vec![
            "query",
            v5d.to_str().unwrap(),
            "--views",
            views.to_str().unwrap(),
        ];
        if json {
            args.push("--json");
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_vis5d"))
            .args(&args)
            .current_dir(crate::root())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take()); // the reader goes away at once
        let out = child.wait_with_output().unwrap();
        assert_eq!(
            out.status.code(),
            Some(0),
            "json {json}: {}",
            text(&out.stderr)
        );
    }
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "{} info nope.obj 2>&-",
            env!("CARGO_BIN_EXE_vis5d")
        ))
        .current_dir(crate::root())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "no panic (101)");
}

/// Any scene the loaders accept builds a tree that writes, decodes to the
/// same tree and answers queries: random small scenes of every shape
/// (flat, a single sliver, tiny, huge, far from the origin, with
/// degenerate and duplicate triangles), written as OBJ and loaded back.
#[test]
fn any_accepted_scene_builds_a_tree_that_decodes() {
    use glam::Vec3;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;
    use vis5d::builder::{BuildParams, build, to_file};
    use vis5d::codec::{ReadLimits, read_file, write_file};
    use vis5d::query::{Pvs, View};
    use vis5d::random::{uniform_direction, uniform_point};
    use vis5d::trace::Tracer;

    let mut rng = Pcg64::seed_from_u64(2026);
    let (mut accepted, mut refused, mut splits) = (0, 0, 0);
    for case in 0..60 {
        let scale = [1e-9f32, 1e-3, 1.0, 1e3, 1e9, 1e13][case % 6];
        let offset = [0.0f32, 1e3, -1e5, 1e6][case / 6 % 4] * scale.min(1.0);
        let flat = case % 5 == 0;
        let b = vis5d::geom::Aabb::new(Vec3::splat(offset), Vec3::splat(offset + scale));
        let mut obj = String::new();
        let mut v = 0;
        for o in 0..rng.random_range(1..6) {
            obj += &format!("o obj{o}\n");
            for _ in 0..rng.random_range(1..5) {
                let a = uniform_point(&mut rng, &b);
                let mut tri = [a, a + uniform_direction(&mut rng) * scale * 0.3, a];
                tri[2] = match rng.random_range(0..4) {
                    0 => tri[1],                 // degenerate: a repeated corner
                    1 => a + (tri[1] - a) * 2.0, // degenerate: collinear
                    _ => a + uniform_direction(&mut rng) * scale * 0.3,
                };
                if flat {
                    for p in &mut tri {
                        p.z = offset;
                    }
                }
                for p in tri {
                    obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
                }
                obj += &format!("f {} {} {}\n", v + 1, v + 2, v + 3);
                v += 3;
            }
        }
        let scene = match vis5d::scene::load_obj_bytes(format!("case{case}.obj"), obj.as_bytes()) {
            Ok(s) => s,
            Err(_) => {
                refused += 1; // all degenerate, or a size f32 cannot resolve
                continue;
            }
        };
        accepted += 1;
        let tracer = Tracer::new(&scene);
        let params = BuildParams {
            max_depth: 4,
            cache_rays: 256,
            min_visible_triangles: 0,
            seed: case as u64,
            ..BuildParams::default()
        };
        let (tree, _) = build(&scene, &tracer, &params, &|_| {})
            .unwrap_or_else(|e| panic!("case {case} (scale {scale}, offset {offset}): {e}"));
        tree.validate().unwrap();
        splits += usize::from(tree.nodes().len() > 1);
        let bytes = write_file(&to_file(&scene, tree.clone(), &params, None));
        let back = read_file(&bytes, ReadLimits::default())
            .unwrap_or_else(|e| panic!("case {case} (scale {scale}, offset {offset}): {e}"));
        assert_eq!(back.tree, tree, "case {case}");
        let pvs = Pvs::from_bytes(&bytes).unwrap();
        let mut out = pvs.new_set();
        pvs.query_view(
            &View::square(scene.bounds().center(), Vec3::X, 90.0),
            &mut out,
        )
        .unwrap();
    }
    assert!(accepted >= 40, "{accepted} accepted, {refused} refused");
    eprintln!("{accepted} accepted, {refused} refused, {splits} trees split");
    assert!(splits >= accepted / 2, "{splits} of {accepted} trees split");
}

/// The f64 world entry points of a far tree answer what the tree answers
/// at the same local place (a first version took f32 world positions,
/// which at 4.6e6 move the eye by up to 0.25 and missed walls).
#[test]
fn far_trees_take_f64_world_positions() {
    use glam::DVec3;
    use vis5d::builder::{BuildParams, build, to_file};
    use vis5d::query::Pvs;
    use vis5d::scene::procedural::{SceneKind, generate};

    let near = generate(SceneKind::Apartment, 1, 1);
    let offset = DVec3::new(500_123.7, 4_649_876.3, 250.0);
    let far = near
        .translated(offset, Path::new("far.obj"))
        .expect("within the limits");
    let tracer = vis5d::trace::Tracer::new(&far);
    let params = BuildParams {
        max_depth: 6,
        ..BuildParams::default()
    };
    let (tree, _) = build(&far, &tracer, &params, &|_| {}).unwrap();
    let pvs = Pvs::from_bytes(&vis5d::codec::write_file(&to_file(
        &far, tree, &params, None,
    )))
    .unwrap();
    let frame = pvs.frame();
    assert_eq!(frame, far.frame());
    let (mut a, mut b) = (pvs.new_set(), pvs.new_set());
    let views = vis5d::render::random_views(&far.bounds(), 50, 90.0, 9);
    let mut equal = 0;
    for v in &views {
        // The eye in world coordinates, f64, exactly as a user holds it.
        let eye = frame.to_world(v.position);
        pvs.query_view_world(eye, v, &mut a).unwrap();
        pvs.query_view(v, &mut b).unwrap();
        assert!(b.is_subset(&a), "{v:?}");
        equal += usize::from(a == b);
        assert!(a.count() < pvs.object_count(), "{v:?}: nothing culled");
    }
    assert!(equal >= 45, "{equal} of 50 equal");
}

/// A site plan off zero along its thin axis (ground at z = 50, a 5 cm
/// kerb): the bounds grid there is finer than f32, and flat objects got
/// crossed bounds codes that the reader refused, so the build failed
/// ("the bounds codes ... are not a box"). A review found it.
#[test]
fn a_thin_site_plan_off_zero_builds() {
    let dir = tempfile::tempdir().unwrap();
    let obj = "o ground\nv 0 0 50\nv 40 0 50\nv 40 40 50\nv 0 40 50\nf 1 2 3\nf 1 3 4\n\
               o kerb\nv 0 0 50.05\nv 40 0 50.05\nv 40 1 50.05\nv 0 1 50.05\nf 5 6 7\nf 5 7 8\n";
    let model = write(dir.path(), "site.obj", obj);
    let out = vis5d(&["build", &model, "--max-depth", "3"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v5d = dir.path().join("site.v5d");
    let out = vis5d(&[
        "query",
        v5d.to_str().unwrap(),
        "--pos",
        "20,20,50.02",
        "--dir",
        "0,0,1",
        "--scene",
        &model,
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
}
