//! What the commands share: value parsers for the flags, reading the
//! inputs (scenes, `.v5d` files, camera paths) with clear errors, progress
//! bars, and the tree summary printed by `build` and `stat`.

use std::io::{self, IsTerminal, Write};
use std::path::Path;
use std::sync::OnceLock;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use glam::{DVec3, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use vis5d::codec::{self, Coding, code_size};
use vis5d::geom::{Aabb, Frame};
use vis5d::query::View;
use vis5d::scene::{self, LoadOptions, Scene};
use vis5d::tree::{TreeSummary, VisTree};

/// A name from a file (an object, a parameter), safe to print as text:
/// control characters (a newline, a terminal escape) are escaped as in
/// Rust string literals, so a crafted name cannot forge lines of output or
/// drive the terminal. JSON output escapes on its own.
pub fn printable(name: &str) -> std::borrow::Cow<'_, str> {
    if name.chars().any(char::is_control) {
        name.chars()
            .map(|c| {
                if c.is_control() {
                    c.escape_default().to_string()
                } else {
                    c.to_string()
                }
            })
            .collect::<String>()
            .into()
    } else {
        name.into()
    }
}

/// The flag of a library parameter: `grid_cell` is `--grid-cell`.
pub fn flag(parameter: &str) -> String {
    format!("--{}", parameter.replace('_', "-"))
}

/// Refuses, before any work, an output that would destroy an input or
/// something that is not an earlier output: `output` the same file as one
/// of `inputs` (under any spelling), an existing `output` that is not a
/// regular file (a device, a FIFO, a folder), or a folder that does not
/// exist.
pub fn check_output(output: &Path, what: &str, inputs: &[&Path]) -> Result<()> {
    let dir = output
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !dir.is_dir() {
        bail!(
            "{}: cannot write the {what} there: {} is not a folder",
            output.display(),
            dir.display()
        );
    }
    for input in inputs {
        if vis5d::atomic_write::same_file(output, input) {
            bail!(
                "{}: refusing to write the {what} over the input {}: name another output with -o",
                output.display(),
                input.display()
            );
        }
    }
    if let Ok(m) = std::fs::metadata(output)
        && !m.is_file()
    {
        bail!(
            "{}: refusing to write the {what} there: it exists and is not a regular file",
            output.display()
        );
    }
    Ok(())
}

/// A box of positions in world coordinates, as typed on the command line:
/// parsed in f64, so that a georeferenced position keeps its precision
/// until it meets the scene's frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldBox {
    /// The smallest corner.
    pub min: DVec3,
    /// The largest corner.
    pub max: DVec3,
}

impl WorldBox {
    /// The box in `frame`'s local coordinates, rounded outwards.
    pub fn to_local(self, frame: &Frame) -> Aabb {
        frame.box_to_local(self.min, self.max)
    }

    /// The centre point.
    pub fn center(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }
}

/// Parses `x0,y0,z0,x1,y1,z1` (world coordinates).
pub fn parse_box(s: &str) -> Result<WorldBox, String> {
    let v = parse_numbers(s)?;
    if v.len() != 6 {
        return Err(format!(
            "expected 6 numbers x0,y0,z0,x1,y1,z1, got {}",
            v.len()
        ));
    }
    let b = WorldBox {
        min: DVec3::new(v[0], v[1], v[2]),
        max: DVec3::new(v[3], v[4], v[5]),
    };
    if !(b.min.is_finite() && b.max.is_finite() && b.min.cmplt(b.max).all()) {
        return Err("the box needs finite corners with x0 < x1, y0 < y1, z0 < z1".into());
    }
    Ok(b)
}

/// Comma-separated numbers, parsed in f64.
fn parse_numbers(s: &str) -> Result<Vec<f64>, String> {
    s.split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
        .collect()
}

/// Parses a point `x,y,z` (world coordinates, f64).
pub fn parse_point(s: &str) -> Result<DVec3, String> {
    match parse_numbers(s)?[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(DVec3::new(x, y, z)),
        [_, _, _] => Err("the coordinates must be finite".into()),
        ref v => Err(format!("expected 3 numbers x,y,z, got {}", v.len())),
    }
}

/// Parses `a,b`.
pub fn parse_pair(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or("expected two numbers a,b")?;
    let p = |x: &str| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}"));
    Ok((p(a)?, p(b)?))
}

/// Parses a direction `x,y,z` (f32: directions need no frame).
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let p = parse_point(s)?;
    let v = p.as_vec3();
    if !v.is_finite() {
        return Err("the coordinates must be finite in f32".into());
    }
    Ok(v)
}

/// Loads a scene (+z up) with a progress bar on a terminal.
pub fn load_scene(path: &Path) -> Result<(Scene, f64)> {
    load_scene_up(path, vis5d::geom::Up::Z)
}

/// Loads a scene whose up axis is `up` ([`vis5d::scene::Scene::with_up`]),
/// with a progress bar on a terminal.
pub fn load_scene_up(path: &Path, up: vis5d::geom::Up) -> Result<(Scene, f64)> {
    let bar = if io::stderr().is_terminal() {
        let bar = ProgressBar::new(0).with_style(
            ProgressStyle::with_template("loading {msg} [{bar:30}] {bytes}/{total_bytes} {eta}")
                .expect("the template is valid")
                .progress_chars("=> "),
        );
        bar.set_message(path.display().to_string());
        bar
    } else {
        ProgressBar::hidden()
    };
    let start = Instant::now();
    // Loading holds the file and the scene made of it: about 3-9 times
    // the file's size (notes/reliability.md).
    if let Ok(m) = std::fs::metadata(path) {
        crate::memory::check(
            m.len().saturating_mul(LOAD_BYTES_PER_FILE_BYTE),
            &format!("loading {}", path.display()),
            "load a smaller scene, or give the run more memory",
        )?;
    }
    let options = LoadOptions {
        up,
        ..LOAD_OPTIONS.get_or_init(LoadOptions::default).clone()
    };
    let result = scene::load_with(path, &options, &mut |done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    Ok((result?, start.elapsed().as_secs_f64()))
}

/// What to add to a "built for another scene" error when the file was
/// built with another up axis than the scene was loaded with (else
/// nothing).
pub fn up_hint(file: vis5d::geom::Up, scene: vis5d::geom::Up) -> String {
    if file == scene {
        String::new()
    } else {
        format!(
            " (the file was built with --up {file}, the scene loaded with --up {scene}: pass --up {file})"
        )
    }
}

/// Reads and decodes a `.v5d` file (a regular file, within the decoder's
/// limits).
pub fn read_v5d(path: &Path) -> Result<(Vec<u8>, codec::V5dFile)> {
    let limits = codec::ReadLimits::default();
    let bytes = vis5d::input::read_regular(path, limits.max_file_bytes)
        .with_context(|| format!("{}: cannot read the .v5d file", path.display()))?;
    let file =
        codec::read_file(&bytes, limits).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok((bytes, file))
}

/// The largest views file read: 256 MiB, some four million views.
const MAX_VIEWS_BYTES: u64 = 256 << 20;

/// Memory a scene takes while loading, per byte of its file (measured 2.8
/// on the 35 MB forest, 4.4 on San Francisco, 8.7 on the 0.9 MB duplex
/// where fixed costs dominate; notes/reliability.md).
const LOAD_BYTES_PER_FILE_BYTE: u64 = 10;

/// How scenes are read (`--allow-outside-paths`), set once by `main`.
static LOAD_OPTIONS: OnceLock<LoadOptions> = OnceLock::new();

/// Sets how every command reads scenes; the first call wins.
pub fn set_load_options(options: LoadOptions) {
    let _ = LOAD_OPTIONS.set(options);
}

/// One view of a views file (`query --views`, `report --views`).
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ViewSpec {
    pos: [f64; 3],
    dir: [f32; 3],
    /// Square field of view, degrees.
    fov: Option<f32>,
    /// Up direction.
    up: Option<[f32; 3]>,
    /// Vertical field of view, degrees (with `aspect`).
    vfov: Option<f32>,
    /// Width over height (with `vfov`).
    aspect: Option<f32>,
}

/// What a view that does not say takes: the square field of view and the
/// up direction of `query`'s `--fov` and `--up`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewDefaults {
    /// Square field of view, degrees.
    pub fov: f32,
    /// The up direction (world); `None`: the tree's up axis.
    pub up: Option<Vec3>,
}

impl Default for ViewDefaults {
    fn default() -> Self {
        Self {
            fov: 90.0,
            up: None,
        }
    }
}

/// A view whose eye is in world coordinates (f64, as read), to be put in
/// a scene's or a tree's frame before it is used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldView {
    /// The eye, world coordinates.
    pub position: DVec3,
    /// The rest of the view, its directions in world axes (its `position`
    /// is the eye in f32, for nothing but messages).
    pub view: View,
    /// Whether the view's up was given; else it is the frame's up axis
    /// (the next axis when looking straight along it).
    pub up_given: bool,
}

impl WorldView {
    /// A square view from `position` (see [`View::square`]), its up the
    /// frame's.
    pub fn square(position: DVec3, dir: Vec3, fov_degrees: f32) -> Self {
        Self {
            position,
            view: View::square(position.as_vec3(), dir, fov_degrees),
            up_given: false,
        }
    }

    /// The view in `frame`'s local coordinates (the eye at the nearest
    /// local point, the directions turned).
    pub fn local(&self, frame: &Frame) -> View {
        let mut view = self.view;
        if !self.up_given {
            view.up = default_up(frame.up, view.dir);
        }
        view.to_local(frame, self.position)
    }

    /// The box of eye positions (the eye and its radius) in `frame`'s
    /// local coordinates, rounded outwards.
    pub fn positions(&self, frame: &Frame) -> Aabb {
        let r = DVec3::splat(f64::from(self.view.radius.max(0.0)));
        frame.box_to_local(self.position - r, self.position + r)
    }
}

/// The world up direction of a view along `dir` that does not say: the
/// `up` axis, or the axis after it when `dir` is (nearly) along it.
pub fn default_up(up: vis5d::geom::Up, dir: Vec3) -> Vec3 {
    let u = up.world_vector();
    if dir.normalize_or_zero().dot(u).abs() > 0.999 {
        let mut v = Vec3::ZERO;
        v[up.world_axis(1)] = 1.0;
        v
    } else {
        u
    }
}

/// The help's description of a views file.
pub const VIEWS_HELP: &str = "a JSON list of {\"pos\": [x,y,z], \"dir\": [x,y,z]} with, optionally, \"fov\": degrees (square) or \"vfov\": degrees and \"aspect\": width/height, and \"up\": [x,y,z]";

/// Reads a views file: a JSON list of `{"pos": [x,y,z], "dir": [x,y,z]}`,
/// each optionally with `"fov"` (a square field of view, degrees) or
/// `"vfov"` (vertical, degrees) and `"aspect"` (width over height), and
/// `"up"`; positions and directions in world coordinates. A view without
/// a field of view or an up direction takes `defaults`'.
pub fn read_views(path: &Path, defaults: ViewDefaults) -> Result<Vec<WorldView>> {
    let bytes = vis5d::input::read_regular(path, MAX_VIEWS_BYTES)
        .with_context(|| format!("{}: cannot read the views", path.display()))?;
    let text = String::from_utf8(bytes)
        .with_context(|| format!("{}: the views are not UTF-8 text", path.display()))?;
    let specs: Vec<ViewSpec> = serde_json::from_str(&text)
        .with_context(|| format!("{}: expected {VIEWS_HELP}", path.display()))?;
    specs
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let bad = |what: &str| anyhow::anyhow!("{}: view {i}: {what}", path.display());
            let (pos, dir) = (DVec3::from_array(v.pos), Vec3::from_array(v.dir));
            if !(pos.is_finite() && dir.is_finite() && dir != Vec3::ZERO) {
                return Err(bad("needs a finite pos and a finite, non-zero dir"));
            }
            let angle = |name: &str, a: f32| {
                if a > 0.0 && a < 180.0 {
                    Ok(a)
                } else {
                    Err(bad(&format!("{name} must be above 0 and below 180 degrees")))
                }
            };
            let mut view = match (v.fov, v.vfov, v.aspect) {
                (Some(_), Some(_), _) => return Err(bad("give fov (square) or vfov, not both")),
                (_, None, Some(_)) => return Err(bad("aspect needs vfov")),
                (fov, None, None) => {
                    WorldView::square(pos, dir, angle("fov", fov.unwrap_or(defaults.fov))?)
                }
                (None, Some(vfov), aspect) => {
                    let vfov = angle("vfov", vfov)?.to_radians();
                    let aspect = aspect.unwrap_or(1.0);
                    if !(aspect.is_finite() && aspect > 0.0) {
                        return Err(bad("aspect must be finite and above 0"));
                    }
                    let view = View::look(pos.as_vec3(), dir, Vec3::Z, vfov, aspect);
                    if view.fov_x.is_nan() || view.fov_x >= std::f32::consts::PI {
                        return Err(bad("vfov and aspect make a horizontal field of view of 180 degrees or more"));
                    }
                    WorldView {
                        position: pos,
                        view,
                        up_given: false,
                    }
                }
            };
            if let Some(up) = v.up.map(Vec3::from_array).or(defaults.up) {
                if !(up.is_finite() && up.cross(dir).length() > 1e-3 * up.length() * dir.length()) {
                    return Err(bad("up must be finite and not along dir"));
                }
                view.view.up = up;
                view.up_given = true;
            }
            Ok(view)
        })
        .collect()
}

/// A progress bar on a terminal, hidden otherwise.
pub fn progress_bar(what: &str, len: u64) -> ProgressBar {
    if !io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len).with_style(
        ProgressStyle::with_template(
            "{msg} [{bar:30}] {percent}% of view space {elapsed} (eta {eta})",
        )
        .expect("the template is valid")
        .progress_chars("=> "),
    );
    bar.set_message(what.to_owned());
    bar
}

/// A local point shown in world coordinates: the f32 values as they are
/// for the identity frame, the f64 world values otherwise (as
/// [`Frame::world_text`]); `(x, y, z)` as text, `[x, y, z]` in JSON.
#[derive(Clone, Copy, Debug)]
pub struct World(pub Frame, pub Vec3);

impl std::fmt::Display for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text = self.0.world_text(self.1).replace(',', ", ");
        write!(f, "({text})")
    }
}

impl Serialize for World {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if self.0.is_identity() {
            self.1.to_array().serialize(s)
        } else {
            // The short decimals of the text form (500123.7, not
            // 500123.69999980927), as numbers.
            let text = self.0.world_text(self.1);
            let mut w = self.0.to_world(self.1).to_array();
            for (c, t) in w.iter_mut().zip(text.split(',')) {
                *c = t.parse().unwrap_or(*c);
            }
            w.serialize(s)
        }
    }
}

/// A tree's shape and set sizes, as `build` and `stat` report them.
#[derive(Serialize)]
pub struct ShapeReport {
    nodes: usize,
    leaves: usize,
    depth: u32,
    mean_leaf_objects: f64,
    max_leaf_objects: usize,
    mean_leaf_triangles: f64,
    max_leaf_triangles: u64,
    measure_weighted_leaf_objects: f64,
}

impl From<TreeSummary> for ShapeReport {
    fn from(s: TreeSummary) -> Self {
        Self {
            nodes: s.nodes,
            leaves: s.leaves,
            depth: s.depth,
            mean_leaf_objects: s.mean_leaf_objects,
            max_leaf_objects: s.max_leaf_objects,
            mean_leaf_triangles: s.mean_leaf_triangles,
            max_leaf_triangles: s.max_leaf_triangles,
            measure_weighted_leaf_objects: s.measure_weighted_objects,
        }
    }
}

/// Prints the view box and the tree's shape, for `build` and `stat`.
pub fn print_shape(
    out: &mut impl Write,
    [min, max]: [World; 2],
    t: &ShapeReport,
) -> io::Result<()> {
    writeln!(out, "  view box         {min} .. {max}")?;
    if !min.0.is_identity() {
        let o = min.0.origin;
        writeln!(out, "  frame origin     ({}, {}, {})", o.x, o.y, o.z)?;
    }
    writeln!(
        out,
        "  tree             {} nodes, {} leaves, depth {}",
        t.nodes, t.leaves, t.depth
    )?;
    writeln!(
        out,
        "  leaf sets        mean {:.1} objects ({:.0} triangles), max {} objects ({} triangles)",
        t.mean_leaf_objects, t.mean_leaf_triangles, t.max_leaf_objects, t.max_leaf_triangles
    )?;
    writeln!(
        out,
        "                   {:.1} objects for a random view ray (measure-weighted)",
        t.measure_weighted_leaf_objects
    )
}

/// The size of a tree in one coding.
#[derive(Serialize)]
pub struct CodingSize {
    pub coding: String,
    pub structure_bits: u64,
    pub set_bits: u64,
    pub bytes: u64,
}

pub fn coding_sizes(tree: &VisTree) -> Vec<CodingSize> {
    Coding::ALL
        .iter()
        .map(|&c| {
            let s = code_size(tree, c);
            CodingSize {
                coding: c.name().to_owned(),
                structure_bits: s.structure_bits,
                set_bits: s.set_bits,
                bytes: s.bytes(),
            }
        })
        .collect()
}

/// The scene with the flags of the sidecar at `path` (`--flags`) added
/// to those the model gives (a glTF node's `extras.vis5d.flags`),
/// checked before the build.
pub fn with_flags(path: Option<&Path>, scene: Scene) -> Result<Scene> {
    let Some(path) = path else {
        return Ok(scene);
    };
    let bytes = vis5d::input::read_regular(path, 64 << 20)
        .with_context(|| format!("{}: cannot read the flags", path.display()))?;
    let user: std::collections::HashMap<String, Vec<String>> = serde_json::from_slice(&bytes)
        .with_context(|| {
            format!(
                "{}: expected a JSON object from default ids (names, or name#k where names repeat) \
                 to lists of flags (always_visible, never_occluder)",
                path.display()
            )
        })?;
    let ids = vis5d::codec::default_ids(scene.objects().iter().map(|o| o.name.as_str()));
    let flags: Vec<_> = vis5d::codec::flags_from_names(&ids, &user)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?
        .into_iter()
        .zip(scene.objects())
        .map(|(f, o)| f.union(o.flags))
        .collect();
    Ok(scene.with_flags(&flags))
}
