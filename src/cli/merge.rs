//! `vis5d merge`: the parts of a sharded build (`vis5d build --shard`)
//! joined into the `.v5d` file a single build writes.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use vis5d::codec;

use crate::common::check_output;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// The parts, one per shard, in any order (`vis5d build --shard I/N
    /// -o PART`).
    #[arg(required = true, value_name = "PART")]
    parts: Vec<PathBuf>,
    /// Where to write the tree (written atomically).
    #[arg(short, long, value_name = "FILE.v5d")]
    output: PathBuf,
}

/// Runs `vis5d merge`.
pub fn run(args: &MergeArgs) -> Result<()> {
    let inputs: Vec<&std::path::Path> = args.parts.iter().map(PathBuf::as_path).collect();
    check_output(&args.output, "tree", &inputs)?;
    let limits = codec::ReadLimits::default();
    let mut parts = Vec::with_capacity(args.parts.len());
    for path in &args.parts {
        // A part holds up to 1,024 subtree files, each within a file's
        // limit: read up to 4 GiB.
        let bytes = vis5d::input::read_regular(path, 4 << 30)
            .with_context(|| format!("{}: cannot read the part", path.display()))?;
        let part = codec::read_part(&bytes, limits).map_err(|e| match e {
            codec::CodecError::NotV5d => anyhow::anyhow!(
                "{}: not a part of a sharded build (made by `vis5d build --shard I/N`)",
                path.display()
            ),
            e => anyhow::anyhow!("{}: {e}", path.display()),
        })?;
        parts.push(part);
    }
    let names: Vec<String> = args.parts.iter().map(|p| p.display().to_string()).collect();
    let file = vis5d::builder::merge(parts)
        .map_err(|e| anyhow::anyhow!("cannot merge {}: {e}", names.join(", ")))?;
    file.tree
        .validate()
        .map_err(|e| anyhow::anyhow!("the merged tree is inconsistent: {e}"))?;
    let bytes = codec::write_file(&file);
    vis5d::atomic_write::write_atomic(&args.output, &bytes)
        .with_context(|| format!("{}: cannot write the tree", args.output.display()))?;
    say!(
        "merged {} parts into {}: {} nodes, {} bytes",
        args.parts.len(),
        args.output.display(),
        file.tree.nodes().len(),
        bytes.len()
    );
    Ok(())
}
