//! `vis5d view`: the server's API against `Pvs` answers, its 400s, and the
//! page flown in headless Chromium.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use glam::{DVec3, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::geom::cell::direction_to_angles;
use vis5d::query::{Answer, Pvs, View};
use vis5d::render::{Camera, IdBuffer};
use vis5d::trace::Tracer;

use crate::{assert_refused, build_poor_tree, chromium, root, text, vis5d};

/// A running `vis5d view`, stopped when dropped.
struct Server {
    child: Child,
    /// "127.0.0.1:port".
    address: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `vis5d view MODEL --pvs ... --port 0` and reads the address it
/// prints.
fn start(model: &str, trees: &[&Path]) -> Server {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vis5d"));
    cmd.args(["view", model, "--port", "0"]).current_dir(root());
    for t in trees {
        cmd.arg("--pvs").arg(t);
    }
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let address = line
        .trim()
        .strip_prefix("http://")
        .and_then(|s| s.strip_suffix('/'))
        .unwrap_or_else(|| panic!("no address printed: {line:?}"))
        .to_owned();
    assert!(address.starts_with("127.0.0.1:"), "{address}");
    Server { child, address }
}

/// One GET: the status and the body.
fn get(server: &Server, path: &str) -> (u16, Vec<u8>) {
    get_as(server, path, &server.address)
}

/// One GET naming `host` in its Host header.
fn get_as(server: &Server, path: &str, host: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(&server.address).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a header");
    let head = text(&raw[..split]);
    assert!(
        !head.to_ascii_lowercase().contains("transfer-encoding"),
        "{head}"
    );
    let status = head[9..12].parse().unwrap();
    (status, raw[split + 4..].to_vec())
}

fn get_json(server: &Server, path: &str) -> serde_json::Value {
    let (status, body) = get(server, path);
    assert_eq!(status, 200, "{path}: {}", text(&body));
    serde_json::from_slice(&body).unwrap()
}

/// A good tree of the apartment and a poor one (few rays, quick verdicts:
/// it drops visible objects).
fn trees(dir: &Path) -> (PathBuf, PathBuf) {
    let good = dir.join("good.v5d");
    let out = vis5d(&[
        "build",
        "scenes/apartment.obj",
        "-o",
        good.to_str().unwrap(),
        "--max-depth",
        "10",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let poor = dir.join("poor.v5d");
    build_poor_tree("scenes/apartment.obj", &poor);
    (good, poor)
}

/// A query's parameters.
struct Ask {
    pos: DVec3,
    dir: Vec3,
    up: Vec3,
    fov: f32,
    aspect: f32,
}

impl Ask {
    fn url(&self, tree: usize) -> String {
        let v = |v: [f64; 3]| format!("{},{},{}", v[0], v[1], v[2]);
        format!(
            "/api/query?pos={}&dir={}&up={}&fov={}&aspect={}&pvs={tree}",
            v(self.pos.to_array()),
            v(self.dir.as_dvec3().to_array()),
            v(self.up.as_dvec3().to_array()),
            self.fov,
            self.aspect
        )
    }

    /// The same view answered by the library: its objects and its leaf.
    fn answer(&self, pvs: &Pvs) -> (Vec<usize>, Option<u32>) {
        let frame = pvs.frame();
        let view = View::look(
            self.pos.as_vec3(),
            self.dir,
            self.up,
            self.fov.to_radians(),
            self.aspect,
        );
        let positions = frame.box_to_local(self.pos, self.pos);
        let mut set = pvs.new_set();
        let answer = pvs
            .query_view_from(&positions, &view.to_local(&frame, self.pos), &mut set)
            .unwrap();
        let p = frame.to_local(self.pos);
        let (theta, phi) = direction_to_angles(frame.dir_to_local(self.dir));
        // No leaf where the answer is every object.
        let leaf = match answer {
            Answer::Tree => pvs.leaf_at([p.x, p.y, p.z, theta, phi]).map(|l| l.0),
            _ => None,
        };
        (set.iter().collect(), leaf)
    }
}

/// Parses a query URL's parameters back (the page's).
fn ask_of(url: &str) -> Ask {
    let q: HashMap<&str, &str> = url
        .split_once('?')
        .unwrap()
        .1
        .split('&')
        .map(|kv| kv.split_once('=').unwrap())
        .collect();
    let v = |k: &str| -> DVec3 {
        let n: Vec<f64> = q[k].split(',').map(|x| x.parse().unwrap()).collect();
        DVec3::new(n[0], n[1], n[2])
    };
    Ask {
        pos: v("pos"),
        dir: v("dir").as_vec3(),
        up: v("up").as_vec3(),
        fov: q["fov"].parse().unwrap(),
        aspect: q["aspect"].parse().unwrap(),
    }
}

fn indices(v: &serde_json::Value) -> Vec<usize> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap() as usize)
        .collect()
}

#[test]
fn the_api_answers_as_the_library_and_refuses_bad_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let (good, poor) = trees(dir.path());
    let server = start("scenes/apartment.obj", &[&good, &poor]);
    let pvs = [Pvs::load(&good).unwrap(), Pvs::load(&poor).unwrap()];
    let scene = vis5d::scene::load(root().join("scenes/apartment.obj")).unwrap();

    let info = get_json(&server, "/api/info");
    assert_eq!(
        info["objects"].as_array().unwrap().len(),
        scene.objects().len()
    );
    assert_eq!(info["pvs"].as_array().unwrap().len(), 2);
    assert_eq!(
        info["triangles"].as_u64().unwrap(),
        scene.triangles().len() as u64
    );

    // The scene: one node per object, in the file's order.
    let (status, glb) = get(&server, "/api/scene.glb");
    assert_eq!(status, 200);
    let back = vis5d::scene::load_bytes(Path::new("scene.glb"), &glb, &Default::default()).unwrap();
    assert_eq!(back.objects().len(), scene.objects().len());
    for (a, b) in back.objects().iter().zip(scene.objects()) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.triangles, b.triangles);
    }

    // Views at random in and around the view box, as the library answers.
    let mut rng = Pcg64::seed_from_u64(7);
    let (lo, hi) = pvs[0].frame().box_to_world(&pvs[0].view_box());
    let (mut outside, mut leaves) = (0, std::collections::HashSet::new());
    for k in 0..300 {
        let t = DVec3::new(rng.random(), rng.random(), rng.random());
        let pos = lo + (hi - lo) * (t * 1.2 - 0.1);
        let dir = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-0.5..0.5),
        );
        let up = if k % 2 == 0 {
            Vec3::Z
        } else {
            dir.cross(Vec3::X).normalize()
        };
        let ask = Ask {
            pos,
            dir,
            up,
            fov: rng.random_range(20.0..120.0),
            aspect: rng.random_range(0.5..2.0),
        };
        let tree = k % 2;
        let got = get_json(&server, &ask.url(tree));
        let (visible, leaf) = ask.answer(&pvs[tree]);
        assert_eq!(indices(&got["visible"]), visible, "{}", ask.url(tree));
        assert_eq!(got["leaf"].as_u64().map(|l| l as u32), leaf);
        let triangles: u64 = visible
            .iter()
            .map(|&i| {
                let r = &scene.objects()[i].triangles;
                u64::from(r.end - r.start)
            })
            .sum();
        assert_eq!(got["triangles"].as_u64().unwrap(), triangles);
        match leaf {
            None => {
                outside += 1;
                assert_eq!(got["answer"], "everything");
            }
            Some(l) => {
                leaves.insert((tree, l));
                assert_eq!(got["answer"], "tree");
                // The leaf's cell holds the eye.
                let v = |v: DVec3| format!("{},{},{}", v.x, v.y, v.z);
                let c = get_json(
                    &server,
                    &format!(
                        "/api/cell?pos={}&dir={}&pvs={tree}",
                        v(pos),
                        v(dir.as_dvec3())
                    ),
                );
                assert_eq!(c["leaf"].as_u64(), Some(u64::from(l)));
                for a in 0..3 {
                    assert!(
                        c["min"][a].as_f64().unwrap() <= pos[a]
                            && pos[a] <= c["max"][a].as_f64().unwrap(),
                        "{c} {pos}"
                    );
                }
            }
        }
    }
    assert!(
        outside > 10 && leaves.len() > 20,
        "{outside} {}",
        leaves.len()
    );

    // Bad parameters: a 400 with a message, and the server goes on.
    let good_view = "pos=1,1,1.5&dir=1,0,0";
    for (query, message) in [
        ("/api/query?dir=1,0,0", "pos=x,y,z is required"),
        ("/api/query?pos=1,1,1.5", "dir=x,y,z is required"),
        ("/api/query?pos=1,1&dir=1,0,0", "expected 3 numbers"),
        ("/api/query?pos=nan,1,1&dir=1,0,0", "finite"),
        ("/api/query?pos=a,b,c&dir=1,0,0", "pos="),
        ("/api/query?pos=1,1,1&dir=0,0,0", "not zero"),
        ("/api/query?pos=1,1,1&dir=0,0,1&up=0,0,2", "not along dir"),
        (
            &format!("/api/query?{good_view}&fov=0"),
            "between 0 and 180",
        ),
        (
            &format!("/api/query?{good_view}&fov=180"),
            "between 0 and 180",
        ),
        (&format!("/api/query?{good_view}&fov=wide"), "fov="),
        (&format!("/api/query?{good_view}&aspect=-1"), "aspect="),
        (&format!("/api/query?{good_view}&aspect=1e9"), "aspect="),
        (
            &format!("/api/query?{good_view}&pvs=2"),
            "there are 2 trees",
        ),
        (&format!("/api/query?{good_view}&pvs=x"), "pvs="),
        (
            &format!("/api/query?{good_view}&zoom=2"),
            "unknown parameter",
        ),
        ("/api/cell", "pos=x,y,z is required"),
        ("/api/cell?pos=1,1,1&fov=20", "unknown parameter"),
        (
            &format!("/api/query?{good_view}&pos=0,0,0"),
            "pos is given twice",
        ),
        (
            &format!("/api/cell?{good_view}&dir=0,1,0"),
            "dir is given twice",
        ),
        (
            &format!("/api/query?pos=1,1,{}x&dir=1,0,0", "9".repeat(5000)),
            "...",
        ),
    ] {
        let (status, body) = get(&server, query);
        assert_eq!(status, 400, "{query}: {}", text(&body));
        assert!(text(&body).contains(message), "{query}: {}", text(&body));
        assert!(
            body.len() > 10 && body.len() < 300,
            "{query}: {}",
            text(&body)
        );
    }
    assert_eq!(get(&server, "/nothing/here").0, 404);
    // Wide but under 180 degrees either way: answered.
    assert_eq!(
        get(&server, &format!("/api/query?{good_view}&fov=179.95")).0,
        200
    );
    assert_eq!(
        get(
            &server,
            &format!("/api/query?{good_view}&fov=90&aspect=1e9")
        )
        .0,
        400
    );
    // Only pages of this machine's names are served (no DNS rebinding).
    for host in ["localhost:1234", "127.0.0.1", "LOCALHOST"] {
        assert_eq!(get_as(&server, "/api/info", host).0, 200, "{host}");
    }
    let (status, body) = get_as(&server, "/api/info", "evil.example:80");
    assert_eq!(status, 403);
    assert!(text(&body).contains("loopback"), "{}", text(&body));
    assert_eq!(get(&server, &format!("/api/query?{good_view}")).0, 200);
    let (status, page) = get(&server, "/");
    assert_eq!(status, 200);
    assert!(text(&page).contains("viewer.js"));
    for script in [
        "/viewer.js",
        "/vendor/three.module.min.js",
        "/vendor/three.core.min.js",
        "/vendor/addons/loaders/GLTFLoader.js",
        "/vendor/addons/utils/BufferGeometryUtils.js",
    ] {
        let (status, body) = get(&server, script);
        assert_eq!(status, 200, "{script}");
        assert!(body.len() > 1000, "{script}");
    }
}

#[test]
fn a_tree_of_another_scene_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("machine.v5d");
    let out = vis5d(&[
        "build",
        "scenes/machine.obj",
        "-o",
        tree.to_str().unwrap(),
        "--max-depth",
        "2",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    for (args, message) in [
        (
            vec![
                "view",
                "scenes/apartment.obj",
                "--pvs",
                tree.to_str().unwrap(),
            ],
            "built for another version of the scene",
        ),
        (
            vec!["view", "scenes/apartment.obj", "--pvs", "no/such.v5d"],
            "no/such.v5d",
        ),
        (
            vec![
                "view",
                "scenes/machine.obj",
                "--pvs",
                tree.to_str().unwrap(),
                "--up",
                "y",
            ],
            "--up",
        ),
        (
            vec!["view", "scenes/machine.obj", "--port", "99999"],
            "--port",
        ),
        (
            vec!["view", "scenes/machine.obj", "--host", "nowhere"],
            "--host",
        ),
    ] {
        assert_refused(&args, message);
    }
}

/// The DOM of `url` once headless Chromium has run its scripts (for at
/// most two minutes of virtual time).
fn dump_dom(chromium: &str, url: &str) -> String {
    let out = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--window-size=640,480",
            "--virtual-time-budget=120000",
            "--dump-dom",
        ])
        .arg(url)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
    text(&out.stdout)
}

/// Flies the page along `views` (x,y,z,dx,dy,dz each) in headless
/// Chromium, checking for popping, and returns the frames it logged.
fn fly(chromium: &str, server: &Server, tree: usize, views: &[[f64; 6]]) -> Vec<serde_json::Value> {
    let path: Vec<String> = views
        .iter()
        .map(|v| v.map(|x| x.to_string()).join(","))
        .collect();
    let url = format!(
        "http://{}/?tree={tree}&check=1&fly={}",
        server.address,
        path.join("%3B")
    );
    let dom = dump_dom(chromium, &url);
    let log = dom
        .split_once("<pre id=\"log\">")
        .and_then(|(_, rest)| rest.split_once("</pre>"))
        .map(|(log, _)| log)
        .unwrap_or_else(|| panic!("no log in the page: {dom}"));
    assert!(dom.contains("<title>vis5d view: flown</title>"), "{log}");
    // The DOM's text, unescaped (the URLs hold '&').
    let log = log
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&");
    let frames: Vec<serde_json::Value> = serde_json::from_str(&log).unwrap();
    assert_eq!(frames.len(), views.len(), "{log}");
    frames
}

#[test]
fn the_page_flies_a_path_and_marks_popping_in_headless_chromium() {
    let Some(chromium) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (good, poor) = trees(dir.path());
    let server = start("scenes/apartment.obj", &[&good, &poor]);
    let pvs = [Pvs::load(&good).unwrap(), Pvs::load(&poor).unwrap()];
    // A walk through the living room at eye height, turning (an eye inside
    // a wall sees the wall's inside, which rays and rasters tell apart).
    let (lo, hi) = pvs[0].frame().box_to_world(&pvs[0].view_box());
    let mut views = Vec::new();
    for k in 0..12 {
        let t = f64::from(k) / 11.0;
        let p = lo + (hi - lo) * DVec3::new(0.12 + 0.4 * t, 0.3 + 0.4 * t, 0.55);
        let a = 0.6 * f64::from(k);
        views.push([p.x, p.y, p.z, a.cos(), a.sin(), -0.1]);
    }
    // Straight down (the page finds the camera's up on its own).
    let p = lo + (hi - lo) * DVec3::new(0.3, 0.5, 0.55);
    views.push([p.x, p.y, p.z, 0.0, 0.0, -1.0]);
    // And one from outside the view box: every object in the frustum.
    let c = (lo + hi) * 0.5;
    views.push([c.x, c.y, hi.z + 1.0, 1.0, 0.0, -0.3]);

    let scene = vis5d::scene::load(root().join("scenes/apartment.obj")).unwrap();
    let tracer = Tracer::new(&scene);
    let mut checked = 0;
    for (tree, pvs) in pvs.iter().enumerate() {
        let frames = fly(chromium, &server, tree, &views);
        let mut missing = 0;
        for f in &frames {
            // What the page drew is the library's answer for the page's view.
            let ask = ask_of(f["url"].as_str().unwrap());
            let (visible, leaf) = ask.answer(pvs);
            assert_eq!(indices(&f["drawn"]), visible, "{f}");
            assert_eq!(f["leaf"].as_u64().map(|l| l as u32), leaf, "{f}");
            assert!(f["seen"].as_u64().unwrap() > 0, "{f}");
            // The page's id render sees what rays see: every object of 16
            // pixels or more in one is in the other (edges and slivers
            // differ between rasterising and casting).
            let (w, h) = (f["width"].as_u64().unwrap(), f["height"].as_u64().unwrap());
            let page: HashMap<u32, u64> = f["seenPixels"]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| (p[0].as_u64().unwrap() as u32, p[1].as_u64().unwrap()))
                .collect();
            let view = View::look(
                ask.pos.as_vec3(),
                ask.dir,
                ask.up,
                ask.fov.to_radians(),
                ask.aspect,
            )
            .to_local(&scene.frame(), ask.pos);
            let camera = Camera::new(&view, w as u32, h as u32).unwrap();
            let rays: HashMap<u32, u64> = IdBuffer::render(&tracer, &camera)
                .object_pixels(scene.objects().len())
                .into_iter()
                .collect();
            for (a, b, what) in [(&page, &rays, "page"), (&rays, &page, "rays")] {
                for (o, &n) in a {
                    assert!(n < 16 || b.contains_key(o), "{what} sees {o} ({n} px): {f}");
                }
            }
            checked += 1;
            // An object marked red is seen and outside the set.
            for i in indices(&f["missing"]) {
                assert!(!visible.contains(&i), "{f}");
            }
            missing += f["missing"].as_array().unwrap().len();
        }
        assert_eq!(frames.last().unwrap()["answer"], "everything");
        assert!(frames.last().unwrap()["leaf"].is_null());
        if tree == 1 {
            assert!(missing > 0, "the poor tree drops nothing the page sees");
        }
    }
    assert_eq!(checked, 2 * views.len());
}

/// Without a tree the page draws every object and flies (no query).
#[test]
fn without_a_tree_the_page_draws_everything() {
    let Some(chromium) = chromium() else { return };
    let server = start("scenes/apartment.obj", &[]);
    let (status, body) = get(&server, "/api/query?pos=1,1,1&dir=1,0,0");
    assert_eq!(status, 400);
    assert!(text(&body).contains("--pvs"), "{}", text(&body));
    let dom = dump_dom(
        chromium,
        &format!("http://{}/?pos=2,2,1.5&dir=0,0,-1", server.address),
    );
    assert!(!dom.contains("failed"), "{dom}");
    assert!(dom.contains("<b id=\"objects\">174 of 174</b>"), "{dom}");
}
