//! `vis5d report`: the page, the JSON and the Markdown, their figures
//! checked against the ground truth they come from, and the page loaded
//! in headless Chromium.

use std::path::Path;
use std::process::Command;

use crate::{build_poor_tree, chromium, text, vis5d};

/// Runs a small report on the machine scene into `dir`.
fn small_report(dir: &Path, extra: &[&str]) -> serde_json::Value {
    let out_dir = dir.to_str().unwrap();
    let mut args = vec![
        "report",
        "scenes/machine.obj",
        "-o",
        out_dir,
        "--random",
        "6",
        "--resolution",
        "48",
    ];
    args.extend_from_slice(extra);
    let out = vis5d(&args);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("wrote"), "{}", text(&out.stdout));
    serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap()
}

#[test]
fn report_writes_consistent_figures() {
    let dir = tempfile::tempdir().unwrap();
    let j = small_report(dir.path(), &[]);
    let names: Vec<&str> = j["methods"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "frustum",
            "vis5d",
            "lazy grid",
            "oracle",
            "shrinking",
            "oracle and shrinking"
        ]
    );
    // Both together draw no more than either, view by view.
    let per_view = |name: &str| -> Vec<u64> {
        j["methods"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["name"] == name)
            .unwrap()["per_view"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v["objects"].as_u64().unwrap())
            .collect()
    };
    let (o, s, b) = (
        per_view("oracle"),
        per_view("shrinking"),
        per_view("oracle and shrinking"),
    );
    for v in 0..o.len() {
        assert!(
            b[v] <= o[v].min(s[v]),
            "view {v}: {} {} {}",
            o[v],
            s[v],
            b[v]
        );
    }
    assert_eq!(j["views"].as_array().unwrap().len(), 6);
    for m in j["methods"].as_array().unwrap() {
        let per_view = m["per_view"].as_array().unwrap();
        assert_eq!(per_view.len(), 6);
        // The conservative methods never miss what the truth sees.
        if m["name"] != "vis5d" {
            assert_eq!(m["summary"]["missed_objects"], 0, "{}", m["name"]);
            assert_eq!(m["summary"]["worst_pixel_error"], 0.0, "{}", m["name"]);
        }
        for (v, t) in per_view.iter().zip(j["views"].as_array().unwrap()) {
            // Drawn = seen - missed + extra.
            let seen = t["seen_objects"].as_u64().unwrap() as f64;
            let drawn = v["objects"].as_u64().unwrap() as f64;
            let missed = v["missed_objects"].as_u64().unwrap() as f64;
            if seen > 0.0 {
                let q_o = v["q_o"].as_f64().unwrap();
                assert!(
                    (drawn - (seen - missed) - q_o * seen).abs() < 1e-6,
                    "{v} {t}"
                );
            }
        }
    }
    // The tree, the grid and the oracle draw no more than frustum culling.
    let mean = |k: usize| j["methods"][k]["summary"]["mean_objects"].as_f64().unwrap();
    assert!(mean(1) <= mean(0) && mean(2) <= mean(0) && mean(3) <= mean(0));
    // Lazy and busy grid costs are both counted, per view.
    assert_eq!(j["grid_costs"].as_array().unwrap().len(), 6);
    assert_eq!(j["tree"]["codings"].as_array().unwrap().len(), 3);
    assert!(j["tree"]["build_seconds"].as_f64().is_some());
    // The oracle's depth maps go to the GPU where there is one (CI
    // requires one: Mesa's lavapipe).
    let rasteriser = j["oracle_rasteriser"].as_str().unwrap();
    if std::env::var_os("VIS5D_REQUIRE_GPU").is_some() {
        assert!(rasteriser.starts_with("GPU: "), "{rasteriser}");
    }
    let html = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 5, "five plots");
    assert!(!html.contains("<script"), "no JavaScript");
    check_pictures(dir.path(), &j, &html, 6);
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(
        md.contains("| frustum |") && md.contains("| oracle |"),
        "{md}"
    );
}

/// Reads a PNG: its size and RGB bytes.
fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// The report's `count` pictures: PNG files of the views' size whose red
/// pixels are the tree's missing pixels of the view, thumbnails linked to
/// them on the page.
fn check_pictures(dir: &Path, j: &serde_json::Value, html: &str, count: usize) {
    let pictures = j["pictures"].as_array().unwrap();
    assert_eq!(pictures.len(), count);
    let tree = j["methods"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"] == "vis5d")
        .unwrap();
    let resolution = j["resolution"].as_u64().unwrap() as u32;
    for (v, p) in pictures.iter().enumerate() {
        assert_eq!(p["view"], v);
        let (w, h, rgb) = read_png(&dir.join(p["file"].as_str().unwrap()));
        assert_eq!((w, h), (resolution, resolution));
        let red = rgb.chunks_exact(3).filter(|c| *c == [255, 0, 0]).count() as u64;
        let missing = tree["per_view"][v]["missing_pixels"].as_u64().unwrap();
        assert_eq!(
            red, missing,
            "view {v}: red pixels against the tree's missing ones"
        );
        assert_eq!(p["dropped_pixels"], missing);
        let (sw, sh, _) = read_png(&dir.join(p["small"].as_str().unwrap()));
        assert_eq!(
            [sw, sh],
            [
                p["small_size"][0].as_u64().unwrap() as u32,
                p["small_size"][1].as_u64().unwrap() as u32
            ]
        );
        assert!(sw <= 200 && sh <= 200);
        let link = format!(
            "<a href=\"{}\"><img src=\"{}\"",
            p["file"].as_str().unwrap(),
            p["small"].as_str().unwrap()
        );
        assert!(html.contains(&link), "{link}");
        // What each method draws: one picture a method, red exactly where
        // its set lacks the object seen (at this resolution the same rays
        // as the ground truth's).
        let methods = j["methods"].as_array().unwrap();
        let drawn = p["methods"].as_array().unwrap();
        assert_eq!(drawn.len(), methods.len());
        for (d, m) in drawn.iter().zip(methods) {
            assert_eq!(d["method"], m["name"]);
            let (w, h, rgb) = read_png(&dir.join(d["file"].as_str().unwrap()));
            assert_eq!(
                [w, h],
                [0, 1].map(|k| d["size"][k].as_u64().unwrap() as u32)
            );
            assert_eq!((w, h), (resolution.min(200), resolution.min(200)));
            let red = rgb.chunks_exact(3).filter(|c| *c == [255, 0, 0]).count() as u64;
            assert_eq!(d["dropped_pixels"], red, "{d}");
            let figures = &m["per_view"][v];
            assert_eq!(d["objects"], figures["objects"], "{d}");
            if resolution <= 200 {
                assert_eq!(d["dropped_pixels"], figures["missing_pixels"], "{d}");
            }
            let layers = d["mean_layers"].as_f64().unwrap();
            assert!(red > 0 || layers >= 1.0, "{d}");
            assert!(html.contains(&format!("<img src=\"{}\"", d["file"].as_str().unwrap())));
        }
    }
    // The map, with the pictures.
    let map = &j["map"];
    let (w, h, _) = read_png(&dir.join(map["file"].as_str().unwrap()));
    assert_eq!(w.max(h), resolution.max(512));
    assert!(map["cells"].as_u64().unwrap() >= 1);
    let link = format!(
        "<a href=\"{}\"><img src=\"{}\"",
        map["file"].as_str().unwrap(),
        map["small"].as_str().unwrap()
    );
    assert!(html.contains(&link), "{link}");
    let methods = j["methods"].as_array().unwrap().len();
    assert_eq!(html.matches("<img").count(), count * (1 + methods) + 1);
}

/// Pictures of a tree that drops objects: red where it does, and none
/// with `--pictures 0`; too many refused.
#[test]
fn the_pictures_paint_what_a_poor_tree_drops() {
    let dir = tempfile::tempdir().unwrap();
    let poor = dir.path().join("poor.v5d");
    build_poor_tree("scenes/apartment.obj", &poor);
    let report = dir.path().join("report");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "report",
            "scenes/apartment.obj",
            "--pvs",
            poor.to_str().unwrap(),
            "-o",
            report.to_str().unwrap(),
            "--random",
            "8",
            "--resolution",
            "96",
            "--no-oracle",
            "--no-shrink",
        ];
        args.extend_from_slice(extra);
        vis5d(&args)
    };
    let out = run(&["--pictures", "5"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let j: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report.join("report.json")).unwrap()).unwrap();
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    check_pictures(&report, &j, &html, 5);
    let red: u64 = j["pictures"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["dropped_pixels"].as_u64().unwrap())
        .sum();
    eprintln!("{red} red pixels in 5 pictures");
    // Without pictures: none on the page, no folder made.
    let none = dir.path().join("none");
    let out = vis5d(&[
        "report",
        "scenes/machine.obj",
        "-o",
        none.to_str().unwrap(),
        "--random",
        "2",
        "--resolution",
        "32",
        "--no-oracle",
        "--no-shrink",
        "--pictures",
        "0",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(!none.join("images").exists());
    let j: serde_json::Value =
        serde_json::from_slice(&std::fs::read(none.join("report.json")).unwrap()).unwrap();
    assert!(j["map"].is_null() && j["pictures"].as_array().unwrap().is_empty());
    assert!(
        !std::fs::read_to_string(none.join("index.html"))
            .unwrap()
            .contains("<img")
    );
    let out = run(&["--pictures", "1001"]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("--pictures"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn report_takes_a_tree_and_a_camera_path_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let v5d = crate::machine_tree(dir.path(), 5);
    let views = dir.path().join("path.json");
    std::fs::write(
        &views,
        r#"[{"pos": [0.5, 0.4, 0.3], "dir": [1, 0, 0], "fov": 60}, {"pos": [0.5, 0.4, 0.3], "dir": [0, 1, 0]}]"#,
    )
    .unwrap();
    let out_dir = dir.path().join("r");
    let j = small_report(
        &out_dir,
        &[
            "--pvs",
            v5d.to_str().unwrap(),
            "--views",
            views.to_str().unwrap(),
            "--no-oracle",
            "--no-shrink",
        ],
    );
    assert_eq!(j["views"].as_array().unwrap().len(), 2);
    assert_eq!(j["methods"].as_array().unwrap().len(), 3);
    assert!(j["tree"]["build_seconds"].is_null());
    for (args, message) in [
        (
            vec![
                "report",
                "scenes/apartment.obj",
                "-o",
                "/tmp/x",
                "--pvs",
                v5d.to_str().unwrap(),
            ],
            "another scene",
        ),
        (
            vec![
                "report",
                "scenes/machine.obj",
                "-o",
                "/tmp/x",
                "--resolution",
                "0",
            ],
            "--resolution",
        ),
        (vec!["report", "nope.obj", "-o", "/tmp/x"], "nope.obj"),
        (
            vec![
                "report",
                "scenes/machine.obj",
                "-o",
                "/tmp/x",
                "--random",
                "0",
            ],
            "--random",
        ),
        (
            vec![
                "report",
                "scenes/machine.obj",
                "-o",
                "/tmp/x",
                "--grid-cell",
                "0",
            ],
            "--grid-cell",
        ),
    ] {
        let out = vis5d(&args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: usage and runtime errors exit with 2"
        );
        assert!(
            text(&out.stderr).contains(message),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
}

/// The page in headless Chromium: it loads, its DOM holds the five plots,
/// and a screenshot shows them. Skipped without Chromium unless
/// `VIS5D_REQUIRE_CHROMIUM` is set (CI sets it).
#[test]
fn the_page_loads_in_headless_chromium() {
    let Some(chromium) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    small_report(dir.path(), &["--no-oracle"]);
    let url = format!("file://{}", dir.path().join("index.html").display());
    let headless = |extra: &[&str]| {
        Command::new(chromium)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--enable-logging=stderr",
                "--v=0",
            ])
            .args(extra)
            .arg(&url)
            .output()
            .unwrap()
    };
    let dom = headless(&["--dump-dom"]);
    assert!(dom.status.success(), "{}", text(&dom.stderr));
    let html = text(&dom.stdout);
    assert_eq!(html.matches("<svg").count(), 5, "{html}");
    assert!(
        !text(&dom.stderr).contains("Uncaught"),
        "{}",
        text(&dom.stderr)
    );
    let shot = dir.path().join("page.png");
    let out = headless(&[
        &format!("--screenshot={}", shot.display()),
        "--window-size=1100,2000",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let png = std::fs::read(&shot).unwrap();
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 20_000,
        "{} bytes",
        png.len()
    );
}

#[test]
fn report_counts_triangles_at_slice_granularity() {
    let dir = tempfile::tempdir().unwrap();
    let j = small_report(dir.path(), &["--slices", "8"]);
    for m in j["methods"].as_array().unwrap() {
        let s = &m["summary"];
        match m["name"].as_str().unwrap() {
            "oracle" | "shrinking" | "oracle and shrinking" => {
                let t = s["mean_slice_triangles"].as_f64().expect("slices counted");
                assert!(t <= s["mean_triangles"].as_f64().unwrap() + 1e-9, "{m}");
            }
            _ => assert!(s["mean_slice_triangles"].is_null(), "{m}"),
        }
    }
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(md.contains("(slices: "), "{md}");
    let out = vis5d(&[
        "report",
        "scenes/machine.obj",
        "-o",
        dir.path().join("bad").to_str().unwrap(),
        "--slices",
        "300",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("--slices"),
        "{}",
        text(&out.stderr)
    );
}
