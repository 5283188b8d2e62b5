//! `vis5d info`: load a scene and say what loading found.

use std::io::{self, Write};
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use serde::Serialize;

use crate::common::{World, load_scene};

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// The scene file (.obj, .gltf or .glb).
    file: PathBuf,
    /// Print the summary as JSON (with every object) instead of text.
    #[arg(long)]
    json: bool,
    /// List every object (index, name, triangles, area, bounds; empty
    /// objects, groups of the model with no triangle of non-zero area, are
    /// listed too: they keep the model's indices but are never visible).
    #[arg(long)]
    objects: bool,
}

/// One object in `info --json`.
#[derive(Serialize)]
struct ObjectInfo<'a> {
    index: usize,
    name: &'a str,
    triangles: usize,
    area: f64,
    /// None for an empty object (no triangles, no box).
    bounds: Option<[World; 2]>,
}

/// The summary printed by `info`.
#[derive(Serialize)]
struct SceneInfo<'a> {
    file: String,
    format: String,
    objects: usize,
    triangles: usize,
    /// World coordinates.
    bounds: [World; 2],
    /// Where the scene's local frame sits (absent for the identity).
    #[serde(skip_serializing_if = "Option::is_none")]
    frame_origin: Option<[f64; 3]>,
    size: [f32; 3],
    surface_area: f64,
    load_seconds: f64,
    dropped_degenerate_triangles: usize,
    /// The indices of the empty objects.
    empty_objects: &'a [usize],
    skipped_non_triangles: usize,
    duplicate_names: Vec<DuplicateName<'a>>,
    object_list: Vec<ObjectInfo<'a>>,
}

#[derive(Serialize)]
struct DuplicateName<'a> {
    name: &'a str,
    count: usize,
}

/// Runs `vis5d info`.
pub fn run(args: &InfoArgs) -> Result<()> {
    let (scene, seconds) = load_scene(&args.file)?;
    let b = scene.bounds();
    let frame = scene.frame();
    let report = scene.report();
    let summary = SceneInfo {
        file: args.file.display().to_string(),
        format: scene.format().to_string(),
        objects: scene.objects().len(),
        triangles: scene.triangles().len(),
        bounds: [World(frame, b.min), World(frame, b.max)],
        frame_origin: (!frame.at_world_origin()).then(|| frame.origin.to_array()),
        size: b.size().to_array(),
        surface_area: scene.objects().iter().map(|o| o.area).sum(),
        load_seconds: seconds,
        dropped_degenerate_triangles: report.dropped_degenerate,
        empty_objects: &report.empty_objects,
        skipped_non_triangles: report.skipped_non_triangles,
        duplicate_names: report
            .duplicate_names
            .iter()
            .map(|(name, count)| DuplicateName {
                name,
                count: *count,
            })
            .collect(),
        object_list: scene
            .objects()
            .iter()
            .enumerate()
            .map(|(index, o)| ObjectInfo {
                index,
                name: &o.name,
                triangles: o.triangle_count(),
                area: o.area,
                bounds: (!o.is_empty())
                    .then_some([World(frame, o.bounds.min), World(frame, o.bounds.max)]),
            })
            .collect(),
    };
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, &summary)?;
        writeln!(out)?;
        return Ok(());
    }
    print_info(&mut out, &summary, args.objects)?;
    Ok(())
}

fn print_info(out: &mut impl Write, s: &SceneInfo, all_objects: bool) -> io::Result<()> {
    let [min, max] = s.bounds;
    let size = s.size;
    writeln!(out, "{} ({})", s.file, s.format)?;
    writeln!(out, "  objects          {}", s.objects)?;
    writeln!(out, "  triangles        {}", s.triangles)?;
    writeln!(out, "  bounds           {min} .. {max}")?;
    if let Some([x, y, z]) = s.frame_origin {
        writeln!(
            out,
            "  frame origin     ({x}, {y}, {z}): far from the origin, the scene is held relative to it"
        )?;
    }
    writeln!(
        out,
        "  size             {} x {} x {}",
        size[0], size[1], size[2]
    )?;
    writeln!(out, "  surface area     {:.6}", s.surface_area)?;
    writeln!(out, "  loaded in        {:.3} s", s.load_seconds)?;
    writeln!(
        out,
        "  dropped          {} zero-area triangles",
        s.dropped_degenerate_triangles,
    )?;
    if !s.empty_objects.is_empty() {
        // A note, not an error: the groups keep their places (and the
        // model's indices) but have no surface.
        let shown: Vec<String> = s
            .empty_objects
            .iter()
            .take(if all_objects { usize::MAX } else { 10 })
            .map(|&i| format!("#{i} {:?}", s.object_list[i].name))
            .collect();
        writeln!(
            out,
            "  empty objects    {} without a triangle of non-zero area (listed, never visible): {}{}",
            s.empty_objects.len(),
            shown.join(", "),
            if shown.len() < s.empty_objects.len() {
                ", ... (--objects lists them all)"
            } else {
                ""
            }
        )?;
    }
    writeln!(
        out,
        "  skipped          {} lines and points",
        s.skipped_non_triangles
    )?;
    if s.duplicate_names.is_empty() {
        writeln!(out, "  duplicate names  none")?;
    } else {
        let total: usize = s.duplicate_names.iter().map(|d| d.count).sum();
        writeln!(
            out,
            "  duplicate names  {} names shared by {} objects (objects are told apart by index):",
            s.duplicate_names.len(),
            total
        )?;
        for d in s
            .duplicate_names
            .iter()
            .take(if all_objects { usize::MAX } else { 10 })
        {
            writeln!(out, "    {:?} x{}", d.name, d.count)?;
        }
        if !all_objects && s.duplicate_names.len() > 10 {
            writeln!(out, "    ... (--objects lists them all)")?;
        }
    }
    let mut listed: Vec<&ObjectInfo> = s.object_list.iter().collect();
    if all_objects {
        writeln!(out, "  objects:")?;
    } else {
        listed.sort_by_key(|o| std::cmp::Reverse(o.triangles));
        listed.truncate(5);
        writeln!(out, "  largest objects (--objects lists all):")?;
    }
    for o in listed {
        writeln!(
            out,
            "    #{:<6} {:>9} tris  area {:<12.4} {:?}",
            o.index, o.triangles, o.area, o.name
        )?;
    }
    Ok(())
}
