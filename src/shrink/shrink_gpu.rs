//! The shrinking oracle's cube map (`shrink_cube.rs`) built on the GPU
//! (wgpu compute shaders, `shrink_gpu.wgsl`), never covering a pixel the
//! CPU reference leaves open and never holding a smaller `D`.
//!
//! **Split.** The CPU does, in f64 and with the reference's own functions,
//! everything that decides *which* polygons there are: each kept face's
//! far distance, its clipping and projection onto each cube face
//! ([`project`], the same [`ThroughEye`] refusal skipping the solid), and
//! which edges are outline edges ([`edge_inside`]). Each projected polygon
//! becomes half-plane *lines* in pixel units (rounded to f32) and a pixel
//! box; the GPU does the per-pixel work: one invocation per (polygon, row)
//! solves the row's touched and inside columns, `atomicMax`es the far value (positive f32 bits
//! order as u32) and ORs the solid's tag with an inside or outline bit;
//! then one invocation per pixel resolves the solid's coverage (inside and
//! not outline) into the min maps and clears the scratch.
//!
//! **Batches.** Solids whose pixel boxes fall in disjoint tiles of the map
//! share a batch (their scratch pixels never meet, so the tag tells them
//! apart); a batch is one or more draw dispatches and one resolve. The
//! merge (the smaller `D`, then the lower floor) does not depend on the
//! order of the solids. Everything is one command buffer, one submission
//! and one readback.
//!
//! **Margins: erring on one side only.** Let `m = 1e-3 + 1e-5 (n + 4)`
//! pixels ([`margin`]). Coordinates are within `[-2, n + 2]` (the
//! projection clips to the face widened by two pixels). Evaluating a line
//! `a x + b y + c` (unit `(a, b)`, `|c| <= 1.5 (n + 2)`) in f32, with its
//! coefficients rounded to f32, errs by at most about `8 * 2^-24 * 4 (n +
//! 4) ~ 2e-6 (n + 4)`, five times below `1e-5 (n + 4)`; solving it for the
//! column (one division, one subtraction) adds an error of a few f32 ulps
//! of a column below `n + 8`, which is below `m` in distance too. The
//! `1e-3` covers the f64 errors of the lines (below `1e-9` pixel) and the
//! reference's own `1e-7` pixel widening many times over. The shader
//! solves, per row and line, the columns that pass, and widens (touch) or
//! shrinks (inside) each line by a further `m` to absorb those errors:
//! - *Touch* (far values, outline edges): every line is a *supporting*
//!   line, shifted in f64 until all the polygon's vertices lie on its inner
//!   side, so the lines bound a superset of the polygon (whatever its
//!   shape or degeneracy); a pixel is touched when its square grown by `m`
//!   has a corner within `m` of the inner side of every line (and lies in
//!   the polygon's pixel box, grown by `2 m`). A pixel the reference
//!   touches (its square grown by `1e-7` meets the polygon) is therefore
//!   touched here: far values are never smaller, outlines never fewer.
//! - *Inside* (pixel centres): the polygon's vertices closer than
//!   [`MERGE`] to the previous one are dropped (a subset of the vertices
//!   spans a subset of the convex polygon), the rest must be convex in f64
//!   (else no centre counts as inside), and a centre is inside when it is
//!   at least `2 m` inside every edge line. With edges at least `1e-4`
//!   long, an edge line's direction errs by below `1e-8`, so it strays
//!   below `1e-4` pixel from the true edge across the map: such a centre is
//!   inside the reference's polygon by far more than its rounding.
//! - Far values and floors are rounded up to f32 ([`up32`]); a solid whose
//!   values do not fit is skipped.
//!
//! Per pixel and solid, then: inside here implies inside on the CPU, not
//! outline on the CPU follows from not outline here, and the far value is
//! at least the CPU's; so a pixel covered here is covered on the CPU, with
//! a `D` no smaller.

use glam::{DVec2, DVec3};
use wgpu::util::DeviceExt;

use super::shrink_cube::{CubeMap, FACES, edge_inside, project};
use super::shrink_mesh::Shrunk;
use crate::oracle::{GpuError, GpuRasteriser};

/// Vertices of a projected face closer than this (pixels) to the one
/// before are dropped for the centre test.
const MERGE: f64 = 1e-4;

/// How many batches back a solid looks for one it does not overlap.
const BATCH_SCAN: usize = 64;

/// The most tiles on a side of a cube face (for batching).
const TILES: usize = 32;

/// Invocations per draw workgroup, and the most workgroups of a dispatch.
const DRAW_GROUP: usize = 64;
const MAX_GROUPS: usize = 65535;

/// Invocations per resolve workgroup.
const RESOLVE_GROUP: usize = 256;

/// Bytes of one uniform `Params` entry (aligned for dynamic offsets).
const PARAMS_STRIDE: u64 = 256;

const KIND_FACE: u32 = 0;
const KIND_OUTLINE: u32 = 1;
const KIND_TOUCH_ONLY: u32 = 2;

const SHADER: &str = include_str!("shrink_gpu.wgsl");

/// The margin in pixels of a map of side `n` (see the module's doc).
pub(super) fn margin(n: usize) -> f64 {
    1e-3 + 1e-5 * (n as f64 + 4.0)
}

/// The smallest f32 at or above `x` (`None` past f32's range or NaN).
pub(super) fn up32(x: f64) -> Option<f32> {
    let f = x as f32;
    let f = if f64::from(f) < x { f.next_up() } else { f };
    (f.is_finite() && f.abs() < f32::MAX).then_some(f)
}

/// The compute pipelines of the shrinking oracle's cube maps on a device.
pub struct ShrinkGpu {
    layout: wgpu::BindGroupLayout,
    draw: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
}

impl std::fmt::Debug for ShrinkGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShrinkGpu").finish_non_exhaustive()
    }
}

/// A polygon as the shader reads it (twelve u32).
#[derive(Clone, Copy, Default)]
struct Poly {
    r0: u32,
    r1: u32,
    c0: u32,
    c1: u32,
    base: u32,
    first: u32,
    ntouch: u32,
    ninside: u32,
    far: u32,
    tag: u32,
    kind: u32,
    pad: u32,
}

/// One solid's polygons, ready to upload.
#[derive(Default)]
struct Prepared {
    polys: Vec<Poly>,
    lines: Vec<[f32; 4]>,
    /// Tiles its polygons' pixel boxes touch.
    tiles: Vec<usize>,
}

/// Everything of one map, in batches.
struct Upload {
    polys: Vec<Poly>,
    lines: Vec<[f32; 4]>,
    items: Vec<[u32; 2]>,
    /// Per solid (tag - 1): floor bits and whether it has a floor.
    solids: Vec<[u32; 2]>,
    /// Per batch, its items' range and its tiles' range.
    batches: Vec<(std::ops::Range<usize>, std::ops::Range<usize>)>,
    /// The tiles of every batch, in turn.
    tiles: Vec<u32>,
}

impl ShrinkGpu {
    /// Builds the pipelines on `gpu`'s device.
    pub fn new(gpu: &GpuRasteriser) -> Result<Self, GpuError> {
        let device = gpu.device();
        let scope = crate::oracle::ErrorScopes::push(device);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("shrink cube map"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shrink cube map"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(32),
                    },
                    count: None,
                },
                storage(1, true),
                storage(2, true),
                storage(3, true),
                storage(4, false),
                storage(5, false),
                storage(6, false),
                storage(7, false),
                storage(8, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("shrink cube map"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let draw = pipeline("draw");
        let resolve = pipeline("resolve");
        scope.pop().map_err(|e| GpuError::Unsupported {
            adapter: gpu.adapter_name(),
            message: format!("creating the cube map pipelines failed: {e}"),
        })?;
        Ok(Self {
            layout,
            draw,
            resolve,
        })
    }

    /// Why maps of side `n` cannot be made on `gpu`'s device (a map's
    /// buffer past its limits), if they cannot.
    pub(super) fn too_big(gpu: &GpuRasteriser, n: usize) -> Option<String> {
        let bytes = (6 * n * n * 4) as u64;
        let limits = gpu.device().limits();
        let limit = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        (bytes > limit).then(|| {
            format!(
                "cube maps of {n} x {n} pixels a face need buffers of {bytes} bytes, more than {} \
                 allows ({limit})",
                gpu.adapter_name()
            )
        })
    }

    /// The cube map of `n` x `n` pixels a face around `eye` with `solids`
    /// drawn, as [`CubeMap::draw`] would make it but for the margins (see
    /// the module's doc): never a pixel covered that the CPU leaves open,
    /// never a smaller `D`.
    pub(super) fn build(
        &self,
        gpu: &GpuRasteriser,
        eye: DVec3,
        n: usize,
        solids: &[&Shrunk],
    ) -> Result<CubeMap, GpuError> {
        let pixels = 6 * n * n;
        let upload = prepare(eye, n, solids);
        if upload.items.is_empty() {
            return Ok(CubeMap::new(eye, n));
        }
        let device = gpu.device();
        let limits = device.limits();
        let biggest = [
            pixels * 4,
            (upload.items.len() + upload.tiles.len() + upload.solids.len()) * 8,
            upload.lines.len() * 16,
            upload.polys.len() * 48,
            upload.tiles.len() * 4,
        ]
        .into_iter()
        .max()
        .unwrap_or(0) as u64;
        if biggest > limits.max_storage_buffer_binding_size
            || biggest > limits.max_buffer_size
            || pixels > u32::MAX as usize / 4
        {
            return Err(GpuError::Unsupported {
                adapter: gpu.adapter_name(),
                message: format!("a cube map needs a buffer of {biggest} bytes"),
            });
        }
        gpu.guarded(|| self.run(gpu, eye, n, &upload))
    }

    fn run(
        &self,
        gpu: &GpuRasteriser,
        eye: DVec3,
        n: usize,
        up: &Upload,
    ) -> Result<CubeMap, GpuError> {
        let device = gpu.device();
        let pixels = 6 * n * n;
        let init = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let polys = init(
            "polys",
            &bytes(up.polys.iter().flat_map(Poly::words)),
            storage,
        );
        let lines = init(
            "lines",
            &bytes(up.lines.iter().flatten().map(|x| x.to_bits())),
            storage,
        );
        let tiles_at = up.items.len();
        let solids_at = tiles_at + up.tiles.len();
        let items = init(
            "items",
            &bytes(
                up.items
                    .iter()
                    .flatten()
                    .copied()
                    .chain(up.tiles.iter().flat_map(|&t| [t, 0]))
                    .chain(up.solids.iter().flatten().copied()),
            ),
            storage,
        );
        let scratch = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (pixels * 4) as u64,
                usage: storage,
                mapped_at_creation: false,
            })
        };
        let far = scratch("far");
        let flags = scratch("flags");
        // The three maps (D, D on floors, F), and their readbacks.
        let size = (pixels * 4) as u64;
        let maps: Vec<wgpu::Buffer> = [f32::MAX, f32::MAX, -f32::MAX]
            .into_iter()
            .map(|value| {
                init(
                    "map",
                    &bytes(std::iter::repeat_n(value.to_bits(), pixels)),
                    storage | wgpu::BufferUsages::COPY_SRC,
                )
            })
            .collect();
        let readbacks: Vec<wgpu::Buffer> = (0..3)
            .map(|_| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("map readback"),
                    size,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
            .collect();

        // One Params entry per dispatch: draws chunk by chunk, then the
        // resolve, per batch.
        let margin = margin(n) as f32;
        let mut entries: Vec<u8> = Vec::new();
        let mut dispatches: Vec<(bool, u32, u32, u32)> = Vec::new();
        let tps = n.min(TILES);
        let ts = n / tps;
        let push = |start: usize, count: usize, entries: &mut Vec<u8>| {
            let offset = entries.len() as u32;
            let words: [u32; 8] = [
                n as u32,
                start as u32,
                count as u32,
                pixels as u32,
                margin.to_bits(),
                ts as u32,
                tps as u32,
                solids_at as u32,
            ];
            for w in words {
                entries.extend_from_slice(&w.to_ne_bytes());
            }
            entries.resize(entries.len() + PARAMS_STRIDE as usize - 32, 0);
            offset
        };
        for (items, tiles) in &up.batches {
            let mut s = items.start;
            while s < items.end {
                let count = (items.end - s).min(MAX_GROUPS * DRAW_GROUP);
                let offset = push(s, count, &mut entries);
                dispatches.push((true, offset, count.div_ceil(DRAW_GROUP) as u32, 1));
                s += count;
            }
            let count = tiles.len() * ts * ts;
            let offset = push(tiles_at + tiles.start, count, &mut entries);
            let groups = count.div_ceil(RESOLVE_GROUP);
            let (rx, ry) = if groups <= MAX_GROUPS {
                (groups, 1)
            } else {
                (MAX_GROUPS, groups.div_ceil(MAX_GROUPS))
            };
            dispatches.push((false, offset, rx as u32, ry as u32));
        }
        let params = init("params", &entries, wgpu::BufferUsages::UNIFORM);
        fn entry(
            binding: u32,
            buffer: &wgpu::Buffer,
            size: Option<wgpu::BufferSize>,
        ) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset: 0,
                    size,
                }),
            }
        }
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shrink cube map"),
            layout: &self.layout,
            entries: &[
                entry(0, &params, wgpu::BufferSize::new(32)),
                entry(1, &polys, None),
                entry(2, &lines, None),
                entry(3, &items, None),
                entry(4, &maps[1], None),
                entry(5, &far, None),
                entry(6, &flags, None),
                entry(7, &maps[0], None),
                entry(8, &maps[2], None),
            ],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("shrink cube map"),
        });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("shrink cube map"),
                timestamp_writes: None,
            });
            for &(draw, offset, x, y) in &dispatches {
                pass.set_bind_group(0, &bind, &[offset]);
                pass.set_pipeline(if draw { &self.draw } else { &self.resolve });
                pass.dispatch_workgroups(x, y, 1);
            }
        }
        for (map, readback) in maps.iter().zip(&readbacks) {
            encoder.copy_buffer_to_buffer(map, 0, readback, 0, size);
        }
        gpu.queue().submit([encoder.finish()]);

        gpu.map_for_reading(&readbacks.iter().collect::<Vec<_>>())?;
        // Back to f64, the sentinels to infinities.
        let read = |readback: &wgpu::Buffer| -> Result<Vec<f64>, GpuError> {
            let values = {
                let data = readback
                    .get_mapped_range(..)
                    .map_err(|e| GpuError::Readback(e.to_string()))?;
                data.chunks_exact(4)
                    .map(|b| match f32::from_ne_bytes([b[0], b[1], b[2], b[3]]) {
                        f32::MAX => f64::INFINITY,
                        f if f == -f32::MAX => f64::NEG_INFINITY,
                        f => f64::from(f),
                    })
                    .collect()
            };
            readback.unmap();
            Ok(values)
        };
        let depth = read(&readbacks[0])?;
        let depth_floor = read(&readbacks[1])?;
        let floor = read(&readbacks[2])?;
        Ok(CubeMap::from_maps(eye, n, depth, depth_floor, floor))
    }
}

/// The polygons of every solid, batched, with the rows to draw.
fn prepare(eye: DVec3, n: usize, solids: &[&Shrunk]) -> Upload {
    let tps = n.min(TILES);
    let words = (6 * tps * tps).div_ceil(64);
    let mut up = Upload {
        polys: Vec::new(),
        lines: Vec::new(),
        items: Vec::new(),
        solids: Vec::new(),
        batches: Vec::new(),
        tiles: Vec::new(),
    };
    let mut prepared: Vec<Prepared> = Vec::new();
    // Batches: their tiles, and the solids (indices into `prepared`).
    let mut batches: Vec<(Vec<u64>, Vec<usize>)> = Vec::new();
    for s in solids {
        let Some(floor) = s.floor.map_or(Some(-f32::MAX), up32) else {
            continue;
        };
        let Some(p) = prepare_solid(eye, n, s, up.solids.len() as u32 + 1) else {
            continue;
        };
        if p.polys.is_empty() {
            continue;
        }
        up.solids
            .push([floor.to_bits(), u32::from(s.floor.is_some())]);
        let free = |bits: &[u64]| p.tiles.iter().all(|&t| bits[t / 64] & (1 << (t % 64)) == 0);
        let from = batches.len().saturating_sub(BATCH_SCAN);
        let b = match (from..batches.len()).find(|&b| free(&batches[b].0)) {
            Some(b) => b,
            None => {
                batches.push((vec![0; words], Vec::new()));
                batches.len() - 1
            }
        };
        for &t in &p.tiles {
            batches[b].0[t / 64] |= 1 << (t % 64);
        }
        batches[b].1.push(prepared.len());
        prepared.push(p);
    }
    for (bits, members) in &batches {
        let start = up.items.len();
        let tile0 = up.tiles.len();
        for (w, &word) in bits.iter().enumerate() {
            for b in 0..64 {
                if word & (1 << b) != 0 {
                    up.tiles.push((64 * w + b) as u32);
                }
            }
        }
        for &i in members {
            let p = &prepared[i];
            let line0 = up.lines.len() as u32;
            up.lines.extend_from_slice(&p.lines);
            for poly in &p.polys {
                let index = up.polys.len() as u32;
                up.polys.push(Poly {
                    first: poly.first + line0,
                    ..*poly
                });
                for row in poly.r0..=poly.r1 {
                    up.items.push([index, row]);
                }
            }
        }
        up.batches
            .push((start..up.items.len(), tile0..up.tiles.len()));
    }
    if up.lines.is_empty() {
        up.lines.push([0.0; 4]);
    }
    up
}

/// One solid's polygons (tag `tag`), or `None` when the reference would
/// skip it (a face through the eye) or a value does not fit in f32.
fn prepare_solid(eye: DVec3, n: usize, solid: &Shrunk, tag: u32) -> Option<Prepared> {
    let v: Vec<DVec3> = solid.vertices.iter().map(|p| *p - eye).collect();
    let mut out = Prepared::default();
    let m = margin(n);
    for t in &solid.triangles {
        let tri = t.map(|i| v[i as usize]);
        let far = up32(tri.iter().map(|p| p.length()).fold(0.0, f64::max))?;
        for face in 0..6 {
            let poly = project(&tri, face, n).ok()?;
            if poly.len() < 3 {
                continue;
            }
            add_polygon(&mut out, n, m, face, &poly, far, tag, false)?;
        }
    }
    for e in &solid.edges {
        if edge_inside(&v, e.a, e.b, e.third) {
            continue;
        }
        let seg = [v[e.a as usize], v[e.b as usize]];
        for face in 0..6 {
            let poly = project(&seg, face, n).ok()?;
            if poly.is_empty() {
                continue;
            }
            add_polygon(&mut out, n, m, face, &poly, 0.0, tag, true)?;
        }
    }
    out.tiles.sort_unstable();
    out.tiles.dedup();
    Some(out)
}

/// Adds a projected face (or an outline edge, `outline`) of cube face
/// `face`: its pixel box, touch lines and (faces) inside lines. `None` for
/// a non-finite coordinate.
#[allow(clippy::too_many_arguments)]
fn add_polygon(
    out: &mut Prepared,
    n: usize,
    m: f64,
    face: usize,
    poly: &[DVec2],
    far: f32,
    tag: u32,
    outline: bool,
) -> Option<()> {
    debug_assert!(face < FACES.len());
    if !poly.iter().all(|p| p.is_finite()) {
        return None;
    }
    let (lo, hi) = poly
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), p| {
            (a.min(*p), b.max(*p))
        });
    let last = n as f64 - 1.0;
    // Twice the margin: the box holds every pixel the GPU may touch.
    let r0 = (lo.y - 2.0 * m).floor().max(0.0);
    let r1 = (hi.y + 2.0 * m).floor().min(last);
    let c0 = (lo.x - 2.0 * m).floor().max(0.0);
    let c1 = (hi.x + 2.0 * m).floor().min(last);
    if r0 > r1 || c0 > c1 {
        return Some(());
    }
    let first = out.lines.len() as u32;
    // Touch lines: supporting lines along each edge's normals.
    let area = signed_area(poly);
    let k = poly.len();
    let mut normals: Vec<DVec2> = Vec::with_capacity(2 * k);
    for i in 0..k {
        let d = poly[(i + 1) % k] - poly[i];
        let len = d.length();
        if len == 0.0 || !len.is_finite() {
            continue;
        }
        let left = DVec2::new(-d.y, d.x) / len;
        if area > 0.0 {
            normals.push(left);
        } else if area < 0.0 {
            normals.push(-left);
        } else {
            normals.push(left);
            normals.push(-left);
        }
    }
    for nm in &normals {
        let c = -poly
            .iter()
            .map(|p| nm.dot(*p))
            .fold(f64::INFINITY, f64::min);
        out.lines.push([nm.x as f32, nm.y as f32, c as f32, 0.0]);
    }
    let ntouch = out.lines.len() as u32 - first;
    let mut kind = if outline {
        KIND_OUTLINE
    } else {
        KIND_TOUCH_ONLY
    };
    let mut ninside = 0;
    if !outline && let Some(lines) = inside_lines(poly) {
        kind = KIND_FACE;
        ninside = lines.len() as u32;
        out.lines.extend(lines);
    }
    out.polys.push(Poly {
        r0: r0 as u32,
        r1: r1 as u32,
        c0: c0 as u32,
        c1: c1 as u32,
        base: (face * n * n) as u32,
        first,
        ntouch,
        ninside,
        far: far.to_bits(),
        tag,
        kind,
        pad: 0,
    });
    // Tiles of the pixel box.
    let tps = n.min(TILES);
    let ts = n / tps;
    for tr in r0 as usize / ts..=r1 as usize / ts {
        for tc in c0 as usize / ts..=c1 as usize / ts {
            out.tiles.push((face * tps + tr) * tps + tc);
        }
    }
    Some(())
}

/// The inward edge lines of a projected face for the centre test: its
/// vertices with those within [`MERGE`] of the one before dropped, if
/// they are at least three and convex; else `None`.
fn inside_lines(poly: &[DVec2]) -> Option<Vec<[f32; 4]>> {
    let mut kept: Vec<DVec2> = Vec::with_capacity(poly.len());
    for &p in poly {
        if kept.last().is_none_or(|q| (p - *q).length() >= MERGE) {
            kept.push(p);
        }
    }
    while kept.len() > 1 && (kept[0] - kept[kept.len() - 1]).length() < MERGE {
        kept.pop();
    }
    if kept.len() < 3 {
        return None;
    }
    let area = signed_area(&kept);
    if area == 0.0 || !area.is_finite() {
        return None;
    }
    let k = kept.len();
    let mut lines = Vec::with_capacity(k);
    for i in 0..k {
        let (p, q) = (kept[i], kept[(i + 1) % k]);
        let d = q - p;
        let mut nm = DVec2::new(-d.y, d.x) / d.length();
        if area < 0.0 {
            nm = -nm;
        }
        let c = -nm.dot(p);
        // Convex: every vertex on the inner side (up to f64 rounding).
        if kept.iter().any(|v| nm.dot(*v) + c < -1e-9) {
            return None;
        }
        lines.push([nm.x as f32, nm.y as f32, c as f32, 0.0]);
    }
    Some(lines)
}

fn signed_area(poly: &[DVec2]) -> f64 {
    let k = poly.len();
    (0..k)
        .map(|i| poly[i].perp_dot(poly[(i + 1) % k]))
        .sum::<f64>()
        / 2.0
}

/// Words as bytes, for a buffer.
fn bytes(words: impl Iterator<Item = u32>) -> Vec<u8> {
    words.flat_map(u32::to_ne_bytes).collect()
}

impl Poly {
    fn words(&self) -> [u32; 12] {
        [
            self.r0,
            self.r1,
            self.c0,
            self.c1,
            self.base,
            self.first,
            self.ntouch,
            self.ninside,
            self.far,
            self.tag,
            self.kind,
            self.pad,
        ]
    }
}
