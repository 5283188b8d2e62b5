//! `vis5d stat`: a `.v5d` file's header, its tree's shape and the size of
//! each coding.

use std::io::{self, Write};
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use glam::Vec3;
use serde::Serialize;
use vis5d::tree::LeafRecord;

use crate::common::{
    CodingSize, ShapeReport, World, coding_sizes, print_shape, printable, read_v5d,
};

#[derive(Args, Debug)]
pub struct StatArgs {
    /// The .v5d file.
    file: PathBuf,
    /// Print as JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// `stat`'s report.
#[derive(Serialize)]
struct StatReport {
    file: String,
    file_bytes: usize,
    version: u16,
    coding: String,
    grid_bits: u32,
    objects: usize,
    fingerprint: String,
    /// "sampled" or "conservative".
    method: &'static str,
    /// In the tree's local coordinates: world = P^-1(local) +
    /// `frame_origin`, P the turn that puts the `up` axis on local z.
    root_cell: [[f32; 5]; 2],
    frame_origin: [f64; 3],
    /// The scene's up axis (local z), "x", "y" or "z".
    up: String,
    params: Vec<(String, String)>,
    #[serde(flatten)]
    tree: ShapeReport,
    coding_sizes: Vec<CodingSize>,
    /// How sure the leaves' sets are (files from version 3).
    leaf_records: Option<RecordSummary>,
    /// The leaves' hidden slices (files from version 4 built with
    /// --slices).
    slices: Option<SliceSummary>,
}

/// A file's slices, summarised.
#[derive(Serialize)]
struct SliceSummary {
    /// Slices an axis.
    slices: usize,
    /// Pieces over all objects.
    pieces: usize,
    /// Leaves with some hidden slices.
    leaves_with_slices: usize,
    /// (leaf, object) pairs with hidden slices.
    entries: usize,
    /// Over the leaves, the mean fraction of the triangles of a leaf's
    /// set that its slices cull.
    mean_culled_fraction: f64,
}

fn summarise_slices(file: &vis5d::codec::V5dFile) -> Option<SliceSummary> {
    let s = file.slices.as_ref()?;
    let leaves = file.tree.leaves();
    let mut fraction = 0.0;
    for (rank, leaf) in leaves.iter().enumerate() {
        let set = &file.tree.nodes()[leaf.node].set;
        let all: u64 = set
            .iter()
            .map(|o| u64::from(file.objects[o].triangles))
            .sum();
        let culled: usize = s.leaves[rank]
            .iter()
            .map(|(o, indices)| {
                let pieces = s.sliced.pieces(*o as usize);
                pieces
                    .iter()
                    .zip(indices)
                    .map(|(p, &i)| p.culled_count(i))
                    .sum::<usize>()
            })
            .sum();
        fraction += culled as f64 / all.max(1) as f64;
    }
    let objects = file.objects.len();
    Some(SliceSummary {
        slices: s.sliced.slices(),
        pieces: (0..objects).map(|o| s.sliced.pieces(o).len()).sum(),
        leaves_with_slices: s.leaves.iter().filter(|l| !l.is_empty()).count(),
        entries: s.leaves.iter().map(Vec::len).sum(),
        mean_culled_fraction: fraction / leaves.len().max(1) as f64,
    })
}

/// The leaf records of a file, summarised: what the residual risk of its
/// leaves rests on.
#[derive(Serialize)]
struct RecordSummary {
    /// Leaves where some object was called invisible on ray evidence.
    leaves_with_rejections: usize,
    /// Objects called invisible, per leaf, on average.
    mean_rejected: f64,
    /// The fewest misses behind any rejection of any leaf.
    fewest_rays: u32,
    /// The largest visible fraction an object called invisible could
    /// have, at 95% confidence, in the least sure leaf.
    largest_missed_fraction_95: f64,
    /// Objects kept without a decision, per leaf, on average.
    mean_undecided: f64,
}

fn summarise_records(records: &[LeafRecord]) -> RecordSummary {
    let n = records.len().max(1) as f64;
    let rejecting: Vec<&LeafRecord> = records.iter().filter(|r| r.rejected > 0).collect();
    RecordSummary {
        leaves_with_rejections: rejecting.len(),
        mean_rejected: records.iter().map(|r| r.rejected as f64).sum::<f64>() / n,
        fewest_rays: rejecting.iter().map(|r| r.fewest_rays).min().unwrap_or(0),
        largest_missed_fraction_95: records
            .iter()
            .map(|r| r.largest_missed_fraction(0.95))
            .fold(0.0, f64::max),
        mean_undecided: records.iter().map(|r| r.undecided as f64).sum::<f64>() / n,
    }
}

/// Runs `vis5d stat`.
pub fn run(args: &StatArgs) -> Result<()> {
    let (bytes, file) = read_v5d(&args.file)?;
    let tree = &file.tree;
    let triangles: Vec<u64> = file.objects.iter().map(|o| o.triangles as u64).collect();
    let summary = tree.summarize(&triangles);
    let root = tree.root_cell();
    let report = StatReport {
        file: args.file.display().to_string(),
        file_bytes: bytes.len(),
        version: u16::from_le_bytes([bytes[8], bytes[9]]),
        coding: file.coding.name().to_owned(),
        grid_bits: tree.grid_bits(),
        objects: file.objects.len(),
        fingerprint: format!("{:016x}", file.fingerprint),
        method: if vis5d::codec::params_say_conservative(&file.params) {
            "conservative"
        } else {
            "sampled"
        },
        root_cell: [root.lo, root.hi],
        frame_origin: file.frame.origin.to_array(),
        up: file.frame.up.to_string(),
        params: file
            .params
            .lines()
            .filter_map(|l| l.split_once('='))
            .map(|(k, v)| (k.to_owned(), v.to_owned()))
            .collect(),
        tree: summary.into(),
        coding_sizes: coding_sizes(tree),
        leaf_records: tree.leaf_records().map(summarise_records),
        slices: summarise_slices(&file),
    };
    let mut out = io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
        return Ok(());
    }
    let r = &report;
    writeln!(
        out,
        "{}: .v5d version {}, {} bytes",
        r.file, r.version, r.file_bytes
    )?;
    writeln!(
        out,
        "  coding           {} (q = {} bits per split value)",
        r.coding, r.grid_bits
    )?;
    writeln!(
        out,
        "  method           {}",
        if r.method == "conservative" {
            "conservative (the oracle's sets: no visible object is ever missing)"
        } else {
            "sampled (objects tested by rays)"
        }
    )?;
    writeln!(out, "  objects          {}", r.objects)?;
    writeln!(out, "  scene            fingerprint {}", r.fingerprint)?;
    writeln!(
        out,
        "  up axis          {} (directions' angles: phi from it, theta about it)",
        r.up
    )?;
    let space = [
        World(file.frame, Vec3::new(root.lo[0], root.lo[1], root.lo[2])),
        World(file.frame, Vec3::new(root.hi[0], root.hi[1], root.hi[2])),
    ];
    print_shape(&mut out, space, &r.tree)?;
    writeln!(out, "  coded tree size  structure bits + set bits = bytes")?;
    for c in &r.coding_sizes {
        let mark = if c.coding == r.coding {
            "  (this file)"
        } else {
            ""
        };
        writeln!(
            out,
            "    {:<8} {:>10} + {:>12} = {:>10} B{mark}",
            c.coding, c.structure_bits, c.set_bits, c.bytes
        )?;
    }
    match &r.leaf_records {
        Some(l) => writeln!(
            out,
            "  leaf records     {} leaves rejected objects on ray evidence ({:.1} a leaf, at least {} misses each: \
             a fraction over {:.2}% would have shown at 95%); {:.1} objects a leaf kept undecided",
            l.leaves_with_rejections,
            l.mean_rejected,
            l.fewest_rays,
            100.0 * l.largest_missed_fraction_95,
            l.mean_undecided
        )?,
        None if r.method == "conservative" => writeln!(
            out,
            "  leaf records     none (conservative: no set rests on ray evidence)"
        )?,
        None => writeln!(out, "  leaf records     none (a file before version 3)")?,
    }
    match &r.slices {
        Some(s) => writeln!(
            out,
            "  slices           {} an axis, {} pieces; {} of the leaves have hidden slices ({} objects), \
             culling {:.1}% of a leaf's triangles on average",
            s.slices,
            s.pieces,
            s.leaves_with_slices,
            s.entries,
            100.0 * s.mean_culled_fraction
        )?,
        None => writeln!(
            out,
            "  slices           none (objects drawn whole; build with --slices N)"
        )?,
    }
    writeln!(out, "  build parameters")?;
    for (k, v) in &r.params {
        writeln!(out, "    {:<22} {}", printable(k), printable(v))?;
    }
    Ok(())
}
