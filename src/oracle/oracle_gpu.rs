//! GPU rasterisation of extended-projection occluders into a Depth Map
//! (papers/001 sec. 3.2 and appendix A), the twin of the CPU rasteriser.
//!
//! Each occluder comes as its views from the corners of the view cell
//! (convex polygons in the pixel coordinates of the map) and its Depth. A
//! pixel belongs to the occluder's extended projection when it lies
//! entirely inside every view; the map keeps, per pixel, the smallest Depth
//! of the occluders it belongs to. The result feeds a "never wrong"
//! occlusion oracle, so every step errs on one side only: a pixel may be
//! left out (the map is then less useful) but never written where no
//! occluder covers it entirely, and a stored Depth is never below the true
//! one.
//!
//! How it is done:
//!
//! 1. **Erosion (CPU, f64).** A pixel square lies inside a convex polygon
//!    iff its centre lies inside the polygon eroded by the square, and for
//!    a half-plane with unit inward normal `(nx, ny)` that erosion moves
//!    the edge inward by `0.5 * (|nx| + |ny|)` pixels. Each view is eroded
//!    that way plus a margin of 1/16 pixel (GPUs snap vertices to a
//!    sub-pixel grid and round in f32), so the GPU's pixel-centre sampling
//!    of the eroded polygon only ever picks pixels entirely inside the
//!    view. Edges that
//!    are exactly horizontal or vertical are placed on the integer pixel
//!    boundary instead, which is exact (see `erode_view`).
//! 2. **Stencil counting (GPU).** Per occluder, view `i` is drawn with the
//!    stencil test `Equal(i)` and `IncrementClamp`, with no colour or depth
//!    write: after its `k` views a pixel holds `k` iff every view covered
//!    it. The test (rather than a blind increment) makes overlapping
//!    triangles of one view harmless: the second one finds `i + 1` and
//!    leaves it. A quad over the occluder's bounding box is then drawn with
//!    `Equal(k)`, writing the Depth (colour) and keeping the smallest
//!    (depth test); its stencil operations reset every pixel to 0 for the
//!    next occluder.
//! 3. **Batching.** Occluders whose bounding boxes are disjoint share draw
//!    calls (view `i` of all of them in one draw, then all their quads),
//!    so a map costs `k + 1` draws per batch rather than per occluder, all
//!    in one vertex buffer, one render pass and one submission.

use std::ops::Range;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};

use glam::DVec2;
use wgpu::util::DeviceExt;

use crate::geom::polygon::{clip_half_plane, rectangle, signed_area};

pub use super::oracle_plane::{MapJob, ProjectedOccluder};

/// GPU failures: no adapter, device lost, validation error, readback
/// failure.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No Vulkan, Metal or DirectX 12 adapter was found.
    #[error(
        "no GPU adapter found for Vulkan, Metal or DirectX 12 (the OpenGL backend is not used); \
         on Linux without a GPU, install Mesa's CPU Vulkan driver: \
         apt-get install mesa-vulkan-drivers libvulkan1"
    )]
    NoAdapter,
    /// The adapter was found but a device could not be opened on it.
    #[error("could not open a GPU device on {adapter}: {message}")]
    RequestDevice {
        /// The adapter's name and backend.
        adapter: String,
        /// What wgpu said.
        message: String,
    },
    /// The adapter lacks something the rasteriser needs.
    #[error("the GPU adapter {adapter} cannot rasterise depth maps: {message}")]
    Unsupported {
        /// The adapter's name and backend.
        adapter: String,
        /// What is missing.
        message: String,
    },
    /// The request itself is invalid (map size, number of views).
    #[error("invalid depth map request: {0}")]
    InvalidInput(String),
    /// The GPU reported a validation, out-of-memory or internal error.
    #[error("the GPU reported an error while rasterising the depth map: {0}")]
    Gpu(String),
    /// The device was lost (driver reset, GPU removed).
    #[error("the GPU device was lost: {0}")]
    DeviceLost(String),
    /// The finished map could not be copied back from the GPU.
    #[error("could not read the depth map back from the GPU: {0}")]
    Readback(String),
}

/// Extra inward shift of every slanted eroded edge, in pixels, so that GPU
/// rasterisation cannot pick a pixel centre outside the exactly eroded
/// polygon. Vulkan snaps vertices to a grid of at least 4 sub-pixel bits
/// (`subPixelPrecisionBits >= 4`), moving each vertex by up to 1/32 pixel
/// in x and y, i.e. up to sqrt(2)/32 = 0.044 pixel; rounding the vertices
/// to f32 and the viewport transform add below 1e-3 pixel at n = 4096. A
/// snapped triangle stays within that distance of the exact one, so a
/// margin of 1/16 pixel covers both. Smaller margins are not safe: with
/// 1e-3 (and with 0) the tests here catch lavapipe writing pixels outside
/// the views, as its 8 sub-pixel bits move vertices by up to 0.003 pixel.
const SNAP_MARGIN: f64 = 1.0 / 16.0;

/// Bound on the f64 rounding error of an edge test, relative to the
/// largest coordinate involved.
const F64_ERROR: f64 = 64.0 * f64::EPSILON;

/// The largest map side.
const MAX_SIDE: usize = 4096;

/// The most views an occluder may have: the stencil buffer has 8 bits.
const MAX_VIEWS: usize = 255;

/// The most occluders drawn together in one batch.
const MAX_BATCH: usize = 1024;

/// How many batches back a new occluder looks for a place.
const BATCH_SCAN: usize = 64;

/// The largest vertex buffer of one render pass, in vertices (64 MiB).
const CHUNK_VERTICES: usize = 4 << 20;

/// Bytes of one vertex: NDC x, NDC y, normalised depth, value (all f32).
const VERTEX_BYTES: u64 = 16;

/// The colour target's format: the stored value.
const VALUE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;

/// The shaders: the vertex shader passes positions through, the count
/// pass touches only the stencil, the resolve pass writes the occluder's
/// value (flat, so bit-exact).
const SHADER: &str = include_str!("oracle_gpu.wgsl");

/// A wgpu device ready to rasterise depth maps.
pub struct GpuRasteriser {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    depth_format: wgpu::TextureFormat,
    /// Draws a view: stencil `Equal(i)` then `IncrementClamp`, no writes.
    count_pipeline: wgpu::RenderPipeline,
    /// Draws the bounding quads: stencil `Equal(k)`, value and depth
    /// written where the depth test passes, stencil reset to 0.
    resolve_pipeline: wgpu::RenderPipeline,
    /// Errors wgpu reported outside this crate's error scopes.
    uncaptured: Arc<Mutex<Vec<String>>>,
    /// Set when the device is lost.
    lost: Arc<Mutex<Option<String>>>,
}

impl std::fmt::Debug for GpuRasteriser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuRasteriser")
            .field("adapter", &self.adapter_name())
            .field("depth_format", &self.depth_format)
            .finish()
    }
}

impl GpuRasteriser {
    /// Opens a Vulkan (or other PRIMARY backend: Metal, DirectX 12)
    /// adapter; `Err` with a clear message when there is none. The OpenGL
    /// backend is never used (its R32Float render targets fail validation;
    /// DESIGN.md, "Dependencies"). Prefers a discrete GPU, then an
    /// integrated one, then a CPU driver such as lavapipe.
    pub fn new() -> Result<Self, GpuError> {
        Self::open(true)
    }

    /// Opens a device on the best adapter; `depth32` allows
    /// Depth32FloatStencil8 (tests turn it off to exercise
    /// Depth24PlusStencil8).
    fn open(depth32: bool) -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::PRIMARY,
            flags: wgpu::InstanceFlags::empty(),
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY));
        let rank = |t: wgpu::DeviceType| match t {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu => 2,
            wgpu::DeviceType::Other => 3,
            wgpu::DeviceType::Cpu => 4,
        };
        let adapter = adapters
            .into_iter()
            .filter(|a| {
                matches!(
                    a.get_info().backend,
                    wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12
                )
            })
            .min_by_key(|a| rank(a.get_info().device_type))
            .ok_or(GpuError::NoAdapter)?;
        let name = describe(&adapter.get_info());
        // Depth32FloatStencil8 where offered; Depth24PlusStencil8 is always
        // there. Either is sound (see `depth_key`).
        let features = if depth32 {
            adapter.features() & wgpu::Features::DEPTH32FLOAT_STENCIL8
        } else {
            wgpu::Features::empty()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("vis5d depth map"),
            required_features: features,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::RequestDevice {
            adapter: name.clone(),
            message: e.to_string(),
        })?;
        Self::from_device(device, queue)
    }

    /// A rasteriser on a device and queue the caller opened (an engine's
    /// own, or a test's), on a Vulkan, Metal or DirectX 12 adapter (an
    /// OpenGL device is refused: its R32Float render targets fail
    /// validation). It uses Depth32FloatStencil8 when the device was
    /// opened with `Features::DEPTH32FLOAT_STENCIL8`, else
    /// Depth24PlusStencil8 (both are sound, see `depth_key`), and needs the
    /// device's limits to allow the maps asked for (a side up to
    /// `max_texture_dimension_2d`).
    ///
    /// It installs the device's uncaptured-error handler and device-lost
    /// callback (so that such errors come back from
    /// [`GpuRasteriser::rasterise`] as [`GpuError`]s, not panics),
    /// replacing any the caller set.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Result<Self, GpuError> {
        let info = device.adapter_info();
        let name = describe(&info);
        if !matches!(
            info.backend,
            wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12
        ) {
            return Err(GpuError::Unsupported {
                adapter: name,
                message: "only Vulkan, Metal and DirectX 12 devices are used (R32Float render \
                          targets fail validation on the OpenGL backend)"
                    .into(),
            });
        }
        let depth_format = if device
            .features()
            .contains(wgpu::Features::DEPTH32FLOAT_STENCIL8)
        {
            wgpu::TextureFormat::Depth32FloatStencil8
        } else {
            wgpu::TextureFormat::Depth24PlusStencil8
        };

        // Errors outside our scopes would otherwise panic: keep them (a
        // few) and report them from the next call instead.
        let uncaptured = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&uncaptured);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let mut errors = sink.lock().unwrap_or_else(|p| p.into_inner());
            if errors.len() < 8 {
                errors.push(e.to_string());
            }
        }));
        let lost = Arc::new(Mutex::new(None));
        let lost_sink = Arc::clone(&lost);
        device.set_device_lost_callback(move |reason, message| {
            *lost_sink.lock().unwrap_or_else(|p| p.into_inner()) =
                Some(format!("{reason:?}: {message}"));
        });

        let scope = ErrorScopes::push(&device);
        let (count_pipeline, resolve_pipeline) = make_pipelines(&device, depth_format);
        scope.pop().map_err(|e| GpuError::Unsupported {
            adapter: name.clone(),
            message: format!("creating the pipelines failed: {e}"),
        })?;

        Ok(Self {
            device,
            queue,
            info,
            depth_format,
            count_pipeline,
            resolve_pipeline,
            uncaptured,
            lost,
        })
    }

    /// The adapter's name and backend, for messages ("llvmpipe (Vulkan)").
    pub fn adapter_name(&self) -> String {
        describe(&self.info)
    }

    /// Rasterises: returns an n*n map (row-major, row j at j*n..), where
    /// each pixel holds the smallest `depth` among the occluders whose
    /// views ALL cover the pixel ENTIRELY (the intersection of the views,
    /// i.e. stencil count == number of views), and `f64::INFINITY` where
    /// none does. n is a power of two, 1..=4096.
    ///
    /// Conservative: a pixel may be left out by an occluder that covers it
    /// (when it lies within about 0.06 pixel of a slanted edge), never the
    /// other way. A stored value is the Depth, rounded up to f32, of an
    /// occluder that covers the pixel entirely (the smallest among those
    /// drawn there), so it is never below the true smallest Depth.
    pub fn rasterise(
        &self,
        n: usize,
        occluders: &[ProjectedOccluder],
    ) -> Result<Vec<f64>, GpuError> {
        self.rasterise_in_passes(n, occluders, CHUNK_VERTICES)
    }

    /// [`Self::rasterise`] with render passes of at most `chunk_vertices`
    /// vertices each (a single larger batch gets a pass of its own).
    fn rasterise_in_passes(
        &self,
        n: usize,
        occluders: &[ProjectedOccluder],
        chunk_vertices: usize,
    ) -> Result<Vec<f64>, GpuError> {
        let mut maps = self.rasterise_jobs(&[(n, occluders)], chunk_vertices)?;
        Ok(maps.pop().expect("one map per job"))
    }

    /// Several maps at once, `(side, occluders)` each, as
    /// [`Self::rasterise`] makes them, recorded into one command buffer
    /// and read back after one submission (the per-map cost of a
    /// submission and a blocking readback is paid once).
    pub fn rasterise_many(&self, jobs: &[MapJob]) -> Result<Vec<Vec<f64>>, GpuError> {
        self.rasterise_jobs(jobs, CHUNK_VERTICES)
    }

    fn rasterise_jobs(
        &self,
        jobs: &[MapJob],
        chunk_vertices: usize,
    ) -> Result<Vec<Vec<f64>>, GpuError> {
        let mut work: Vec<Option<Vec<Chunk>>> = Vec::with_capacity(jobs.len());
        for &(n, occluders) in jobs {
            work.push(self.chunks_of(n, occluders, chunk_vertices)?);
        }
        if work.iter().all(Option::is_none) {
            return Ok(jobs
                .iter()
                .map(|&(n, _)| vec![f64::INFINITY; n * n])
                .collect());
        }
        self.guarded(|| self.draw_and_read(jobs, &work))
    }

    /// The render passes of one map, checked against the device's limits;
    /// `None` when no occluder covers a pixel (the map is empty).
    fn chunks_of(
        &self,
        n: usize,
        occluders: &[ProjectedOccluder],
        chunk_vertices: usize,
    ) -> Result<Option<Vec<Chunk>>, GpuError> {
        if !n.is_power_of_two() || n > MAX_SIDE {
            return Err(GpuError::InvalidInput(format!(
                "the map side must be a power of two from 1 to {MAX_SIDE}, not {n}"
            )));
        }
        if let Some((index, o)) = occluders
            .iter()
            .enumerate()
            .find(|(_, o)| o.views.len() > MAX_VIEWS)
        {
            return Err(GpuError::InvalidInput(format!(
                "occluder {index} has {} views; the stencil buffer counts at most {MAX_VIEWS}",
                o.views.len()
            )));
        }
        let limits = self.device.limits();
        if n as u64 > u64::from(limits.max_texture_dimension_2d) {
            return Err(GpuError::Unsupported {
                adapter: self.adapter_name(),
                message: format!(
                    "maps of side {n} exceed its largest texture ({})",
                    limits.max_texture_dimension_2d
                ),
            });
        }

        let prepared = prepare(n, occluders);
        if prepared.is_empty() {
            return Ok(None);
        }
        let batches = make_batches(n, &prepared);
        let chunks = build_vertices(n, &prepared, &batches, chunk_vertices);
        let max_vertices = limits.max_buffer_size / VERTEX_BYTES;
        if let Some(c) = chunks
            .iter()
            .find(|c| c.vertices.len() as u64 > max_vertices)
        {
            return Err(GpuError::Unsupported {
                adapter: self.adapter_name(),
                message: format!(
                    "a batch needs {} vertices, more than one buffer holds ({max_vertices})",
                    c.vertices.len()
                ),
            });
        }
        Ok(Some(chunks))
    }

    /// The device (for the shrinking oracle's cube maps, which share it).
    pub(crate) fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The device's queue.
    pub(crate) fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// Runs `work` on the device with its errors caught: the device's
    /// health checked before and after, and wgpu's validation and memory
    /// errors in an error scope around it.
    pub(crate) fn guarded<T>(
        &self,
        work: impl FnOnce() -> Result<T, GpuError>,
    ) -> Result<T, GpuError> {
        self.check_health()?;
        let scope = ErrorScopes::push(&self.device);
        let result = work();
        let scoped = scope.pop();
        self.check_health()?;
        scoped.map_err(GpuError::Gpu)?;
        result
    }

    /// Maps `buffers` for reading, after the work submitted before, and
    /// waits until every one is mapped.
    pub(crate) fn map_for_reading(&self, buffers: &[&wgpu::Buffer]) -> Result<(), GpuError> {
        let (sender, receiver) = mpsc::channel();
        for buffer in buffers {
            let sender = sender.clone();
            buffer.map_async(wgpu::MapMode::Read, .., move |r| {
                let _ = sender.send(r);
            });
        }
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        for _ in buffers {
            receiver
                .recv()
                .map_err(|_| GpuError::Readback("the mapping was never answered".into()))?
                .map_err(|e| GpuError::Readback(e.to_string()))?;
        }
        Ok(())
    }

    /// Reports a lost device or errors wgpu raised outside any scope.
    pub(crate) fn check_health(&self) -> Result<(), GpuError> {
        if let Some(reason) = self.lost.lock().unwrap_or_else(|p| p.into_inner()).clone() {
            return Err(GpuError::DeviceLost(reason));
        }
        let mut errors = self.uncaptured.lock().unwrap_or_else(|p| p.into_inner());
        if !errors.is_empty() {
            let message = errors.join("; ");
            errors.clear();
            return Err(GpuError::Gpu(message));
        }
        Ok(())
    }

    /// Records the render passes of every map (`None`: empty, not drawn)
    /// into one command buffer, submits it once and reads the maps back.
    fn draw_and_read(
        &self,
        jobs: &[MapJob],
        work: &[Option<Vec<Chunk>>],
    ) -> Result<Vec<Vec<f64>>, GpuError> {
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("depth maps"),
            });
        let readbacks: Vec<Option<(wgpu::Buffer, u32)>> = jobs
            .iter()
            .zip(work)
            .map(|(&(n, _), chunks)| {
                chunks
                    .as_ref()
                    .map(|chunks| self.record(&mut encoder, n, chunks))
            })
            .collect();
        self.queue.submit([encoder.finish()]);

        let buffers: Vec<&wgpu::Buffer> = readbacks.iter().flatten().map(|(b, _)| b).collect();
        self.map_for_reading(&buffers)?;
        let mut maps = Vec::with_capacity(jobs.len());
        for (&(n, _), readback) in jobs.iter().zip(&readbacks) {
            let Some((buffer, row_bytes)) = readback else {
                maps.push(vec![f64::INFINITY; n * n]);
                continue;
            };
            let map = {
                let data = buffer
                    .get_mapped_range(..)
                    .map_err(|e| GpuError::Readback(e.to_string()))?;
                let mut map = Vec::with_capacity(n * n);
                for row in data.chunks_exact(*row_bytes as usize) {
                    map.extend(
                        row[..4 * n]
                            .chunks_exact(4)
                            .map(|b| f64::from(f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))),
                    );
                }
                map
            };
            buffer.unmap();
            maps.push(map);
        }
        Ok(maps)
    }

    /// Records one map's render passes and its copy into a new readback
    /// buffer; returns the buffer and its padded row length.
    fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        n: usize,
        chunks: &[Chunk],
    ) -> (wgpu::Buffer, u32) {
        let side = n as u32;
        let extent = wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: 1,
        };
        let texture = |label, format, usage| {
            self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: extent,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let value = texture(
            "depth map values",
            VALUE_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = texture(
            "depth map depth-stencil",
            self.depth_format,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let value_view = value.create_view(&wgpu::TextureViewDescriptor::default());
        let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());

        let buffers: Vec<wgpu::Buffer> = chunks
            .iter()
            .map(|c| {
                let bytes: Vec<u8> = c
                    .vertices
                    .iter()
                    .flat_map(|v| v.iter().flat_map(|x| x.to_ne_bytes()))
                    .collect();
                self.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("depth map vertices"),
                        contents: &bytes,
                        usage: wgpu::BufferUsages::VERTEX,
                    })
            })
            .collect();

        for (c, (chunk, buffer)) in chunks.iter().zip(&buffers).enumerate() {
            let first = c == 0;
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("depth map occluders"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &value_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: if first {
                            wgpu::LoadOp::Clear(wgpu::Color {
                                r: f64::INFINITY,
                                g: 0.0,
                                b: 0.0,
                                a: 0.0,
                            })
                        } else {
                            wgpu::LoadOp::Load
                        },
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: if first {
                            wgpu::LoadOp::Clear(1.0)
                        } else {
                            wgpu::LoadOp::Load
                        },
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: Some(wgpu::Operations {
                        load: if first {
                            wgpu::LoadOp::Clear(0)
                        } else {
                            wgpu::LoadOp::Load
                        },
                        store: wgpu::StoreOp::Store,
                    }),
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_vertex_buffer(0, buffer.slice(..));
            for batch in &chunk.batches {
                pass.set_pipeline(&self.count_pipeline);
                for (i, range) in batch.views.iter().enumerate() {
                    pass.set_stencil_reference(i as u32);
                    pass.draw(range.clone(), 0..1);
                }
                pass.set_pipeline(&self.resolve_pipeline);
                pass.set_stencil_reference(batch.views.len() as u32);
                pass.draw(batch.quads.clone(), 0..1);
            }
        }

        // Rows of a texture copy are padded to 256 bytes.
        let row_bytes = (4 * side).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("depth map readback"),
            size: u64::from(row_bytes) * u64::from(side),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &value,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row_bytes),
                    rows_per_image: Some(side),
                },
            },
            extent,
        );
        (readback, row_bytes)
    }
}

/// "name (Backend)".
fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?})", info.name, info.backend)
}

/// Validation, out-of-memory and internal error scopes, popped together.
pub(crate) struct ErrorScopes {
    guards: Vec<wgpu::ErrorScopeGuard>,
}

impl ErrorScopes {
    pub(crate) fn push(device: &wgpu::Device) -> Self {
        let guards = [
            wgpu::ErrorFilter::Validation,
            wgpu::ErrorFilter::OutOfMemory,
            wgpu::ErrorFilter::Internal,
        ]
        .into_iter()
        .map(|f| device.push_error_scope(f))
        .collect();
        Self { guards }
    }

    /// Pops the scopes (innermost first); the errors caught, joined.
    pub(crate) fn pop(mut self) -> Result<(), String> {
        let mut errors = Vec::new();
        while let Some(guard) = self.guards.pop() {
            if let Some(e) = pollster::block_on(guard.pop()) {
                errors.push(e.to_string());
            }
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(errors.join("; "))
        }
    }
}

/// The two pipelines: counting views into the stencil buffer, and writing
/// the quads where the count is complete.
fn make_pipelines(
    device: &wgpu::Device,
    depth_format: wgpu::TextureFormat,
) -> (wgpu::RenderPipeline, wgpu::RenderPipeline) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("depth map shader"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("depth map layout"),
        bind_group_layouts: &[],
        immediate_size: 0,
    });
    let attributes = wgpu::vertex_attr_array![0 => Float32x4];
    let buffers = [Some(wgpu::VertexBufferLayout {
        array_stride: VERTEX_BYTES,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &attributes,
    })];
    let pipeline = |label, fragment, writes, depth_write, depth_compare, stencil_face| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &buffers,
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: depth_format,
                depth_write_enabled: Some(depth_write),
                depth_compare: Some(depth_compare),
                stencil: wgpu::StencilState {
                    front: stencil_face,
                    back: stencil_face,
                    read_mask: 0xff,
                    write_mask: 0xff,
                },
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(fragment),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: VALUE_FORMAT,
                    blend: None,
                    write_mask: writes,
                })],
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    // View i of an occluder: pixels whose count is i (covered by views
    // 0..i) go to i + 1; a second triangle of the same view over the same
    // pixel then finds i + 1 and keeps it.
    let count = pipeline(
        "depth map count views",
        "fs_count",
        wgpu::ColorWrites::empty(),
        false,
        wgpu::CompareFunction::Always,
        wgpu::StencilFaceState {
            compare: wgpu::CompareFunction::Equal,
            fail_op: wgpu::StencilOperation::Keep,
            depth_fail_op: wgpu::StencilOperation::Keep,
            pass_op: wgpu::StencilOperation::IncrementClamp,
        },
    );
    // The quad: where the count is k (all views), keep the smaller depth;
    // every pixel of the quad returns to 0 whatever the tests say.
    let resolve = pipeline(
        "depth map resolve",
        "fs_resolve",
        wgpu::ColorWrites::ALL,
        true,
        wgpu::CompareFunction::LessEqual,
        wgpu::StencilFaceState {
            compare: wgpu::CompareFunction::Equal,
            fail_op: wgpu::StencilOperation::Zero,
            depth_fail_op: wgpu::StencilOperation::Zero,
            pass_op: wgpu::StencilOperation::Zero,
        },
    );
    (count, resolve)
}

/// The smallest f32 that is >= `x` (x not NaN): round to nearest, then up
/// one step if that fell below.
fn f32_at_least(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x { f.next_up() } else { f }
}

/// The normalised depth of a value: its f32 bits mapped to an unsigned key
/// that orders like the values, keeping the top 24 bits, over 2^24. It is
/// monotone (never decreasing) in the value, exact in f32, below 1, and
/// any depth buffer's quantisation of it is monotone too.
///
/// Why the depth buffer cannot make the map unsound: the value written to
/// a pixel is always the (rounded-up) Depth of an occluder that covers the
/// pixel, because the stencil test admits only covering occluders; the
/// depth test only chooses *which* covering occluder's value survives. So
/// a stored value is >= the smallest covering Depth whatever the depth
/// buffer does. Its precision only decides tightness: two values with the
/// same key tie, and ties are settled by drawing occluders in decreasing
/// value (see [`make_batches`]) so that `LessEqual` lets the smaller one
/// win; the map then holds exactly the smallest covering value.
fn depth_key(value: f32) -> f32 {
    let bits = value.to_bits();
    let key = if bits & 0x8000_0000 != 0 {
        !bits
    } else {
        bits | 0x8000_0000
    };
    (key >> 8) as f32 / (1u32 << 24) as f32
}

/// An occluder ready to draw.
struct Prepared {
    /// The Depth rounded up to f32.
    value: f32,
    /// The eroded views (each non-empty), clipped to [-1, n + 1]^2.
    views: Vec<Vec<DVec2>>,
    /// Pixel columns x0..x1 and rows y0..y1 around all its views, with one
    /// pixel to spare, clipped to the map; never empty.
    rect: [u32; 4],
}

/// Erodes every occluder's views and drops those that can write nothing.
fn prepare(n: usize, occluders: &[ProjectedOccluder]) -> Vec<Prepared> {
    let side = n as f64;
    occluders
        .iter()
        .filter(|o| !o.views.is_empty() && !o.depth.is_nan() && o.depth != f64::INFINITY)
        .filter_map(|o| {
            let views: Vec<Vec<DVec2>> = o
                .views
                .iter()
                .map(|v| erode_view(v, side))
                .collect::<Option<_>>()?;
            let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
            for p in views.iter().flatten() {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            let clamp = |x: f64| x.clamp(0.0, side) as u32;
            let rect = [
                clamp(lo.x.floor() - 1.0),
                clamp(lo.y.floor() - 1.0),
                clamp(hi.x.ceil() + 1.0),
                clamp(hi.y.ceil() + 1.0),
            ];
            (rect[0] < rect[2] && rect[1] < rect[3]).then(|| Prepared {
                value: f32_at_least(o.depth),
                views,
                rect,
            })
        })
        .collect()
}

/// The eroded view: the region where a pixel centre may be sampled by the
/// GPU only if the pixel square lies inside `view`, or `None` if empty.
///
/// Computed as the intersection of the square [-1, n + 1]^2 with one
/// half-plane per edge (Sutherland-Hodgman clipping in f64), not by
/// intersecting consecutive offset lines: when erosion makes a short edge
/// vanish, the half-plane intersection is still exact, where consecutive
/// lines would produce a vertex outside. Each half-plane is:
///
/// - slanted edge, unit inward normal `nn`: `nn . (x - a) >= 0.5 (|nn.x| +
///   |nn.y|) + SNAP_MARGIN + rounding`, the Minkowski erosion by the pixel
///   square plus the GPU margin;
/// - horizontal or vertical edge (exactly, in f64) at coordinate c: the
///   pixels inside are those from `ceil(c)` on (or up to `floor(c)`), so
///   the boundary goes on that integer, halfway between pixel centres. No
///   pixel centre lies within 0.5 of it, far more than any GPU rounding,
///   so pixels flush with the edge are kept.
///
/// For a convex view this is exactly "pixel square inside the view" (less
/// the margin). For a non-convex simple polygon it is the eroded kernel
/// (the intersection of the edges' inner half-planes), still inside the
/// polygon. A clockwise view is reversed first.
fn erode_view(view: &[DVec2], side: f64) -> Option<Vec<DVec2>> {
    if view.len() < 3 || view.iter().any(|p| !p.is_finite()) {
        return None;
    }
    let area2 = signed_area(view);
    if area2 == 0.0 || !area2.is_finite() {
        return None;
    }
    let ccw = area2 > 0.0;
    let m = view.len();
    let mut poly = rectangle(DVec2::splat(-1.0), DVec2::splat(side + 1.0));
    for e in 0..m {
        let (p, q) = (view[e], view[(e + 1) % m]);
        let (a, b) = if ccw { (p, q) } else { (q, p) };
        let d = b - a;
        // Interior to the left of a -> b.
        poly = if d == DVec2::ZERO {
            continue;
        } else if d.x == 0.0 {
            if d.y < 0.0 {
                let c = a.x.ceil();
                clip_half_plane(&poly, |x| x.x - c)
            } else {
                let c = a.x.floor();
                clip_half_plane(&poly, |x| c - x.x)
            }
        } else if d.y == 0.0 {
            if d.x > 0.0 {
                let c = a.y.ceil();
                clip_half_plane(&poly, |x| x.y - c)
            } else {
                let c = a.y.floor();
                clip_half_plane(&poly, |x| c - x.y)
            }
        } else {
            let normal = d.perp() / d.length();
            let scale = a.abs().max_element().max(b.abs().max_element()) + side + 1.0;
            let shift = 0.5 * (normal.x.abs() + normal.y.abs()) + SNAP_MARGIN + F64_ERROR * scale;
            clip_half_plane(&poly, |x| normal.dot(x - a) - shift)
        };
        if poly.len() < 3 {
            return None;
        }
    }
    (signed_area(&poly) > 0.0).then_some(poly)
}

/// Occluders drawn together: same view count, pixel-disjoint rectangles.
struct Batch {
    views: usize,
    members: Vec<usize>,
    /// Occupied cells of a coarse grid over the map, one bit per cell.
    cells: [u64; 64],
}

/// Groups occluders into batches, each drawn with `k + 1` draw calls.
///
/// Occluders are taken in decreasing value, and each goes into a batch
/// after the last one holding an occluder it overlaps (on a coarse grid of
/// at most 64 x 64 cells), so overlapping occluders are drawn in
/// decreasing value: with `LessEqual`, the smaller value wins depth ties.
/// Within a batch the rectangles (quads included) touch disjoint pixels,
/// so their stencil counts cannot mix.
fn make_batches(n: usize, prepared: &[Prepared]) -> Vec<Batch> {
    let grid = n.min(64) as u32;
    let cell = n as u32 / grid;
    let mut order: Vec<usize> = (0..prepared.len()).collect();
    order.sort_by(|&a, &b| prepared[b].value.total_cmp(&prepared[a].value));
    let mut batches: Vec<Batch> = Vec::new();
    for o in order {
        let p = &prepared[o];
        let [x0, y0, x1, y1] = p.rect;
        let (cx0, cx1) = (x0 / cell, (x1 - 1) / cell);
        let (cy0, cy1) = (y0 / cell, (y1 - 1) / cell);
        let mask = (u64::MAX >> (63 - (cx1 - cx0))) << cx0;
        let rows = cy0 as usize..=cy1 as usize;
        let overlaps = |b: &Batch| b.cells[rows.clone()].iter().any(|r| r & mask != 0);
        let mut target = None;
        for (b, batch) in batches.iter().enumerate().rev().take(BATCH_SCAN) {
            if overlaps(batch) {
                break;
            }
            if batch.views == p.views.len() && batch.members.len() < MAX_BATCH {
                target = Some(b);
            }
        }
        let b = target.unwrap_or_else(|| {
            batches.push(Batch {
                views: p.views.len(),
                members: Vec::new(),
                cells: [0; 64],
            });
            batches.len() - 1
        });
        let batch = &mut batches[b];
        batch.members.push(o);
        for r in &mut batch.cells[rows] {
            *r |= mask;
        }
    }
    batches
}

/// One render pass's vertices and draws.
struct Chunk {
    vertices: Vec<[f32; 4]>,
    batches: Vec<BatchDraws>,
}

/// A batch's vertex ranges: one per view index, then the quads.
struct BatchDraws {
    views: Vec<Range<u32>>,
    quads: Range<u32>,
}

/// Lays out the vertices of all batches (NDC x, NDC y, depth, value),
/// splitting them into render passes of at most `chunk_vertices` (a single
/// larger batch gets a pass of its own).
fn build_vertices(
    n: usize,
    prepared: &[Prepared],
    batches: &[Batch],
    chunk_vertices: usize,
) -> Vec<Chunk> {
    // Pixel x to NDC x, pixel y (row, downwards) to NDC y (upwards).
    let scale = 2.0 / n as f64;
    let ndc = |p: DVec2| [(p.x * scale - 1.0) as f32, (1.0 - p.y * scale) as f32];
    let mut chunks = vec![Chunk {
        vertices: Vec::new(),
        batches: Vec::new(),
    }];
    for batch in batches {
        let size: usize = batch
            .members
            .iter()
            .map(|&o| {
                6 + prepared[o]
                    .views
                    .iter()
                    .map(|v| 3 * (v.len() - 2))
                    .sum::<usize>()
            })
            .sum();
        let last = chunks.last().expect("one chunk at least");
        if !last.vertices.is_empty() && last.vertices.len() + size > chunk_vertices {
            chunks.push(Chunk {
                vertices: Vec::with_capacity(size),
                batches: Vec::new(),
            });
        }
        let chunk = chunks.last_mut().expect("one chunk at least");
        let vertices = &mut chunk.vertices;
        let mut views = Vec::with_capacity(batch.views);
        for i in 0..batch.views {
            let start = vertices.len() as u32;
            for &o in &batch.members {
                let view = &prepared[o].views[i];
                let v0 = ndc(view[0]);
                for w in view[1..].windows(2) {
                    for p in [v0, ndc(w[0]), ndc(w[1])] {
                        vertices.push([p[0], p[1], 0.0, 0.0]);
                    }
                }
            }
            views.push(start..vertices.len() as u32);
        }
        let start = vertices.len() as u32;
        for &o in &batch.members {
            let p = &prepared[o];
            let [x0, y0, x1, y1] = p.rect.map(f64::from);
            let z = depth_key(p.value);
            let corner = |x, y| {
                let q = ndc(DVec2::new(x, y));
                [q[0], q[1], z, p.value]
            };
            let (a, b, c, d) = (
                corner(x0, y0),
                corner(x1, y0),
                corner(x1, y1),
                corner(x0, y1),
            );
            vertices.extend([a, b, c, a, c, d]);
        }
        chunk.batches.push(BatchDraws {
            views,
            quads: start..vertices.len() as u32,
        });
    }
    chunks
}

#[cfg(test)]
#[path = "oracle_gpu_tests.rs"]
mod tests;
