//! Scenes whose up axis is not +z (issue 15): a scene turned Y-up (or
//! X-up) and built with `--up y` (`--up x`) gets the very tree the same
//! scene gets Z-up, and the same answers to the same views, each given in
//! its own scene's world coordinates.

use std::fmt::Write as _;
use std::path::Path;

use glam::{DVec3, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::codec::{self, ReadLimits};
use vis5d::geom::Up;
use vis5d::query::{Pvs, View};
use vis5d::scene::{self, Scene};

use crate::{committed, text, vis5d};

/// World coordinates of a Z-up point in the same scene turned so that
/// `up` is up (local z follows `up`: see `vis5d::geom::Frame`).
fn turn(up: Up, p: DVec3) -> DVec3 {
    let mut w = DVec3::ZERO;
    for k in 0..3 {
        w[up.world_axis(k)] = p[k];
    }
    w
}

/// Writes `scene` (near the origin) as OBJ with its axes turned for `up`.
fn write_turned(scene: &Scene, up: Up, path: &Path) {
    let mut out = String::new();
    for (i, o) in scene.objects().iter().enumerate() {
        writeln!(out, "o {}", o.name).unwrap();
        for t in scene.object_triangles(i) {
            for v in t {
                let w = turn(up, v.as_dvec3()).as_vec3();
                writeln!(out, "v {} {} {}", w.x, w.y, w.z).unwrap();
            }
            out.push_str("f -3 -2 -1\n");
        }
    }
    std::fs::write(path, out).unwrap();
}

#[test]
fn a_scene_turned_and_built_with_its_up_axis_gives_the_same_tree_and_answers() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene::load(committed("apartment.obj")).expect("committed scene loads");
    assert!(scene.frame().is_identity());
    let mut trees = Vec::new();
    for up in [Up::Z, Up::Y, Up::X] {
        let model = dir.path().join(format!("{up}.obj"));
        write_turned(&scene, up, &model);
        let out = dir.path().join(format!("{up}.v5d"));
        let (m, o) = (model.to_str().unwrap(), out.to_str().unwrap());
        let flags = ["--max-depth", "8", "--seed", "4", "--threads", "2"];
        let up_name = up.to_string();
        let mut args = vec!["build", m, "-o", o, "--up", up_name.as_str(), "--json"];
        args.extend(flags);
        let built = vis5d(&args);
        assert!(built.status.success(), "{}", text(&built.stderr));
        let report: serde_json::Value = serde_json::from_slice(&built.stdout).unwrap();
        assert_eq!(report["up"], up_name);
        let stat = vis5d(&["stat", o, "--json"]);
        let s: serde_json::Value = serde_json::from_slice(&stat.stdout).unwrap();
        assert_eq!(
            (s["version"].as_u64(), s["up"].as_str()),
            (Some(u64::from(vis5d::codec::VERSION)), Some(up.name()))
        );
        let bytes = std::fs::read(&out).unwrap();
        let file = codec::read_file(&bytes, ReadLimits::default()).unwrap();
        assert_eq!(file.frame.up, up);
        // The scene given with the file is loaded with its up axis.
        let q = vis5d(&["query", o, "--scene", m, "--pos", "1,1,1", "--dir", "1,0,0"]);
        assert!(q.status.success(), "{}", text(&q.stderr));
        trees.push((up, model, out, file, Pvs::from_bytes(&bytes).unwrap()));
    }
    // The same tree, objects and local bounds; another fingerprint.
    let z = &trees[0];
    for t in &trees[1..] {
        assert_eq!(t.3.tree, z.3.tree, "--up {}", t.0);
        assert_eq!(t.3.objects, z.3.objects, "--up {}", t.0);
        assert_ne!(t.3.fingerprint, z.3.fingerprint);
    }
    // The same answers to the same views, each in its own world: views
    // as engines give them (eye, forward, up, vertical field of view,
    // aspect), eyes with and without a radius.
    let bounds = scene.bounds();
    let mut rng = Pcg64::seed_from_u64(15);
    let unit =
        |rng: &mut Pcg64| Vec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - Vec3::ONE;
    let mut differing = 0;
    for k in 0..400 {
        let eye = bounds
            .lerp(Vec3::new(rng.random(), rng.random(), rng.random()))
            .as_dvec3();
        let forward = unit(&mut rng);
        let up = if k % 2 == 0 { Vec3::Z } else { unit(&mut rng) };
        let mut view = View::look(
            Vec3::ZERO,
            forward,
            up,
            rng.random_range(0.3..1.6),
            rng.random_range(0.5..2.2),
        );
        view.radius = if k % 3 == 0 { 0.25 } else { 0.0 };
        let mut answers = Vec::new();
        for (axis, _, _, _, pvs) in &trees {
            let mut turned = view;
            turned.dir = turn(*axis, view.dir.as_dvec3()).as_vec3();
            turned.up = turn(*axis, view.up.as_dvec3()).as_vec3();
            let mut set = pvs.new_set();
            pvs.query_view_world(turn(*axis, eye), &turned, &mut set)
                .unwrap();
            answers.push(set.iter().collect::<Vec<_>>());
        }
        assert_eq!(answers[1], answers[0], "view {k} (--up y)");
        assert_eq!(answers[2], answers[0], "view {k} (--up x)");
        // The view's up matters here (not a square field of view).
        let mut rolled = view;
        rolled.up = forward.normalize().any_orthonormal_vector();
        differing += usize::from(pvs_answer(&trees[0].4, eye, &rolled) != answers[0]);
    }
    assert!(differing > 0, "the up vector never changed an answer");
    // The command line: a views file in the Y-up world, with up vectors,
    // vertical fields of view and aspect ratios, answers as the library;
    // a view without "up" takes the tree's up axis (world +y).
    let (_, _, y_file, _, y_pvs) = &trees[1];
    let views = dir.path().join("views.json");
    let specs = r#"[
        {"pos": [1.0, 1.2, 1.5], "dir": [0.0, -0.2, 1.0], "up": [0, 1, 0], "vfov": 40, "aspect": 2.0},
        {"pos": [1.0, 1.2, 1.5], "dir": [0.0, -0.2, 1.0], "vfov": 40, "aspect": 2.0},
        {"pos": [2.0, 1.0, 4.0], "dir": [1.0, 0.0, 0.0], "fov": 60}
    ]"#;
    std::fs::write(&views, specs).unwrap();
    let q = vis5d(&[
        "query",
        y_file.to_str().unwrap(),
        "--views",
        views.to_str().unwrap(),
        "--json",
    ]);
    assert!(q.status.success(), "{}", text(&q.stderr));
    let lists: Vec<Vec<String>> = serde_json::from_slice(&q.stdout).unwrap();
    let names = |objects: Vec<usize>| -> Vec<String> {
        objects
            .into_iter()
            .map(|o| y_pvs.object(o).unwrap().name().to_owned())
            .collect()
    };
    let look = View::look(
        Vec3::ZERO,
        Vec3::new(0.0, -0.2, 1.0),
        Vec3::Y,
        40f32.to_radians(),
        2.0,
    );
    let expected = names(pvs_answer(y_pvs, DVec3::new(1.0, 1.2, 1.5), &look));
    assert_eq!(lists[0], expected);
    assert_eq!(lists[1], expected);
    let mut square = View::square(Vec3::ZERO, Vec3::X, 60.0);
    square.up = Vec3::Y;
    assert_eq!(
        lists[2],
        names(pvs_answer(y_pvs, DVec3::new(2.0, 1.0, 4.0), &square))
    );
    // A scene given with another up axis than the file's is refused, and
    // the message says which to pass.
    let y_model = trees[1].1.to_str().unwrap();
    let wrong = vis5d(&[
        "report",
        y_model,
        "-o",
        dir.path().join("report").to_str().unwrap(),
        "--pvs",
        y_file.to_str().unwrap(),
    ]);
    assert!(!wrong.status.success());
    assert!(
        text(&wrong.stderr).contains("pass --up y"),
        "{}",
        text(&wrong.stderr)
    );
    // The oracle: the same cell in each world keeps the same objects.
    let oracle = |model: &Path, up: Up, cell: [f64; 6]| -> serde_json::Value {
        let cell = cell.map(|c| c.to_string()).join(",");
        let out = vis5d(&[
            "oracle",
            model.to_str().unwrap(),
            "--up",
            up.name(),
            "--cell",
            &cell,
            "--cpu",
            "--json",
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let (lo, hi) = (DVec3::new(1.0, 1.0, 0.5), DVec3::new(2.0, 2.0, 1.5));
    let corners = |up: Up| {
        let (a, b) = (turn(up, lo), turn(up, hi));
        let (a, b) = (a.min(b), a.max(b));
        [a.x, a.y, a.z, b.x, b.y, b.z]
    };
    let z = oracle(&trees[0].1, Up::Z, corners(Up::Z));
    let y = oracle(&trees[1].1, Up::Y, corners(Up::Y));
    let kept = z["potentially_visible"].as_array().unwrap();
    assert!(kept.len() < scene.objects().len(), "{kept:?}");
    assert_eq!(&y["potentially_visible"], &z["potentially_visible"]);
    // Its planes are printed in world axes: the Z-up scene's +x is the
    // Y-up one's +z (world = (y, z, x)), at the same place.
    let planes = |v: &serde_json::Value| -> Vec<(String, f64)> {
        v["planes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                (
                    p["face"].as_str().unwrap().to_owned(),
                    p["position"].as_f64().unwrap(),
                )
            })
            .collect()
    };
    let renamed: Vec<(String, f64)> = planes(&z)
        .into_iter()
        .map(|(f, p)| {
            let axis = match &f[1..] {
                "x" => "z",
                "y" => "x",
                _ => "y",
            };
            (format!("{}{axis}", &f[..1]), p)
        })
        .collect();
    assert!(!renamed.is_empty());
    assert_eq!(planes(&y), renamed);
}

/// The objects `pvs` answers for `view` from the world eye `eye`, sorted.
fn pvs_answer(pvs: &Pvs, eye: DVec3, view: &View) -> Vec<usize> {
    let mut set = pvs.new_set();
    pvs.query_view_world(eye, view, &mut set).unwrap();
    set.iter().collect()
}
