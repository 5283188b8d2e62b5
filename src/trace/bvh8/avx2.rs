//! The traversal of [`Bvh8`] compiled for CPUs with AVX2 (chosen at run
//! time): the eight slab tests of a node in one 256-bit pass, and a
//! leaf's triangles in another (see the parent module for the design and
//! why the answers are exact).

use std::arch::x86_64::*;

use super::{
    Bvh8, Hit, LANES, LEAF, NO_HIT, Pack, Ray, STACK, ScaledRay, Shear, Tracer, WIDTH, leaf_packs,
};

/// Eight f32 as a register.
#[inline]
#[target_feature(enable = "avx")]
fn load(a: &[f32; WIDTH]) -> __m256 {
    bytemuck::cast(*a)
}

/// The traversal's stack: (child reference, entry `t`) pairs. Made once
/// for many rays (it is 2 KiB).
pub(in crate::trace) type Stack = [(u32, f32); STACK];

/// A new [`Stack`].
pub(in crate::trace) fn stack() -> Stack {
    [(0, 0.0); STACK]
}

/// Asks the CPU to start loading what `reference` points to, to be read
/// when it is popped: six cache lines from its start, a leaf's two packs
/// or a node's four lines and two past them. The address is a select, not
/// a branch (which mispredicted on the mix of leaves and nodes pushed), and
/// the same six lines whatever it points to: 1-5% faster on x18's and San
/// Francisco's rays (notes/trace.md, stop 52).
#[inline(always)]
fn prefetch(bvh: &Bvh8, reference: u32) {
    let (first, _) = leaf_packs(reference);
    let leaf = bvh.packs.as_ptr().wrapping_add(first) as usize;
    let node = bvh.nodes.as_ptr().wrapping_add(reference as usize) as usize;
    // All ones for a leaf, else zero.
    let is_leaf = (((reference & LEAF) >> 31) as usize).wrapping_neg();
    let p = ((leaf & is_leaf) | (node & !is_leaf)) as *const u8;
    for k in 0..6 {
        // SAFETY: a prefetch never faults and reads nothing the program
        // sees, whatever the address (past the end of an allocation too).
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * k).cast()) }
    }
}

/// The closest hit of `ray` on an occluder or on `target` (see
/// [`Tracer::closest_hit_towards`]), with `stack` as scratch.
#[target_feature(enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
pub(in crate::trace) fn closest_hit(
    tracer: &Tracer,
    bvh: &Bvh8,
    ray: &Ray,
    target: u32,
    stack: &mut Stack,
) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let scaled = ScaledRay::new(ray, tracer.dir_exponent);
    if scaled.ray.tmin.is_sign_negative() {
        visit::<false>(tracer, bvh, &scaled, target, stack)
    } else {
        visit::<true>(tracer, bvh, &scaled, target, stack)
    }
}

/// [`closest_hit`]'s traversal, for the ray as [`ScaledRay`] made it.
///
/// A node's entry and exit distances are the maximum and minimum of its
/// slab distances compared as signed 32-bit integers (one cycle each,
/// where the float instructions take four; Embree's traversal does the
/// same), and with `POSITIVE` (a ray whose `tmin` has its sign bit clear:
/// every ray the builder casts) a child is entered unless its entry is
/// above its exit as integers too; without it, as floats. The children
/// entered are those the float code enters but for intervals that hold
/// no hit, and the hit is the same:
/// - floats with the sign bit clear order as their bits do (`+inf` too),
///   and any with it set (`-0.0` too) is a negative integer, below every
///   float with it clear. Floats with it set order in reverse: the larger
///   magnitude, the larger integer. A child's slab distances are never
///   NaN (its bounds are finite); an empty slot's are where the origin
///   times the inverse direction's cap overflows (origins some 2^58
///   scene sizes away, far outside what the padding covers), and the
///   NaN the CPU makes has its sign bit set, like every exit of an empty
///   slot (`-inf` or NaN), so such a slot is never entered (the float
///   code of 94831d3 entered it there and read past the nodes, a review
///   found);
/// - the entry: where a distance (or `tmin`) has its sign bit clear, the
///   integer maximum is the float maximum (but for the sign of a zero,
///   which no comparison sees); where none has, it is the float
///   minimum, at most the float maximum;
/// - the exit: where every distance (and `tmax`) has its sign bit clear,
///   the integer minimum is the float minimum; otherwise it is the value
///   with the sign bit set nearest zero, at least the float minimum;
/// - so the float test `enter <= leave` enters every child the float
///   entry and exit do, and a child's entry distance is never above the
///   float one (the stack drops no entry the float code keeps);
/// - with `POSITIVE` the entry has its sign bit clear, and so has `tmax`
///   (kept `+0.0` where a hit at `t = -0.0`, the origin on a triangle,
///   would make it `-0.0`), so the integer test agrees with
///   the float one but where a slab's exit is `-0.0` and the entry `+0.0`
///   (the float test enters): an interval of length zero. A slab exit
///   rounds to `-0.0` only where the origin is within rounding of the
///   exit plane, and every hit lies inside its triangle's padded box for
///   a margin of `t` before and after it (`BOX_PAD`), so no such child
///   holds a hit. (Without `POSITIVE` an entry and exit both below zero
///   would compare in reverse.)
///
/// The leaves' tests are exact, so visiting more changes no hit.
#[inline]
#[target_feature(enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn visit<const POSITIVE: bool>(
    tracer: &Tracer,
    bvh: &Bvh8,
    scaled: &ScaledRay,
    target: u32,
    stack: &mut Stack,
) -> Option<Hit> {
    let r = &scaled.ray;
    let shear = Shear::new(r);
    let sheared = Sheared::new(&shear);
    let tmin = r.tmin;
    // `+ 0.0`: `tmax` is never `-0.0` (below every entry as an integer),
    // here or after a hit at `t = -0.0` (the origin on a triangle).
    let mut tmax = r.tmax + 0.0;
    let mut best = NO_HIT;
    // `a < b` for the distances the traversal compares (entries and
    // `tmax`): with `POSITIVE` all have the sign bit clear and order as
    // their bits do, compared as integers.
    let before = |a: f32, b: f32| {
        if POSITIVE {
            a.to_bits() < b.to_bits()
        } else {
            a < b
        }
    };
    let origin = [r.origin.x, r.origin.y, r.origin.z];
    let inv = [r.inv_direction.x, r.inv_direction.y, r.inv_direction.z];
    // The rows of a node's bounds ([`Node::rows`]) a ray enters and
    // leaves the children's slabs by, per axis: chosen once per ray.
    let near: [usize; 3] = [0, 1, 2].map(|k| if inv[k] < 0.0 { 3 + k } else { k });
    let far = near.map(|r| (r + 3) % 6);
    let rinv = inv.map(|v| _mm256_set1_ps(v));
    let org_rinv = [0, 1, 2].map(|k| _mm256_set1_ps(origin[k] * inv[k]));
    let tmin_v = _mm256_set1_ps(tmin);

    // The reference visited now (entered within `tmax`), and the stack of
    // those entered but not visited yet.
    let mut current = bvh.root;
    let mut top = 0usize;
    'visit: loop {
        if current & LEAF != 0 {
            let (first, count) = leaf_packs(current);
            {
                let (lo, hi) = (&bvh.packs[first], &bvh.packs[first + count - 1]);
                let both = count == 2;
                tmax = test_packs(
                    tracer, &sheared, &shear, lo, hi, both, target, tmin, tmax, &mut best,
                ) + 0.0;
            }
        } else {
            let node = &bvh.nodes[current as usize];
            let rows = node.rows();
            let slab = |k: usize| {
                (
                    _mm256_fmsub_ps(load(&rows[near[k]]), rinv[k], org_rinv[k]),
                    _mm256_fmsub_ps(load(&rows[far[k]]), rinv[k], org_rinv[k]),
                )
            };
            let (nx, fx) = slab(0);
            let (ny, fy) = slab(1);
            let (nz, fz) = slab(2);
            // The entry and exit as the integer maximum and minimum of
            // the distances' bits, compared as integers (see the
            // function's notes).
            let bits = _mm256_castps_si256;
            let max = |a, b| _mm256_castsi256_ps(_mm256_max_epi32(bits(a), bits(b)));
            let min = |a, b| _mm256_castsi256_ps(_mm256_min_epi32(bits(a), bits(b)));
            let enter = max(max(nx, ny), max(nz, tmin_v));
            let leave = min(min(fx, fy), min(fz, _mm256_set1_ps(tmax)));
            // The lanes entered, as a vector (all ones) and as bits.
            let entered = if POSITIVE {
                let beyond = _mm256_cmpgt_epi32(bits(enter), bits(leave));
                _mm256_xor_si256(beyond, _mm256_set1_epi32(-1))
            } else {
                bits(_mm256_cmp_ps::<_CMP_LE_OQ>(enter, leave))
            };
            let mut mask = _mm256_movemask_ps(_mm256_castsi256_ps(entered)) as u32;
            if mask & mask.wrapping_sub(1) == 0 && mask != 0 {
                // One child entered: visit it next, no stack.
                current = node.child[mask.trailing_zeros() as usize % WIDTH];
                continue 'visit;
            }
            if mask != 0 {
                // Visit the nearest child entered next, and push the
                // others, farthest at the bottom. Each goes straight to
                // its place, its rank among them (`ranks`): no insertion
                // loop, whose branches mispredicted. The nearest is taken
                // from the ranks in registers, not read back from the
                // stack; it is stored too (above the top, where the next
                // push overwrites it) and prefetched with the others:
                // leaving it out of the loop made the loop wait for the
                // ranks and the prefetches start later (6-8% slower).
                let rv = ranks::<POSITIVE>(enter, entered);
                let rank: [u32; WIDTH] = bytemuck::cast(rv);
                let enter: [f32; WIDTH] = bytemuck::cast(enter);
                let base = top;
                let n = mask.count_ones();
                let nearest = _mm256_cmpeq_epi32(rv, _mm256_set1_epi32(n as i32 - 1));
                let nearest = _mm256_movemask_ps(_mm256_castsi256_ps(nearest)) as u32;
                current = node.child[nearest.trailing_zeros() as usize % WIDTH];
                top += n as usize - 1;
                while mask != 0 {
                    let lane = mask.trailing_zeros() as usize % WIDTH;
                    mask &= mask - 1;
                    let child = node.child[lane];
                    prefetch(bvh, child);
                    stack[(base + rank[lane] as usize) % STACK] = (child, enter[lane]);
                }
                continue 'visit;
            }
        }
        // The next entry that starts within `tmax`.
        loop {
            if top == 0 {
                break 'visit;
            }
            top -= 1;
            let (reference, enter) = stack[top % STACK];
            if !before(tmax, enter) {
                current = reference;
                continue 'visit;
            }
        }
    }
    tracer.hit(best, scaled.t_factor)
}

/// For each lane of `entered` (all ones where a child is entered), how
/// many entered children are farther: its place among them counted from
/// the farthest, 0 to one less than their number, each once. Farther is a
/// larger entry distance (its bits as an integer, made to order as the
/// floats do where the sign bit is set), with the three lowest bits
/// given over to the lane, so that the keys differ: distances within
/// eight ulps count as tied, and of those the lower lane as farther (as
/// the insertion that this replaced ordered them). The order decides only
/// which child is visited first, not what is hit: an entry popped is
/// tested against `tmax` with its exact distance.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn ranks<const POSITIVE: bool>(enter: __m256, entered: __m256i) -> __m256i {
    let b = _mm256_castps_si256(enter);
    // Floats with the sign bit set order in reverse as integers: flip the
    // others (with `POSITIVE` every distance entered has the sign bit
    // clear, and the flip is left out: the nearest child waits on the
    // ranks).
    let b = if POSITIVE {
        b
    } else {
        _mm256_xor_si256(b, _mm256_srli_epi32::<1>(_mm256_srai_epi32::<31>(b)))
    };
    let lanes = _mm256_setr_epi32(7, 6, 5, 4, 3, 2, 1, 0);
    let key = _mm256_or_si256(_mm256_andnot_si256(_mm256_set1_epi32(7), b), lanes);
    // A lane not entered is never farther than one entered, and never
    // ties with one: keyed -1 (all ones) with `POSITIVE`, where entered
    // keys are at least zero (one instruction, not a blend), else the
    // least integer.
    let key = if POSITIVE {
        _mm256_or_si256(key, _mm256_andnot_si256(entered, _mm256_set1_epi32(-1)))
    } else {
        _mm256_blendv_epi8(_mm256_set1_epi32(i32::MIN), key, entered)
    };
    let mut rank = _mm256_setzero_si256();
    let mut turn = _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 0);
    for _ in 1..WIDTH {
        let other = _mm256_permutevar8x32_epi32(key, turn);
        rank = _mm256_sub_epi32(rank, _mm256_cmpgt_epi32(other, key));
        turn = _mm256_and_si256(
            _mm256_add_epi32(turn, _mm256_set1_epi32(1)),
            _mm256_set1_epi32(7),
        );
    }
    rank
}

/// A [`Shear`] as registers: the origin's coordinates in the sheared
/// frame's axis order, and the shear's three factors, in every lane.
struct Sheared {
    origin: [__m256; 3],
    s: [__m256; 3],
}

impl Sheared {
    /// `shear` in registers. The origin's coordinates are picked from a
    /// register by lane (`vpermps`), not read back from memory by index:
    /// the copy the compiler made for that read loaded eight bytes across
    /// two of the stores just made, which the CPU cannot forward (on a
    /// scene of two triangles, 52 -> 44 ns a ray; notes/trace.md, stop
    /// 52).
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn new(shear: &Shear) -> Self {
        let [x, y, z] = shear.origin;
        let o = _mm256_setr_ps(x, y, z, 0.0, 0.0, 0.0, 0.0, 0.0);
        Self {
            origin: shear
                .k
                .map(|k| _mm256_permutevar8x32_ps(o, _mm256_set1_epi32(k as i32))),
            s: shear.s.map(|s| _mm256_set1_ps(s)),
        }
    }
}

/// [`Tracer::offer`] of each triangle of packs `lo` and `hi` (lanes 0-3
/// and 4-7; `hi` counts only when `both`), the watertight test of
/// [`Shear::intersect`] run on all lanes at once with the same operations
/// in the same order (so the same `t`, bit for bit); a lane with an edge
/// function of zero is left to the scalar test, which decides it in f64.
#[inline(never)]
#[target_feature(enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[allow(clippy::too_many_arguments)]
fn test_packs(
    tracer: &Tracer,
    sheared: &Sheared,
    shear: &Shear,
    lo: &Pack,
    hi: &Pack,
    both: bool,
    target: u32,
    tmin: f32,
    mut tmax: f32,
    best: &mut (f32, u32),
) -> f32 {
    let [kx, ky, kz] = shear.k;
    let [ox, oy, oz] = sheared.origin;
    let [sx, sy, sz] = sheared.s;
    let ld = |k: usize, axis: usize| -> __m256 { bytemuck::cast([lo.v[k][axis], hi.v[k][axis]]) };
    // A corner's sheared x and y, and its z scaled by the shear's sz.
    let corner = |k: usize| {
        let x = _mm256_sub_ps(ld(k, kx), ox);
        let y = _mm256_sub_ps(ld(k, ky), oy);
        let z = _mm256_sub_ps(ld(k, kz), oz);
        (
            _mm256_sub_ps(x, _mm256_mul_ps(sx, z)),
            _mm256_sub_ps(y, _mm256_mul_ps(sy, z)),
            _mm256_mul_ps(sz, z),
        )
    };
    let (ax, ay, az) = corner(0);
    let (bx, by, bz) = corner(1);
    let (cx, cy, cz) = corner(2);
    let u = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
    let v = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
    let w = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));
    let zero = _mm256_setzero_ps();
    let cmp_any = |f: fn(__m256, __m256) -> __m256| {
        _mm256_or_ps(_mm256_or_ps(f(u, zero), f(v, zero)), f(w, zero))
    };
    let on_edge = cmp_any(|a, b| _mm256_cmp_ps::<_CMP_EQ_OQ>(a, b));
    let negative = cmp_any(|a, b| _mm256_cmp_ps::<_CMP_LT_OQ>(a, b));
    let positive = cmp_any(|a, b| _mm256_cmp_ps::<_CMP_GT_OQ>(a, b));
    let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
    let tt = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(u, az), _mm256_mul_ps(v, bz)),
        _mm256_mul_ps(w, cz),
    );
    // Both negated where det < 0 (det == 0 is no hit).
    let sign = _mm256_and_ps(det, _mm256_set1_ps(-0.0));
    let tt = _mm256_xor_ps(tt, sign);
    let det = _mm256_xor_ps(det, sign);
    let t = _mm256_div_ps(tt, det);
    let inside = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GE_OQ>(t, _mm256_set1_ps(tmin)),
        _mm256_cmp_ps::<_CMP_LE_OQ>(t, _mm256_set1_ps(tmax)),
    );
    let miss = _mm256_or_ps(
        _mm256_and_ps(negative, positive),
        _mm256_cmp_ps::<_CMP_EQ_OQ>(det, zero),
    );
    let lanes = if both { 0xff } else { 0x0f };
    let mut hits =
        _mm256_movemask_ps(_mm256_andnot_ps(_mm256_or_ps(miss, on_edge), inside)) as u32 & lanes;
    let mut edges = _mm256_movemask_ps(on_edge) as u32 & lanes;
    if hits | edges == 0 {
        return tmax;
    }
    let t: [f32; 2 * LANES] = bytemuck::cast(t);
    let pack = |lane: usize| {
        if lane < LANES {
            (lo, lane)
        } else {
            (hi, lane - LANES)
        }
    };
    let limit = tmax;
    while hits != 0 {
        let lane = hits.trailing_zeros() as usize;
        hits &= hits - 1;
        let (p, l) = pack(lane);
        if tracer.passes_through(p.object[l], target) {
            continue;
        }
        let (t, id) = (t[lane], p.id[l]);
        if t < best.0 || (t == best.0 && id < best.1) {
            *best = (t, id);
        }
        if t < tmax {
            tmax = t;
        }
    }
    while edges != 0 {
        let lane = edges.trailing_zeros() as usize;
        edges &= edges - 1;
        let (p, l) = pack(lane);
        // The lanes above were tested within `limit`; so is this one.
        let mut lane_tmax = limit;
        tracer.offer(shear, &p.tri(l), target, tmin, &mut lane_tmax, best);
        if lane_tmax < tmax {
            tmax = lane_tmax;
        }
    }
    tmax
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`ranks`] places the children entered at 0 to one less than their
    /// number, each once, the farthest lowest, and never gives a lane
    /// not entered the top place (the nearest child is the lane ranked
    /// one less than their number): on ties, zeros (origins inside a
    /// box), negative distances and every mask.
    #[test]
    fn ranks_place_each_child_entered_once() {
        if !crate::trace::wide_cpu() {
            return;
        }
        let values = [0.0f32, 0.0, 1.0, 1.0, 2.5, 1e-40, 3e5, 7.0];
        let negative = [-0.0f32, -1.0, 0.0, -3e5, 2.0, -1e-40, 1.0, -1.0];
        let mut seed = 1u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for _ in 0..2000 {
            for positive in [true, false] {
                let pool = if positive { &values } else { &negative };
                let enter: [f32; WIDTH] =
                    std::array::from_fn(|_| pool[next() as usize % pool.len()]);
                let mask = next() & 0xff;
                let entered: [i32; WIDTH] =
                    std::array::from_fn(|l| if mask >> l & 1 == 1 { -1 } else { 0 });
                // SAFETY: the CPU has the features (checked above).
                let rank: [i32; WIDTH] = bytemuck::cast(unsafe {
                    let (e, m) = (bytemuck::cast(enter), bytemuck::cast(entered));
                    if positive {
                        ranks::<true>(e, m)
                    } else {
                        ranks::<false>(e, m)
                    }
                });
                let n = mask.count_ones() as i32;
                let mut seen = [false; WIDTH];
                for l in 0..WIDTH {
                    if mask >> l & 1 == 1 {
                        assert!((0..n).contains(&rank[l]), "{enter:?} {mask:08b} {rank:?}");
                        assert!(!seen[rank[l] as usize], "{enter:?} {mask:08b} {rank:?}");
                        seen[rank[l] as usize] = true;
                        for k in 0..WIDTH {
                            if mask >> k & 1 == 1 && enter[k] > enter[l] {
                                assert!(rank[k] < rank[l], "{enter:?} {mask:08b} {rank:?}");
                            }
                        }
                    } else {
                        assert_ne!(rank[l], n - 1, "{enter:?} {mask:08b} {rank:?}");
                    }
                }
            }
        }
    }
}
