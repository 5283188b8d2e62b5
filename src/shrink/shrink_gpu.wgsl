// The shrinking oracle's cube map on the GPU (shrink_gpu.rs).
//
// `draw`: one invocation per (polygon, row): the row's touched columns
// (within the polygon's pixel box; each pixel's square grown by `margin`,
// and within `margin` of every touch line) and its inside columns (centre
// at least 2 `margin` inside every inside line) are solved line by line;
// a touched pixel takes the polygon's far value (atomicMax on the f32
// bits, all positive) and its solid's tag, with the inside bit where the
// centre is inside; an outline edge sets the outline bit instead.
//
// `resolve`: one invocation per pixel of the batch's tiles: a pixel inside and not on the
// outline is covered by its solid with D = far, merged into the maps by
// the smaller D; the scratch is cleared for the next batch.
//
// No infinities: an empty pixel holds f32::MAX (D) and -f32::MAX (F), as
// does a solid without a floor (F), mapped to infinities on the CPU.

struct Params {
    n: u32,
    start: u32,
    count: u32,
    pixels: u32,
    margin: f32,
    tile: u32,
    tiles: u32,
    // Where the solids start in `items`.
    solids: u32,
}

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

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> polys: array<Poly>;
@group(0) @binding(2) var<storage, read> lines: array<vec4<f32>>;
// The (polygon, row) items, then the batches' tiles (x), then per solid
// (tag - 1) its floor's f32 bits and whether it has a floor.
@group(0) @binding(3) var<storage, read> items: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read_write> far: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> flags: array<atomic<u32>>;
@group(0) @binding(7) var<storage, read_write> depth: array<f32>;
@group(0) @binding(4) var<storage, read_write> depth_floor: array<f32>;
@group(0) @binding(8) var<storage, read_write> floor_of: array<f32>;

// Kinds of polygon.
const FACE: u32 = 0u;
const OUTLINE: u32 = 1u;
const FACE_TOUCH_ONLY: u32 = 2u;

@compute @workgroup_size(64)
fn draw(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.count) {
        return;
    }
    let item = items[params.start + i];
    let p = polys[item.x];
    let row = item.y;
    let m = params.margin;
    let y0 = f32(row) - m;
    let y1 = f32(row) + 1.0 + m;
    let yc = f32(row) + 0.5;
    let top = f32(params.n) + 8.0;
    // Touched columns: those whose square grown by m has its best corner
    // within m of (or inside) every touch line, solved per line.
    var lo = i32(p.c0);
    var hi = i32(p.c1);
    for (var k = 0u; k < p.ntouch; k++) {
        let l = lines[p.first + k];
        let kk = l.y * select(y0, y1, l.y > 0.0) + l.z + m;
        if (l.x > 0.0) {
            // l.x (col + 1 + m) + kk >= 0
            lo = max(lo, i32(ceil(clamp(-kk / l.x - 1.0 - m, -8.0, top))));
        } else if (l.x < 0.0) {
            // l.x (col - m) + kk >= 0
            hi = min(hi, i32(floor(clamp(-kk / l.x + m, -8.0, top))));
        } else if (kk < 0.0) {
            return;
        }
    }
    if (lo > hi) {
        return;
    }
    // Columns whose centre is at least 2 m inside every inside line.
    var ilo = lo;
    var ihi = hi;
    if (p.kind != FACE) {
        ilo = hi + 1;
    }
    for (var k = 0u; k < p.ninside && p.kind == FACE; k++) {
        let l = lines[p.first + p.ntouch + k];
        let kk = l.y * yc + l.z - 2.0 * m;
        if (l.x > 0.0) {
            // l.x (col + 0.5) + kk >= 0
            ilo = max(ilo, i32(ceil(clamp(-kk / l.x - 0.5, -8.0, top))));
        } else if (l.x < 0.0) {
            ihi = min(ihi, i32(floor(clamp(-kk / l.x - 0.5, -8.0, top))));
        } else if (kk < 0.0) {
            ilo = hi + 1;
        }
    }
    let base = p.base + row * params.n;
    let outline = (p.tag << 2u) | 2u;
    let touched = p.tag << 2u;
    let inside = touched | 1u;
    for (var c = lo; c <= hi; c++) {
        let px = base + u32(c);
        // Atomics only where they change something (plain loads first:
        // on a CPU driver an atomic costs far more than a load).
        var bits = outline;
        if (p.kind != OUTLINE) {
            if (atomicLoad(&far[px]) < p.far) {
                atomicMax(&far[px], p.far);
            }
            bits = select(touched, inside, c >= ilo && c <= ihi);
        }
        if ((atomicLoad(&flags[px]) & bits) != bits) {
            atomicOr(&flags[px], bits);
        }
    }
}

@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>) {
    // The pixels of the batch's tiles (`tile` pixels on a side, `tiles`
    // tiles on a side of a face).
    let j = gid.y * nw.x * 256u + gid.x;
    if (j >= params.count) {
        return;
    }
    let ts = params.tile;
    let per = ts * ts;
    let t = items[params.start + j / per].x;
    let w = j % per;
    let tps = params.tiles;
    let face = t / (tps * tps);
    let row = ((t / tps) % tps) * ts + w / ts;
    let col = (t % tps) * ts + w % ts;
    let i = (face * params.n + row) * params.n + col;
    let f = atomicLoad(&flags[i]);
    if (f == 0u) {
        return;
    }
    let d = bitcast<f32>(atomicLoad(&far[i]));
    atomicStore(&flags[i], 0u);
    atomicStore(&far[i], 0u);
    if ((f & 3u) != 1u) {
        return;
    }
    let s = items[params.solids + (f >> 2u) - 1u];
    let fl = bitcast<f32>(s.x);
    if (s.y == 0u) {
        depth[i] = min(depth[i], d);
    }
    let df = depth_floor[i];
    if (d < df || (d == df && fl < floor_of[i])) {
        depth_floor[i] = d;
        floor_of[i] = fl;
    }
}
