//! `vis5d query`: the objects visible from views, answered from a `.v5d`.

use std::io::{self, Write};
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use glam::{DVec3, Vec3};
use vis5d::query::{Answer, Pvs};

use crate::common::{
    ViewDefaults, World, WorldBox, WorldView, load_scene_up, parse_box, parse_point, parse_vec3,
    printable, read_views,
};

#[derive(Args, Debug)]
pub struct QueryArgs {
    /// The .v5d file.
    file: PathBuf,
    /// The eye position, x,y,z (world coordinates).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true, required_unless_present_any = ["views", "box"])]
    pos: Option<DVec3>,
    /// A box of eye positions instead of a point, x0,y0,z0,x1,y1,z1 (world
    /// coordinates).
    #[arg(id = "box", long = "box", value_name = "X0,Y0,Z0,X1,Y1,Z1", value_parser = parse_box, allow_hyphen_values = true, conflicts_with = "pos")]
    positions: Option<WorldBox>,
    /// The viewing direction, x,y,z.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true, required_unless_present = "views")]
    dir: Option<Vec3>,
    /// The up direction, world coordinates [default: the up axis the
    /// tree was built with (`build --up`), or the axis after it when
    /// looking straight along it]; with --views, for the views that do not
    /// give theirs.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    up: Option<Vec3>,
    /// The field of view in degrees, horizontal and vertical [above 0,
    /// below 180; default 90]; with --views, for the views that do not
    /// give theirs.
    #[arg(long, allow_hyphen_values = true)]
    fov: Option<f32>,
    /// Answer every view of this JSON file instead: a list of {"pos":
    /// [x,y,z], "dir": [x,y,z]}, each optionally with "fov" (square,
    /// degrees) or "vfov" (vertical, degrees) and "aspect" (width over
    /// height), and "up": [x,y,z]; world coordinates.
    #[arg(long, value_name = "VIEWS.json", conflicts_with_all = ["pos", "box", "dir"])]
    views: Option<PathBuf>,
    /// The scene the file should have been built for: refuse the file if
    /// its geometry fingerprint differs.
    #[arg(long, value_name = "MODEL")]
    scene: Option<PathBuf>,
    /// Print as JSON: a list of names, or with --views a list of lists.
    #[arg(long)]
    json: bool,
    /// Print the objects' ids instead of their names (unique: the name,
    /// `name#k` where names repeat, the model's own id (a glTF node's
    /// `extras.vis5d.id`) or the build's `--ids`); with --json, each
    /// object as {"index", "id", "name", "flags"} (flags: the model's and
    /// the build's `--flags`, a list of names, omitted when empty).
    #[arg(long, conflicts_with = "triangles")]
    ids: bool,
    /// Also print, per object, the ranges of its triangles to draw
    /// (indices into the object's triangles, in the model's order): those
    /// of the slices not proved hidden, for a file built with --slices;
    /// else all of them. JSON: objects as {"object", "triangles",
    /// "ranges": [[first, end), ...]}.
    #[arg(long)]
    triangles: bool,
}

/// An object of an answer, for --ids --json.
#[derive(serde::Serialize)]
struct IdJson<'a> {
    index: usize,
    id: &'a str,
    name: &'a str,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    flags: Vec<&'static str>,
}

/// An object's triangles to draw, for --triangles --json.
#[derive(serde::Serialize)]
struct TrianglesJson<'a> {
    object: &'a str,
    triangles: u64,
    ranges: Vec<[u32; 2]>,
}

/// Runs `vis5d query`.
pub fn run(args: &QueryArgs) -> Result<()> {
    // The views first (flags and file): bad ones are refused before the
    // tree is read.
    let fov = args.fov.unwrap_or(90.0);
    if !(fov > 0.0 && fov < 180.0) {
        bail!("--fov must be between 0 and 180 degrees");
    }
    if let Some(up) = args.up
        && !(up.is_finite() && up != Vec3::ZERO)
    {
        bail!("--up must be finite and not the zero vector");
    }
    let defaults = ViewDefaults { fov, up: args.up };
    let views: Vec<WorldView> = match &args.views {
        Some(path) => read_views(path, defaults)?,
        None => {
            let dir = args.dir.expect("clap requires --dir without --views");
            if dir == Vec3::ZERO {
                bail!("--dir must not be the zero vector");
            }
            let pos = match (args.pos, args.positions) {
                (_, Some(b)) => b.center(),
                (Some(p), None) => p,
                (None, None) => unreachable!("clap requires --pos or --box"),
            };
            let mut v = WorldView::square(pos, dir, fov);
            if let Some(up) = args.up {
                if up.cross(dir).length() <= 1e-3 * up.length() * dir.length() {
                    bail!("--up must not be along --dir");
                }
                v.view.up = up;
                v.up_given = true;
            }
            vec![v]
        }
    };
    let pvs = Pvs::load(&args.file)?;
    if let Some(model) = &args.scene {
        let (scene, _) = load_scene_up(model, pvs.frame().up)?;
        pvs.check_fingerprint(scene.fingerprint()).map_err(|e| {
            anyhow::anyhow!(
                "{}: {e}{}",
                args.file.display(),
                crate::common::up_hint(pvs.frame().up, scene.frame().up)
            )
        })?;
    }
    // Each answer is printed as it comes (a long camera path is never
    // held whole).
    let mut set = pvs.new_set();
    let mut out = io::BufWriter::new(io::stdout().lock());
    let many = args.views.is_some();
    if args.json && many {
        write!(out, "[")?;
    }
    // Positions meet the tree's frame in f64, rounded outwards.
    let frame = pvs.frame();
    for (i, v) in views.iter().enumerate() {
        let positions = match args.positions {
            Some(b) => b.to_local(&frame),
            None => v.positions(&frame),
        };
        let v = v.local(&frame);
        let answer = pvs.query_view_from(&positions, &v, &mut set)?;
        if answer == Answer::Everything {
            eprintln!(
                "note: {}: every object in the frustum: the eye lies outside the view box the tree was built for ({} .. {})",
                if many {
                    format!("view {i}")
                } else {
                    "the view".to_owned()
                },
                World(frame, pvs.view_box().min),
                World(frame, pvs.view_box().max)
            );
        }
        if args.triangles {
            let r = vis5d::query::frustum_angles(v.dir, v.up, v.fov_x, v.fov_y);
            let drawn = pvs.triangles_of(&positions, r.boxes(), &set)?;
            let rows: Vec<TrianglesJson> = drawn
                .iter()
                .map(|d| TrianglesJson {
                    object: pvs.object(d.object as usize).map_or("", |o| o.name()),
                    triangles: d.count(),
                    ranges: d.ranges.iter().map(|r| [r.start, r.end]).collect(),
                })
                .collect();
            if args.json {
                if many && i > 0 {
                    write!(out, ",")?;
                }
                serde_json::to_writer(&mut out, &rows)?;
            } else {
                let total: u64 = rows.iter().map(|r| r.triangles).sum();
                let all: u64 = set
                    .iter()
                    .filter_map(|o| pvs.object(o))
                    .map(|o| u64::from(o.triangles()))
                    .sum();
                if many {
                    writeln!(out, "# view {i}: {} objects", rows.len())?;
                }
                writeln!(
                    out,
                    "# {total} of the {all} triangles of {} objects to draw{}",
                    rows.len(),
                    if pvs.slices().is_some() {
                        ""
                    } else {
                        " (the file has no slices: build it with --slices N)"
                    }
                )?;
                for r in &rows {
                    let ranges: Vec<String> = r
                        .ranges
                        .iter()
                        .map(|[a, b]| {
                            if b - a == 1 {
                                a.to_string()
                            } else {
                                format!("{a}-{}", b - 1)
                            }
                        })
                        .collect();
                    writeln!(
                        out,
                        "{}: {} triangles: {}",
                        printable(r.object),
                        r.triangles,
                        ranges.join(",")
                    )?;
                }
            }
            continue;
        }
        let names: Vec<&str> = set
            .iter()
            .filter_map(|o| pvs.object(o))
            .map(|o| if args.ids { o.id() } else { o.name() })
            .collect();
        if args.json {
            if many && i > 0 {
                write!(out, ",")?;
            }
            if args.ids {
                let rows: Vec<IdJson> = set
                    .iter()
                    .filter_map(|o| Some((o, pvs.object(o)?)))
                    .map(|(index, o)| IdJson {
                        index,
                        id: o.id(),
                        name: o.name(),
                        flags: o.flags().names().collect(),
                    })
                    .collect();
                serde_json::to_writer(&mut out, &rows)?;
            } else {
                serde_json::to_writer(&mut out, &names)?;
            }
        } else {
            if many {
                writeln!(out, "# view {i}: {} objects", names.len())?;
            }
            for n in names {
                writeln!(out, "{}", printable(n))?;
            }
        }
    }
    if args.json {
        if many {
            write!(out, "]")?;
        }
        writeln!(out)?;
    }
    out.flush()?;
    Ok(())
}
