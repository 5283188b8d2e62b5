// The shrinking oracle's cube map on the GPU (shrink_gpu.rs).
//
// `draw`: one invocation per (polygon, row): the pixels of the row within
// the polygon's pixel box are tested against its touch lines (each pixel's
// square grown by `margin`); a touched pixel takes the polygon's far value
// (atomicMax on the f32 bits, all positive) and its solid's tag, and the
// inside bit when its centre is inside every inside line by `margin`; an
// outline edge sets the outline bit instead.
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
    pad: u32,
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
@group(0) @binding(3) var<storage, read> items: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read> solids: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read_write> far: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> flags: array<atomic<u32>>;
@group(0) @binding(7) var<storage, read_write> maps: array<f32>;
@group(0) @binding(8) var<storage, read> tiles: array<u32>;

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
    // The columns no touch line rules out, solved per line (in f32, so
    // widened by a pixel each way: the test per pixel below decides).
    var lo = i32(p.c0);
    var hi = i32(p.c1);
    let top = f32(params.n) + 8.0;
    for (var k = 0u; k < p.ntouch; k++) {
        let l = lines[p.first + k];
        let kk = l.y * select(y0, y1, l.y > 0.0) + l.z;
        if (l.x > 0.0) {
            lo = max(lo, i32(floor(clamp(-kk / l.x - 1.0 - m, -8.0, top))) - 1);
        } else if (l.x < 0.0) {
            hi = min(hi, i32(floor(clamp(-kk / l.x + m, -8.0, top))) + 1);
        }
    }
    if (lo > hi) {
        return;
    }
    for (var col = u32(lo); col <= u32(hi); col++) {
        let x0 = f32(col) - m;
        let x1 = f32(col) + 1.0 + m;
        var touch = true;
        for (var k = 0u; k < p.ntouch; k++) {
            let l = lines[p.first + k];
            let x = select(x0, x1, l.x > 0.0);
            let y = select(y0, y1, l.y > 0.0);
            if (l.x * x + l.y * y + l.z < 0.0) {
                touch = false;
                break;
            }
        }
        if (!touch) {
            continue;
        }
        let px = p.base + row * params.n + col;
        if (p.kind == OUTLINE) {
            atomicOr(&flags[px], (p.tag << 2u) | 2u);
            continue;
        }
        atomicMax(&far[px], p.far);
        var inside = p.kind == FACE;
        if (inside) {
            let xc = f32(col) + 0.5;
            for (var k = 0u; k < p.ninside; k++) {
                let l = lines[p.first + p.ntouch + k];
                if (l.x * xc + l.y * yc + l.z < m) {
                    inside = false;
                    break;
                }
            }
        }
        atomicOr(&flags[px], (p.tag << 2u) | select(0u, 1u, inside));
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
    let t = tiles[params.start + j / per];
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
    let s = solids[(f >> 2u) - 1u];
    let fl = bitcast<f32>(s.x);
    if (s.y == 0u) {
        maps[i] = min(maps[i], d);
    }
    let pf = params.pixels + i;
    let df = maps[pf];
    if (d < df || (d == df && fl < maps[pf + params.pixels])) {
        maps[pf] = d;
        maps[pf + params.pixels] = fl;
    }
}
