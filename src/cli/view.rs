//! `vis5d view`: a local web viewer of a scene and its trees.
//!
//! An HTTP server (axum on a one-thread tokio runtime) serves a page
//! (`view/index.html`, `view/viewer.js`) that draws the scene with
//! three.js (vendored under `view/vendor/`, so that the page works without
//! a network), and a small JSON API the page asks once a frame:
//! - `GET /api/info`: the scene's objects (names, triangles), its up
//!   axis and bounds, and the loaded trees;
//! - `GET /api/scene.glb`: the scene as binary glTF, one node per object in
//!   the file's order ([`vis5d::scene::write_glb`]);
//! - `GET /api/query?pos=x,y,z&dir=x,y,z[&up=x,y,z][&fov=deg][&aspect=a][&pvs=k]`:
//!   the objects of the view's answer (`Pvs::query_view_from`, as `vis5d
//!   query` answers it) and the leaf holding the eye and the direction;
//! - `GET /api/cell?pos=x,y,z[&dir=x,y,z][&pvs=k]`: that leaf's cell.
//!
//! Every position is in world coordinates (those of the model, as `vis5d
//! query` takes them). Bad parameters get a 400 with a message.

use std::collections::HashMap;
use std::io::Write as _;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use axum::Router;
use axum::extract::{Query, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use clap::Args;
use glam::{DVec3, Vec3};
use vis5d::geom::cell::{DIMS, PHI, THETA, direction_to_angles};
use vis5d::geom::{Frame, Up};
use vis5d::query::{Answer, Pvs, View};
use vis5d::scene::Scene;

use crate::common::{WorldView, default_up, load_scene_up, parse_point, printable};

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// The scene: OBJ, glTF (.gltf) or binary glTF (.glb).
    model: PathBuf,
    /// A .v5d file built for the scene (`vis5d build`, sampled or
    /// conservative); repeat it to switch between trees in the page. Each
    /// is checked against the scene's fingerprint. Without one the page
    /// draws every object.
    #[arg(long, value_name = "FILE.v5d")]
    pvs: Vec<PathBuf>,
    /// The address to listen on. The default serves this machine only;
    /// 0.0.0.0 serves every network the machine is on (the viewer has no
    /// authentication: anyone who reaches it sees the scene).
    #[arg(long, default_value = "127.0.0.1")]
    host: IpAddr,
    /// The port to listen on (0: any free port; the address is printed).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// The scene's up axis, without --pvs [default: z]; with --pvs the
    /// trees' own (the axis they were built with).
    #[arg(long, value_name = "AXIS")]
    up: Option<Up>,
}

/// A loaded tree and what the page shows of it.
struct Tree {
    /// The file's name, as given.
    name: String,
    pvs: Pvs,
}

/// What the handlers share.
struct Viewer {
    scene_name: String,
    frame: Frame,
    /// Per object: name and triangle count.
    objects: Vec<(String, u32)>,
    /// World bounds of the scene.
    bounds: (DVec3, DVec3),
    /// The scene as binary glTF (shared, not copied, per request).
    glb: axum::body::Bytes,
    trees: Vec<Tree>,
}

/// The page and the scripts it loads, with their content types.
const FILES: &[(&str, &str, &str)] = &[
    (
        "/",
        "text/html; charset=utf-8",
        include_str!("view/index.html"),
    ),
    (
        "/viewer.js",
        "text/javascript; charset=utf-8",
        include_str!("view/viewer.js"),
    ),
    (
        "/vendor/three.module.min.js",
        "text/javascript; charset=utf-8",
        include_str!("view/vendor/three.module.min.js"),
    ),
    (
        "/vendor/three.core.min.js",
        "text/javascript; charset=utf-8",
        include_str!("view/vendor/three.core.min.js"),
    ),
    (
        "/vendor/addons/loaders/GLTFLoader.js",
        "text/javascript; charset=utf-8",
        include_str!("view/vendor/addons/loaders/GLTFLoader.js"),
    ),
    (
        "/vendor/addons/utils/BufferGeometryUtils.js",
        "text/javascript; charset=utf-8",
        include_str!("view/vendor/addons/utils/BufferGeometryUtils.js"),
    ),
    (
        "/vendor/LICENSE",
        "text/plain; charset=utf-8",
        include_str!("view/vendor/LICENSE"),
    ),
];

/// Runs `vis5d view`.
pub fn run(args: &ViewArgs) -> Result<()> {
    let viewer = load(args)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .enable_time()
        .build()
        .context("cannot start the server's runtime")?;
    runtime.block_on(serve(args, viewer))
}

/// Loads the trees and the scene, checking that they belong together.
fn load(args: &ViewArgs) -> Result<Viewer> {
    let mut trees = Vec::new();
    for path in &args.pvs {
        let pvs = Pvs::load(path)?;
        trees.push(Tree {
            name: path.display().to_string(),
            pvs,
        });
    }
    let up = match (trees.first(), args.up) {
        (Some(first), Some(up)) if first.pvs.frame().up != up => bail!(
            "{}: the tree was built with --up {}, not --up {up}: leave --up out",
            first.name,
            first.pvs.frame().up
        ),
        (Some(first), _) => first.pvs.frame().up,
        (None, up) => up.unwrap_or(Up::Z),
    };
    for t in &trees {
        if t.pvs.frame().up != up {
            bail!(
                "{}: the tree was built with --up {}, {} with --up {up}: the trees are of different scenes",
                t.name,
                t.pvs.frame().up,
                trees[0].name
            );
        }
    }
    let (scene, _) = load_scene_up(&args.model, up)?;
    for t in &trees {
        t.pvs
            .check_fingerprint(scene.fingerprint())
            .map_err(|e| anyhow::anyhow!("{}: {e}", t.name))?;
    }
    viewer_of(&scene, &args.model.display().to_string(), trees)
}

/// The viewer's state for a loaded scene and its trees.
fn viewer_of(scene: &Scene, name: &str, trees: Vec<Tree>) -> Result<Viewer> {
    let frame = scene.frame();
    let objects = scene
        .objects()
        .iter()
        .map(|o| (o.name.clone(), o.triangles.end - o.triangles.start))
        .collect();
    let mut glb = Vec::new();
    vis5d::scene::write_glb(scene, &mut glb)
        .with_context(|| format!("{name}: cannot serve the scene as glTF"))?;
    Ok(Viewer {
        scene_name: name.to_owned(),
        frame,
        objects,
        bounds: frame.box_to_world(&scene.bounds()),
        glb: glb.into(),
        trees,
    })
}

/// Listens and serves until the process is stopped.
async fn serve(args: &ViewArgs, viewer: Viewer) -> Result<()> {
    let address = SocketAddr::new(args.host, args.port);
    let listener = tokio::net::TcpListener::bind(address)
        .await
        .with_context(|| format!("cannot listen on {address}"))?;
    let bound = listener.local_addr()?;
    let url = match bound.ip() {
        IpAddr::V4(ip) if ip.is_unspecified() => {
            format!("http://{}:{}/", Ipv4Addr::LOCALHOST, bound.port())
        }
        IpAddr::V6(ip) if ip.is_unspecified() => format!("http://[::1]:{}/", bound.port()),
        IpAddr::V6(ip) => format!("http://[{ip}]:{}/", bound.port()),
        IpAddr::V4(ip) => format!("http://{ip}:{}/", bound.port()),
    };
    let trees = if viewer.trees.is_empty() {
        "no tree (pass --pvs FILE.v5d to cull)".to_owned()
    } else {
        viewer
            .trees
            .iter()
            .map(|t| t.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    // The address on stdout, for scripts (a closed stdout does not stop
    // the server).
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{url}").and_then(|()| out.flush());
    drop(out);
    say!(
        "vis5d view: {} with {trees}, on {url} (mouse and W A S D to fly; Ctrl-C to stop)",
        printable(&viewer.scene_name)
    );
    let mut app = router(Arc::new(viewer));
    if bound.ip().is_loopback() {
        app = app.layer(axum::middleware::from_fn(local_only));
    }
    axum::serve(listener, app)
        .await
        .context("the server stopped")
}

/// The routes.
fn router(viewer: Arc<Viewer>) -> Router {
    let mut app = Router::new()
        .route("/api/info", get(info))
        .route("/api/scene.glb", get(scene_glb))
        .route("/api/query", get(query))
        .route("/api/cell", get(cell));
    for &(path, kind, body) in FILES {
        app = app.route(
            path,
            get(move || async move { ([(header::CONTENT_TYPE, kind)], body) }),
        );
    }
    app.fallback(|| async { (StatusCode::NOT_FOUND, "no such page\n") })
        .with_state(viewer)
}

/// Refuses a request that names another host than this machine: a
/// server on the loopback address answers only pages of the loopback
/// address (a web page elsewhere that points a name of its own at
/// 127.0.0.1, "DNS rebinding", gets a 403 instead of the scene).
async fn local_only(request: axum::extract::Request, next: axum::middleware::Next) -> Response {
    let host = request
        .headers()
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    let name = match host.rsplit_once(':') {
        Some((name, port)) if port.bytes().all(|b| b.is_ascii_digit()) => name,
        _ => host,
    };
    if ["127.0.0.1", "localhost", "[::1]", ""].contains(&name.to_ascii_lowercase().as_str()) {
        next.run(request).await
    } else {
        (
            StatusCode::FORBIDDEN,
            format!(
                "Host {:?}: this viewer listens on the loopback address and answers only \
                 http://127.0.0.1 or http://localhost (start it with --host to serve others)\n",
                short(host)
            ),
        )
            .into_response()
    }
}

/// At most 40 characters of `s`, for messages that quote the input.
fn short(s: &str) -> String {
    match s.char_indices().nth(40) {
        Some((end, _)) => format!("{}...", &s[..end]),
        None => s.to_owned(),
    }
}

/// A 400 with a message.
fn bad(message: impl Into<String>) -> Response {
    (StatusCode::BAD_REQUEST, message.into() + "\n").into_response()
}

/// A JSON 200.
fn json(value: serde_json::Value) -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        value.to_string(),
    )
        .into_response()
}

async fn info(State(v): State<Arc<Viewer>>) -> Response {
    let trees: Vec<_> = v
        .trees
        .iter()
        .map(|t| {
            let (min, max) = t.pvs.frame().box_to_world(&t.pvs.view_box());
            serde_json::json!({
                "name": t.name,
                "conservative": t.pvs.is_conservative(),
                "nodes": t.pvs.node_count(),
                "view_box": {"min": min.to_array(), "max": max.to_array()},
            })
        })
        .collect();
    let objects: Vec<_> = v
        .objects
        .iter()
        .map(|(name, triangles)| serde_json::json!({"name": name, "triangles": triangles}))
        .collect();
    json(serde_json::json!({
        "scene": v.scene_name,
        "up": v.frame.up.world_vector().to_array(),
        "bounds": {"min": v.bounds.0.to_array(), "max": v.bounds.1.to_array()},
        "triangles": v.objects.iter().map(|o| u64::from(o.1)).sum::<u64>(),
        "objects": objects,
        "pvs": trees,
    }))
}

async fn scene_glb(State(v): State<Arc<Viewer>>) -> Response {
    ([(header::CONTENT_TYPE, "model/gltf-binary")], v.glb.clone()).into_response()
}

/// The parameters of a query, checked.
struct Asked<'a> {
    tree: &'a Tree,
    pos: DVec3,
    dir: Vec3,
    view: WorldView,
}

/// Reads a query's parameters: `pos` and `dir` required, the rest
/// optional; an error message for the 400 otherwise.
/// A query string's parameters, each named once.
fn parameters(pairs: Vec<(String, String)>) -> Result<HashMap<String, String>, String> {
    let mut q = HashMap::new();
    for (k, v) in pairs {
        if q.contains_key(&k) {
            return Err(format!("{} is given twice", short(&k)));
        }
        q.insert(k, v);
    }
    Ok(q)
}

fn asked<'a>(v: &'a Viewer, q: &HashMap<String, String>) -> Result<Asked<'a>, String> {
    for k in q.keys() {
        if !["pos", "dir", "up", "fov", "aspect", "pvs"].contains(&k.as_str()) {
            return Err(format!(
                "unknown parameter {:?} (known: pos, dir, up, fov, aspect, pvs)",
                short(k)
            ));
        }
    }
    let tree = match q.get("pvs") {
        _ if v.trees.is_empty() => {
            return Err("no tree is loaded: start the viewer with --pvs FILE.v5d to query".into());
        }
        None => &v.trees[0],
        Some(k) => {
            let k: usize = k
                .parse()
                .map_err(|_| format!("pvs={:?}: expected a tree's index", short(k)))?;
            v.trees.get(k).ok_or_else(|| {
                format!(
                    "pvs={k}: there are {} trees (0 to {})",
                    v.trees.len(),
                    v.trees.len() - 1
                )
            })?
        }
    };
    let vector = |name: &str| -> Result<Option<DVec3>, String> {
        q.get(name)
            .map(|s| parse_point(s).map_err(|e| format!("{name}={:?}: {}", short(s), short(&e))))
            .transpose()
    };
    let pos = vector("pos")?.ok_or("pos=x,y,z is required")?;
    let dir = vector("dir")?.ok_or("dir=x,y,z is required")?.as_vec3();
    if !(dir.is_finite() && dir.length() > 0.0) {
        return Err("dir must be a finite vector, not zero".into());
    }
    let up = match vector("up")? {
        Some(u) => {
            let u = u.as_vec3();
            if !(u.is_finite() && u.cross(dir).length() > 1e-3 * u.length() * dir.length()) {
                return Err("up must be finite and not along dir".into());
            }
            u
        }
        None => default_up(v.frame.up, dir),
    };
    let number = |name: &str, default: f32| -> Result<f32, String> {
        q.get(name).map_or(Ok(default), |s| {
            s.trim()
                .parse::<f32>()
                .map_err(|e| format!("{name}={:?}: {e}", short(s)))
        })
    };
    let fov = number("fov", 90.0)?;
    if !(fov > 0.0 && fov < 180.0) {
        return Err(format!(
            "fov={fov}: the vertical field of view must be between 0 and 180 degrees"
        ));
    }
    let aspect = number("aspect", 1.0)?;
    if !(aspect > 0.0 && aspect.is_finite()) {
        return Err(format!(
            "aspect={aspect}: width over height must be a number above 0"
        ));
    }
    let look = View::look(pos.as_vec3(), dir, up, fov.to_radians(), aspect);
    if look.fov_x >= std::f32::consts::PI {
        return Err(format!(
            "aspect={aspect}: with fov={fov} the horizontal field of view comes to 180 degrees"
        ));
    }
    let view = WorldView {
        position: pos,
        view: look,
        up_given: true,
    };
    Ok(Asked {
        tree,
        pos,
        dir,
        view,
    })
}

/// The ray point of an eye and a direction in the tree's frame.
fn ray_point(frame: &Frame, pos: DVec3, dir: Vec3) -> [f32; DIMS] {
    let p = frame.to_local(pos);
    let (theta, phi) = direction_to_angles(frame.dir_to_local(dir));
    [p.x, p.y, p.z, theta, phi]
}

async fn query(State(v): State<Arc<Viewer>>, Query(q): Query<Vec<(String, String)>>) -> Response {
    let a = match parameters(q).and_then(|q| asked(&v, &q)) {
        Ok(a) => a,
        Err(e) => return bad(e),
    };
    let pvs = &a.tree.pvs;
    let frame = pvs.frame();
    let mut set = pvs.new_set();
    let answer =
        match pvs.query_view_from(&a.view.positions(&frame), &a.view.local(&frame), &mut set) {
            Ok(answer) => answer,
            Err(e) => return bad(e.to_string()),
        };
    let visible: Vec<usize> = set.iter().collect();
    let triangles: u64 = visible.iter().map(|&i| u64::from(v.objects[i].1)).sum();
    // The leaf where the eye is; none where the answer is every object
    // (the eye's box, rounded outwards, leaves the view box).
    let leaf = match answer {
        Answer::Tree => pvs.leaf_at(ray_point(&frame, a.pos, a.dir)).map(|l| l.0),
        _ => None,
    };
    json(serde_json::json!({
        "visible": visible,
        "leaf": leaf,
        "answer": if answer == Answer::Tree { "tree" } else { "everything" },
        "triangles": triangles,
    }))
}

async fn cell(State(v): State<Arc<Viewer>>, Query(q): Query<Vec<(String, String)>>) -> Response {
    let mut q = match parameters(q) {
        Ok(q) => q,
        Err(e) => return bad(e),
    };
    for k in ["up", "fov", "aspect"] {
        if q.contains_key(k) {
            return bad(format!("unknown parameter {k:?} (known: pos, dir, pvs)"));
        }
    }
    // Without a direction: the leaf of the horizontal direction along the
    // frame's first axis (theta 0, phi 90 degrees).
    q.entry("dir".into()).or_insert_with(|| {
        let d = v.frame.dir_to_world(Vec3::X);
        format!("{},{},{}", d.x, d.y, d.z)
    });
    let a = match asked(&v, &q) {
        Ok(a) => a,
        Err(e) => return bad(e),
    };
    let frame = a.tree.pvs.frame();
    let Some((leaf, c)) = a.tree.pvs.leaf_at(ray_point(&frame, a.pos, a.dir)) else {
        // Outside the view box no leaf answers (every object is drawn).
        return json(serde_json::json!({"leaf": null}));
    };
    let (min, max) = frame.box_to_world(&c.space());
    json(serde_json::json!({
        "leaf": leaf,
        "min": min.to_array(),
        "max": max.to_array(),
        "theta": [c.lo[THETA], c.hi[THETA]],
        "phi": [c.lo[PHI], c.hi[PHI]],
    }))
}
