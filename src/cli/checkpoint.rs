//! `vis5d build --checkpoint DIR`: each finished subtree of the fixed top
//! saved as it completes (`DIR/subtree-I.v5d`, written atomically), and
//! read back on a restart after a kill, so that the build picks up where
//! it stopped and writes the same bytes as an uninterrupted one. A
//! checkpoint that does not decode, or that another build made (another
//! scene, other parameters or ids), is refused with a message naming it,
//! never used.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::{Context, Result, bail};
use vis5d::builder::BuildParams;
use vis5d::codec::{self, Coding, V5dFile};
use vis5d::scene::Scene;
use vis5d::tree::VisTree;

/// A checkpoint folder for one build.
pub struct Checkpoints<'a> {
    dir: PathBuf,
    scene: &'a Scene,
    params: &'a BuildParams,
    ids: Option<&'a [String]>,
    /// The first error writing a checkpoint (reported after the build).
    failed: Mutex<Option<anyhow::Error>>,
}

/// The file name of subtree `index`'s checkpoint.
fn file_name(index: u32) -> String {
    format!("subtree-{index}.v5d")
}

impl<'a> Checkpoints<'a> {
    /// The folder `dir` (made when missing) for the build of `scene` with
    /// `params` and object ids `ids`.
    pub fn open(
        dir: &Path,
        scene: &'a Scene,
        params: &'a BuildParams,
        ids: Option<&'a [String]>,
    ) -> Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot make the checkpoint folder", dir.display()))?;
        if !dir.is_dir() {
            bail!("{}: the checkpoint folder is not a folder", dir.display());
        }
        Ok(Self {
            dir: dir.to_owned(),
            scene,
            params,
            ids,
            failed: Mutex::new(None),
        })
    }

    /// The file a checkpoint of `tree` holds: the subtree with the
    /// build's fingerprint, frame, parameters and objects.
    fn file_of(&self, tree: VisTree) -> V5dFile {
        let mut file = vis5d::builder::to_file(self.scene, tree, self.params, Some(Coding::Parent));
        crate::build::set_ids(&mut file, self.ids);
        file
    }

    /// The subtrees saved so far, checked: (index, tree), in index order.
    pub fn read(&self) -> Result<Vec<(u32, VisTree)>> {
        let mut out = Vec::new();
        let entries = std::fs::read_dir(&self.dir)
            .with_context(|| format!("{}: cannot list the checkpoints", self.dir.display()))?;
        for entry in entries {
            let entry = entry
                .with_context(|| format!("{}: cannot list the checkpoints", self.dir.display()))?;
            let name = entry.file_name();
            let Some(index) = name
                .to_str()
                .and_then(|n| n.strip_prefix("subtree-"))
                .and_then(|n| n.strip_suffix(".v5d"))
                .and_then(|n| n.parse::<u32>().ok())
            else {
                // Not a checkpoint (an atomic write's leftover, a user's
                // file): left alone.
                continue;
            };
            let path = entry.path();
            let refuse = |why: String| {
                anyhow::anyhow!(
                    "{}: {why}; remove it (or the whole folder) to build that part again",
                    path.display()
                )
            };
            let limits = codec::ReadLimits::default();
            let bytes = vis5d::input::read_regular(&path, limits.max_file_bytes)
                .with_context(|| format!("{}: cannot read the checkpoint", path.display()))?;
            let file = codec::read_file(&bytes, limits)
                .map_err(|e| refuse(format!("a damaged checkpoint ({e})")))?;
            // This build writes its tree to exactly these bytes: the
            // same scene, parameters, ids and tree (object bounds are
            // quantised in a file, so the decoded fields would not
            // compare with the scene's).
            if codec::write_file(&self.file_of(file.tree.clone())) != bytes {
                return Err(refuse(
                    "a checkpoint of another build (another scene, other parameters or ids)"
                        .to_owned(),
                ));
            }
            out.push((index, file.tree));
        }
        out.sort_by_key(|&(i, _)| i);
        Ok(out)
    }

    /// Saves subtree `index` (atomically); an error is kept for
    /// [`Checkpoints::finish`].
    pub fn save(&self, index: u32, tree: &VisTree) {
        let path = self.dir.join(file_name(index));
        let bytes = codec::write_file(&self.file_of(tree.clone()));
        if let Err(e) = vis5d::atomic_write::write_atomic(&path, &bytes) {
            let mut failed = self.failed.lock().unwrap_or_else(|p| p.into_inner());
            failed.get_or_insert_with(|| {
                anyhow::anyhow!("{}: cannot write the checkpoint: {e}", path.display())
            });
        }
    }

    /// The first error saving a checkpoint, if any.
    pub fn finish(self) -> Result<()> {
        match self.failed.into_inner().unwrap_or_else(|p| p.into_inner()) {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}
