//! Where the oracle's Depth Maps are rasterised: on the GPU (wgpu) when an
//! adapter exists, else on the CPU reference, the choice made once, here,
//! for every caller (`vis5d oracle`, `vis5d check`, `vis5d report`, the
//! library).
//!
//! The two rasterisers answer the same question with the same guarantee
//! (a pixel is written only where an occluder's Projection covers it
//! entirely, with a Depth never below the true one); the GPU may leave out
//! a few more pixels along slanted edges. A map that fails on the GPU (a
//! lost device, an out-of-memory error) is redone on the CPU, and the
//! failure is counted for the caller to report.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};

#[cfg(feature = "gpu")]
use super::oracle_gpu::GpuRasteriser;
use super::oracle_plane::{MapJob, ProjectedOccluder, cpu_rasterise};

/// The rasteriser of an [`Oracle`](super::Oracle)'s Depth Maps: the CPU
/// reference, or the GPU with the CPU as a fallback per map.
#[derive(Debug)]
pub struct Rasteriser {
    #[cfg(feature = "gpu")]
    gpu: Option<Box<GpuRasteriser>>,
    /// Why the CPU is used when the GPU was asked for.
    cpu_reason: Option<String>,
    /// Maps the GPU failed and the CPU redid.
    gpu_failures: AtomicU64,
    /// The first such failure.
    first_failure: OnceLock<String>,
}

impl Rasteriser {
    /// The CPU reference rasteriser.
    pub fn cpu() -> Self {
        Self {
            #[cfg(feature = "gpu")]
            gpu: None,
            cpu_reason: None,
            gpu_failures: AtomicU64::new(0),
            first_failure: OnceLock::new(),
        }
    }

    /// The GPU rasteriser `gpu`, with the CPU as a fallback per map.
    #[cfg(feature = "gpu")]
    pub fn gpu(gpu: GpuRasteriser) -> Self {
        Self {
            gpu: Some(Box::new(gpu)),
            ..Self::cpu()
        }
    }

    /// The best there is: the GPU when an adapter opens (with the `gpu`
    /// feature: `GpuRasteriser::new`), else the CPU, with the reason kept
    /// in [`Rasteriser::cpu_reason`].
    pub fn best() -> Self {
        #[cfg(feature = "gpu")]
        {
            match GpuRasteriser::new() {
                Ok(g) => Self::gpu(g),
                Err(e) => Self {
                    cpu_reason: Some(e.to_string()),
                    ..Self::cpu()
                },
            }
        }
        #[cfg(not(feature = "gpu"))]
        {
            Self {
                cpu_reason: Some("vis5d was built without its `gpu` feature".into()),
                ..Self::cpu()
            }
        }
    }

    /// Whether maps go to the GPU.
    pub fn is_gpu(&self) -> bool {
        #[cfg(feature = "gpu")]
        {
            self.gpu.is_some()
        }
        #[cfg(not(feature = "gpu"))]
        {
            false
        }
    }

    /// "CPU", or "GPU: " and the adapter's name.
    pub fn name(&self) -> String {
        #[cfg(feature = "gpu")]
        if let Some(g) = &self.gpu {
            return format!("GPU: {}", g.adapter_name());
        }
        "CPU".into()
    }

    /// Why [`Rasteriser::best`] fell back to the CPU (no adapter, no
    /// `gpu` feature); `None` on the GPU or when the CPU was asked for.
    pub fn cpu_reason(&self) -> Option<&str> {
        self.cpu_reason.as_deref()
    }

    /// How many maps failed on the GPU and were redone on the CPU, and the
    /// first failure's message.
    pub fn gpu_failures(&self) -> (u64, Option<&str>) {
        (
            self.gpu_failures.load(Ordering::Relaxed),
            self.first_failure.get().map(String::as_str),
        )
    }

    /// The GPU rasteriser, if maps go to the GPU (the shrinking oracle
    /// draws its cube maps on the same device).
    #[cfg(feature = "gpu")]
    pub(crate) fn gpu_device(&self) -> Option<&GpuRasteriser> {
        self.gpu.as_deref()
    }

    /// Counts `maps` maps that failed on the GPU (and were made on the
    /// CPU), keeping the first failure's message.
    #[cfg(feature = "gpu")]
    pub(crate) fn note_gpu_failure(&self, maps: u64, message: String) {
        self.gpu_failures.fetch_add(maps, Ordering::Relaxed);
        let _ = self.first_failure.set(message);
    }

    /// Several level-0 maps, `(side, occluders)` each: on the GPU in one
    /// submission (all redone on the CPU if it fails), else on the CPU.
    pub fn rasterise_many(&self, jobs: &[MapJob]) -> Vec<Vec<f64>> {
        #[cfg(feature = "gpu")]
        if let Some(g) = &self.gpu {
            match g.rasterise_many(jobs) {
                Ok(maps) => return maps,
                Err(e) => {
                    self.gpu_failures
                        .fetch_add(jobs.len() as u64, Ordering::Relaxed);
                    let _ = self.first_failure.set(e.to_string());
                }
            }
        }
        // Independent maps: on as many threads as are free.
        use rayon::prelude::*;
        jobs.par_iter().map(|&(n, o)| cpu_rasterise(n, o)).collect()
    }

    /// The `n` x `n` level-0 map of `occluders` (see [`cpu_rasterise`]).
    pub fn rasterise(&self, n: usize, occluders: &[ProjectedOccluder]) -> Vec<f64> {
        #[cfg(feature = "gpu")]
        if let Some(g) = &self.gpu {
            match g.rasterise(n, occluders) {
                Ok(map) => return map,
                Err(e) => {
                    self.gpu_failures.fetch_add(1, Ordering::Relaxed);
                    let _ = self.first_failure.set(e.to_string());
                }
            }
        }
        cpu_rasterise(n, occluders)
    }
}
