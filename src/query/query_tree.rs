//! The tree as queries hold it (issue 15, "memory"): the splits, and the
//! sets kept coded, decoded on the way down.
//!
//! A decoded tree with one bitset per node took 5 to 18 times its file's
//! size (notes/query.md). Here each internal node keeps 12 bytes (its
//! split, where its below subtree ends, where its children's codes start),
//! leaves keep nothing, and the sets are bits, coded as the file's third
//! coding codes them (papers/003 sec. 6, [`crate::codec::Coding::Sibling`]):
//! the root's set whole, then per internal node A with children B (below)
//! and C (above), the lighter child L (fewer objects; B on a tie) one bit
//! per object of A, and the heavier H one bit per object of L (an object of
//! A missing from L is in H, since A = B u C). Whatever the file's coding,
//! the tree is coded this way in memory.
//!
//! A query descends from the root (a recursion, at most
//! [`crate::tree::MAX_DEPTH`] deep) with the sets of the nodes on its path
//! decoded into scratch words: the lighter child by depositing its bits at
//! the parent's objects (`pdep`: one instruction per 64 objects where the
//! CPU has BMI2, a loop over the objects elsewhere), the heavier one from
//! the parent, the lighter one and its own bits. Only the words between the
//! first and the last non-empty word of the parent are touched, so sparse
//! sets (one apartment of a block of 18) cost what their objects cost. The
//! scratch, two sets per level, is per thread: the first query on a thread
//! allocates it, none after (`tests/no_alloc.rs`).
//!
//! Every walk passes through the top of the tree: there the children's
//! sets are kept decoded, for the top levels (up to [`CACHE_LEVELS`]) whose
//! sets take at most a quarter of the codes' size (the apartment: 6 levels,
//! 3 KB beside 19 KB of codes; a quarter of the nodes a view visits).
//!
//! A leaf's preorder rank (the index of its slices) is
//! counted on the way down: going above at internal node k skips the
//! leaves of its below subtree, `end_below[k] - k` of them (a full binary
//! subtree has one leaf more than it has internal nodes).

use std::cell::Cell as StdCell;

use crate::codec::CodecError;
use crate::geom::cell::{Cell, DIMS};
use crate::tree::Node;

/// The split dimension, in the low bits of [`Inner::split`].
const DIM_MASK: u32 = 0b111;
/// The below child is a leaf.
const BELOW_LEAF: u32 = 1 << 3;
/// The above child is a leaf.
const ABOVE_LEAF: u32 = 1 << 4;
/// The above child is the lighter one (its code comes first).
const ABOVE_LIGHTER: u32 = 1 << 5;
/// The children's sets are kept decoded: [`Inner::offset`] is where, in
/// words of [`CodedTree::cache`] (the lighter child's, then the heavier's).
const CACHED: u32 = 1 << 6;
/// The most top levels whose children's sets are kept decoded.
const CACHE_LEVELS: usize = 6;
/// The split code's shift in [`Inner::split`] (codes have at most
/// [`crate::tree::MAX_GRID_BITS`] = 16 bits).
const CODE_SHIFT: u32 = 16;

/// One internal node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Inner {
    /// Dimension, child kinds, which child is lighter, split code.
    split: u32,
    /// The index of the first internal node after the below subtree: the
    /// above child's index when that is internal.
    end_below: u32,
    /// The bit offset of the children's codes in [`CodedTree::code`], or
    /// with [`CACHED`] the word offset of their sets in
    /// [`CodedTree::cache`].
    offset: u32,
}

impl Inner {
    fn dim(self) -> usize {
        (self.split & DIM_MASK) as usize
    }

    fn code(self) -> u32 {
        self.split >> CODE_SHIFT
    }

    fn has(self, flag: u32) -> bool {
        self.split & flag != 0
    }
}

/// The tree of a loaded file with its sets coded (see the module docs).
#[derive(Clone, Debug)]
pub(crate) struct CodedTree {
    root: Cell,
    /// 2^-q: a split code times it is the split's place in its range
    /// (exact, as [`crate::geom::cell::grid_value`]'s division by 2^q is).
    grid_step: f32,
    /// Words per set.
    words: usize,
    /// The root's set.
    root_set: Vec<u64>,
    /// The internal nodes, in preorder; empty when the root is a leaf.
    inner: Vec<Inner>,
    /// The children's codes, least significant bit first, and two more
    /// words of zeros (a read takes two words, from any position up to
    /// the codes' end).
    code: Vec<u64>,
    /// The children's sets of the top levels' nodes, decoded: every walk
    /// passes there (a quarter of the nodes a view visits on the
    /// apartment), for a few sets.
    cache: Vec<u64>,
    /// The most internal nodes on a path from the root.
    depth: usize,
    /// Whether the CPU deposits bits in one instruction (BMI2).
    bmi2: bool,
}

/// What a walk down the tree does with the sets it meets.
trait Visitor {
    /// Whether an internal node whose cell lies inside the range gives
    /// its own set (the union of its leaves') rather than its leaves'.
    const WHOLE_NODES: bool;

    /// A set met: a node's (whole), or a leaf's with its preorder rank.
    /// The set is `set[words]`, zero elsewhere (whatever `set` holds
    /// there: scratch words outside are stale).
    fn set(&mut self, leaf_rank: Option<u32>, set: &[u64], words: std::ops::Range<usize>);
}

/// ORs the sets met into `out`.
struct Union<'a> {
    out: &'a mut [u64],
}

impl Visitor for Union<'_> {
    const WHOLE_NODES: bool = true;

    #[inline(always)]
    fn set(&mut self, _: Option<u32>, set: &[u64], words: std::ops::Range<usize>) {
        for (a, b) in self.out[words.clone()].iter_mut().zip(&set[words]) {
            *a |= b;
        }
    }
}

/// Collects the leaves met: their ranks and sets.
struct Leaves<'a> {
    words: usize,
    ranks: &'a mut Vec<u32>,
    sets: &'a mut Vec<u64>,
}

impl Visitor for Leaves<'_> {
    const WHOLE_NODES: bool = false;

    fn set(&mut self, leaf_rank: Option<u32>, set: &[u64], words: std::ops::Range<usize>) {
        self.ranks.push(leaf_rank.unwrap_or(0));
        let at = self.sets.len();
        self.sets.resize(at + self.words, 0);
        self.sets[at + words.start..at + words.end].copy_from_slice(&set[words]);
    }
}

/// Puts bits at the set bits of a mask, in order (`pdep`), and walks on
/// with the same instruction.
trait Deposit: Sized {
    /// The low bits of `bits`, as many as `mask` has (the others are not
    /// read), at the set bits of `mask`.
    fn deposit(bits: u64, mask: u64) -> u64;

    /// Walks the subtree of internal node `at` ([`CodedTree::visit`]).
    fn recurse<V: Visitor, const N: usize>(
        tree: &CodedTree,
        walk: &mut Walk<'_, V>,
        at: At<'_>,
        scratch: &mut [u64],
    );
}

/// A loop over the mask's bits: any CPU.
struct Soft;

impl Deposit for Soft {
    #[inline(always)]
    fn deposit(mut bits: u64, mut mask: u64) -> u64 {
        if mask == u64::MAX {
            return bits;
        }
        let mut out = 0;
        while mask != 0 {
            let low = mask & mask.wrapping_neg();
            out |= low & (bits & 1).wrapping_neg();
            bits >>= 1;
            mask ^= low;
        }
        out
    }

    fn recurse<V: Visitor, const N: usize>(
        tree: &CodedTree,
        walk: &mut Walk<'_, V>,
        at: At<'_>,
        scratch: &mut [u64],
    ) {
        tree.visit::<Soft, V, N>(walk, at, scratch);
    }
}

/// The BMI2 instruction; only used once the CPU is known to have it
/// ([`CodedTree::bmi2`]).
#[cfg(target_arch = "x86_64")]
struct Bmi2;

#[cfg(target_arch = "x86_64")]
impl Deposit for Bmi2 {
    #[inline(always)]
    fn deposit(bits: u64, mask: u64) -> u64 {
        // SAFETY: `Bmi2` is used only below `CodedTree::visit_bmi2`, reached
        // only when `is_x86_feature_detected!` said the CPU has BMI2 and
        // POPCNT.
        unsafe { std::arch::x86_64::_pdep_u64(bits, mask) }
    }

    fn recurse<V: Visitor, const N: usize>(
        tree: &CodedTree,
        walk: &mut Walk<'_, V>,
        at: At<'_>,
        scratch: &mut [u64],
    ) {
        // SAFETY: as for `deposit`: the CPU has BMI2 and POPCNT.
        unsafe { tree.visit_bmi2::<V, N>(walk, at, scratch) };
    }
}

/// The 64 bits of `code` from bit `pos` (at most where the codes end,
/// before the two spare words of zeros): a deposit takes the ones it
/// needs.
#[inline(always)]
fn read(code: &[u64], pos: usize) -> u64 {
    let i = pos >> 6;
    // Two words as one (a double shift on x86).
    let two = u128::from(code[i]) | (u128::from(code[i + 1]) << 64);
    (two >> (pos & 63)) as u64
}

/// Decodes the lighter child's `words` from `a`'s, its bits at `pos`;
/// the position after them.
#[inline(always)]
fn lighter<D: Deposit>(
    code: &[u64],
    mut pos: usize,
    a: &[u64],
    l: &mut [u64],
    words: std::ops::Range<usize>,
) -> usize {
    for w in words {
        // No branch on the word: a deposit at no bits is 0.
        let m = a[w];
        l[w] = D::deposit(read(code, pos), m);
        pos += m.count_ones() as usize;
    }
    pos
}

/// Decodes the heavier child's `words` from `a`'s and the lighter
/// child's `l`, its bits at `pos`.
#[inline(always)]
fn heavier<D: Deposit>(
    code: &[u64],
    mut pos: usize,
    a: &[u64],
    l: &[u64],
    h: &mut [u64],
    words: std::ops::Range<usize>,
) {
    for w in words {
        let m = l[w];
        h[w] = (a[w] & !m) | D::deposit(read(code, pos), m);
        pos += m.count_ones() as usize;
    }
}

/// The words of `set` within `words` with the empty ones at both ends
/// dropped (a few words are kept as they are: scanning them costs what
/// skipping them would save).
#[inline(always)]
fn tighten(set: &[u64], words: std::ops::Range<usize>) -> std::ops::Range<usize> {
    if words.len() <= 4 {
        return words;
    }
    let (mut lo, mut hi) = (words.start, words.end);
    while lo < hi && set[lo] == 0 {
        lo += 1;
    }
    while hi > lo && set[hi - 1] == 0 {
        hi -= 1;
    }
    lo..hi
}

/// The dimensions (bit d) in which `range` holds `cell`'s extent.
#[inline(always)]
fn covered_dims(range: &Cell, cell: &Cell) -> u8 {
    (0..DIMS).fold(0, |m, d| {
        m | (u8::from(range.lo[d] <= cell.lo[d] && range.hi[d] >= cell.hi[d]) << d)
    })
}

/// Every dimension: the range holds the cell.
const ALL_DIMS: u8 = (1 << DIMS) - 1;

/// Whether `range` holds all of `cell`.
#[cfg(test)]
fn covers(range: &Cell, cell: &Cell) -> bool {
    covered_dims(range, cell) == ALL_DIMS
}

/// A walk's range, what it does with the sets it meets, and the cell of
/// the node it is at: one cell for the whole walk, a bound changed on the
/// way down and put back on the way up (copying a cell per node, with one
/// bound written alone and the whole read back, cost a stalled load a
/// node).
struct Walk<'a, V> {
    range: &'a Cell,
    visitor: &'a mut V,
    cell: Cell,
}

/// An internal node as a walk reaches it (its cell is the walk's): its
/// index and set (zero outside `span`), the preorder rank of its first
/// leaf, [`covered_dims`] of its cell.
struct At<'a> {
    inner: u32,
    set: &'a [u64],
    span: std::ops::Range<usize>,
    rank: u32,
    covered: u8,
}

thread_local! {
    /// Each thread's scratch for the sets on a walk's path.
    static SCRATCH: StdCell<Vec<u64>> = const { StdCell::new(Vec::new()) };
}

/// Appends bits to a vector of words, least significant bit first.
struct BitPusher {
    words: Vec<u64>,
    len: usize,
}

impl BitPusher {
    fn push(&mut self, bits: u64, n: u32) {
        if n == 0 {
            return;
        }
        let s = (self.len & 63) as u32;
        if s == 0 {
            self.words.push(bits);
        } else {
            *self.words.last_mut().expect("a partial word") |= bits << s;
            if s + n > 64 {
                self.words.push(bits >> (64 - s));
            }
        }
        self.len += n as usize;
    }
}

/// The bits of `value` at the set bits of `mask`, packed (`pext`).
fn extract(value: u64, mut mask: u64) -> u64 {
    let (mut out, mut k) = (0u64, 0);
    while mask != 0 {
        let low = mask & mask.wrapping_neg();
        if value & low != 0 {
            out |= 1 << k;
        }
        k += 1;
        mask ^= low;
    }
    out
}

impl CodedTree {
    /// Codes a decoded tree (`nodes` in preorder, as [`crate::tree::VisTree`]
    /// holds them, each set of `objects` bits). An error when a node's
    /// children do not make up its set (a decoded tree always does) or the
    /// codes pass 2^32 bits.
    pub(crate) fn new(
        root: Cell,
        grid_bits: u32,
        objects: usize,
        nodes: &[Node],
    ) -> Result<CodedTree, CodecError> {
        CodedTree::with_cache(root, grid_bits, objects, nodes, None)
    }

    /// As [`CodedTree::new`], with the children's sets of the internal
    /// nodes in the top `levels` levels kept decoded; `None`: as many
    /// levels (up to [`CACHE_LEVELS`]) as fit in a quarter of the codes'
    /// size.
    pub(crate) fn with_cache(
        root: Cell,
        grid_bits: u32,
        objects: usize,
        nodes: &[Node],
        levels: Option<usize>,
    ) -> Result<CodedTree, CodecError> {
        let words = objects.div_ceil(64);
        // Each node's depth in internal nodes (the root's 0), the most
        // internal nodes on a path, the internal nodes before each node (the
        // internal index of an above child), and the codes' size, to choose
        // the cached levels.
        let mut depth_of = vec![0u8; nodes.len()];
        let mut depth = 0;
        let mut before = Vec::with_capacity(nodes.len() + 1);
        let mut count = 0u32;
        let mut per_level = [0usize; CACHE_LEVELS + 1];
        let mut code_bits = 0usize;
        for (i, node) in nodes.iter().enumerate() {
            before.push(count);
            let Some(s) = node.split else { continue };
            count += 1;
            let d = depth_of[i];
            depth = depth.max(usize::from(d) + 1);
            for child in [i + 1, s.above as usize] {
                if let Some(c) = depth_of.get_mut(child) {
                    *c = d.saturating_add(1);
                }
            }
            per_level[usize::from(d).min(CACHE_LEVELS)] += 1;
            let (b, c) = (nodes.get(i + 1), nodes.get(s.above as usize));
            let lighter = b
                .zip(c)
                .map_or(0, |(b, c)| b.set.count().min(c.set.count()));
            code_bits += node.set.count() + lighter;
        }
        let levels = levels.unwrap_or_else(|| {
            let budget = code_bits / 8 / 4;
            let mut cached = 0;
            let mut k = 0;
            while k < CACHE_LEVELS {
                cached += per_level[k];
                if cached * 2 * words * 8 > budget {
                    break;
                }
                k += 1;
            }
            k
        });
        before.push(count);
        let mut cache = Vec::new();
        let mut inner = Vec::with_capacity(count as usize);
        let mut pusher = BitPusher {
            words: Vec::new(),
            len: 0,
        };
        let is_leaf = |i: usize| nodes[i].split.is_none();
        for (i, node) in nodes.iter().enumerate() {
            let Some(s) = node.split else { continue };
            let (b, c) = (&nodes[i + 1].set, &nodes[s.above as usize].set);
            let a = node.set.words();
            let (bw, cw) = (b.words(), c.words());
            let whole = a
                .iter()
                .zip(bw.iter().zip(cw))
                .all(|(&a, (&b, &c))| b | c == a);
            if !whole {
                return Err(CodecError::Corrupt(format!(
                    "node {i}: its children's sets do not make up its own"
                )));
            }
            let above_lighter = c.count() < b.count();
            let (l, h) = if above_lighter { (cw, bw) } else { (bw, cw) };
            let cached = usize::from(depth_of[i]) < levels;
            let offset = if cached {
                let at = cache.len();
                cache.extend_from_slice(l);
                cache.extend_from_slice(h);
                u32::try_from(at).map_err(|_| {
                    CodecError::TooLarge("the decoded top levels pass 2^32 words".into())
                })?
            } else {
                let at = u32::try_from(pusher.len).map_err(|_| {
                    CodecError::TooLarge("the coded sets pass 2^32 bits in memory".into())
                })?;
                for (&a, &l) in a.iter().zip(l) {
                    pusher.push(extract(l, a), a.count_ones());
                }
                for (&l, &h) in l.iter().zip(h) {
                    pusher.push(extract(h, l), l.count_ones());
                }
                at
            };
            let flags = [
                (is_leaf(i + 1), BELOW_LEAF),
                (is_leaf(s.above as usize), ABOVE_LEAF),
                (above_lighter, ABOVE_LIGHTER),
                (cached, CACHED),
            ]
            .iter()
            .fold(0, |f, &(on, bit)| if on { f | bit } else { f });
            inner.push(Inner {
                split: u32::from(s.dim) | flags | (s.code << CODE_SHIFT),
                end_below: before[s.above as usize],
                offset,
            });
        }
        u32::try_from(pusher.len)
            .map_err(|_| CodecError::TooLarge("the coded sets pass 2^32 bits in memory".into()))?;
        let mut code = pusher.words;
        // Two words to spare: a read at the end takes two words.
        code.extend([0, 0]);
        code.shrink_to_fit();
        inner.shrink_to_fit();
        cache.shrink_to_fit();
        #[cfg(target_arch = "x86_64")]
        let bmi2 = std::is_x86_feature_detected!("bmi2") && std::is_x86_feature_detected!("popcnt");
        #[cfg(not(target_arch = "x86_64"))]
        let bmi2 = false;
        Ok(CodedTree {
            root,
            grid_step: 1.0 / (1u32 << grid_bits) as f32,
            words,
            root_set: nodes
                .first()
                .map_or_else(|| vec![0; words], |n| n.set.words().to_vec()),
            inner,
            code,
            cache,
            depth,
            bmi2,
        })
    }

    /// The bytes held: the struct and its vectors, by capacity.
    pub(crate) fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.root_set.capacity() * 8
            + self.inner.capacity() * std::mem::size_of::<Inner>()
            + self.code.capacity() * 8
            + self.cache.capacity() * 8
    }

    /// The words of a set.
    pub(crate) fn words(&self) -> usize {
        self.words
    }

    /// Nodes, leaves included.
    pub(crate) fn node_count(&self) -> usize {
        2 * self.inner.len() + 1
    }

    /// The split value of internal node `n` in `cell`: [`crate::geom::cell::grid_value`]'s.
    #[inline(always)]
    fn value(&self, n: Inner, cell: &Cell) -> f32 {
        let d = n.dim();
        let (lo, hi) = (cell.lo[d], cell.hi[d]);
        lo + (hi - lo) * (n.code() as f32 * self.grid_step)
    }

    /// ORs into `out` (of the tree's words) the sets of the leaves the
    /// range meets, a node whose cell the range holds giving its own.
    pub(crate) fn union(&self, range: &Cell, out: &mut [u64]) {
        self.walk(range, &mut Union { out });
    }

    /// The preorder ranks and sets (the tree's words each, flat) of the
    /// leaves the range meets, appended.
    pub(crate) fn leaves_met(&self, range: &Cell, ranks: &mut Vec<u32>, sets: &mut Vec<u64>) {
        let words = self.words;
        self.walk(range, &mut Leaves { words, ranks, sets });
    }

    /// Walks the nodes the range meets with this thread's scratch, the
    /// deposit the CPU has, and the set size fixed where it is small.
    fn walk<V: Visitor>(&self, range: &Cell, visitor: &mut V) {
        let words = self.words;
        let all = tighten(&self.root_set, 0..words);
        let covered = covered_dims(range, &self.root);
        if self.inner.is_empty() || (V::WHOLE_NODES && covered == ALL_DIMS) {
            visitor.set(self.inner.is_empty().then_some(0), &self.root_set, all);
            return;
        }
        // Outside a thread's lifetime (a query from another thread-local's
        // destructor) the scratch is made for this walk alone.
        let mut scratch = SCRATCH.try_with(StdCell::take).unwrap_or_default();
        let need = 2 * words * (self.depth + 1);
        if scratch.len() < need {
            scratch.resize(need, 0);
        }
        let mut walk = Walk {
            range,
            visitor,
            cell: self.root,
        };
        let at = At {
            inner: 0,
            set: &self.root_set,
            span: all,
            rank: 0,
            covered,
        };
        #[cfg(target_arch = "x86_64")]
        if self.bmi2 {
            self.enter::<Bmi2, V>(&mut walk, at, &mut scratch);
            let _ = SCRATCH.try_with(|s| s.set(scratch));
            return;
        }
        self.enter::<Soft, V>(&mut walk, at, &mut scratch);
        let _ = SCRATCH.try_with(|s| s.set(scratch));
    }

    /// The walk from the root, with the words a set takes as a constant up
    /// to 4 (256 objects: the loops unrolled), else as they come.
    fn enter<D: Deposit, V: Visitor>(
        &self,
        walk: &mut Walk<'_, V>,
        at: At<'_>,
        scratch: &mut [u64],
    ) {
        match self.words {
            1 => D::recurse::<V, 1>(self, walk, at, scratch),
            2 => D::recurse::<V, 2>(self, walk, at, scratch),
            3 => D::recurse::<V, 3>(self, walk, at, scratch),
            4 => D::recurse::<V, 4>(self, walk, at, scratch),
            _ => D::recurse::<V, 0>(self, walk, at, scratch),
        }
    }

    /// [`CodedTree::visit`] with BMI2's deposit.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "bmi2,popcnt")]
    fn visit_bmi2<V: Visitor, const N: usize>(
        &self,
        walk: &mut Walk<'_, V>,
        at: At<'_>,
        scratch: &mut [u64],
    ) {
        self.visit::<Bmi2, V, N>(walk, at, scratch);
    }

    /// Walks the subtree of an internal node the range meets (and does not
    /// hold whole): its children's sets decoded into the first two sets of
    /// `scratch` (or read from the decoded top levels), then each child
    /// the range meets given to the visitor (a leaf, or a node the range
    /// holds) or walked, with the rest of `scratch`. `N`: the words of a
    /// set, or 0 for [`CodedTree::words`], with only each set's non-empty
    /// stretch of words touched.
    #[inline(always)]
    fn visit<D: Deposit, V: Visitor, const N: usize>(
        &self,
        walk: &mut Walk<'_, V>,
        at: At<'_>,
        scratch: &mut [u64],
    ) {
        let words = if N > 0 { N } else { self.words };
        let n = self.inner[at.inner as usize];
        let d = n.dim();
        let value = self.value(n, &walk.cell);
        let range = walk.range;
        let go_below = range.lo[d] < value;
        let go_above = range.hi[d] >= value;
        let above_lighter = n.has(ABOVE_LIGHTER);
        let span = if N > 0 { 0..N } else { at.span.clone() };
        let (mine, rest) = scratch.split_at_mut(2 * words);
        let (l, h): (&[u64], &[u64]) = if n.has(CACHED) {
            let o = n.offset as usize;
            self.cache[o..o + 2 * words].split_at(words)
        } else {
            let (l, h) = mine.split_at_mut(words);
            let pos = lighter::<D>(&self.code, n.offset as usize, at.set, l, span.clone());
            if if above_lighter { go_below } else { go_above } {
                // The heavier child is walked.
                heavier::<D>(&self.code, pos, at.set, l, h, span.clone());
            }
            (l, h)
        };
        for above in [false, true] {
            if !(if above { go_above } else { go_below }) {
                continue;
            }
            // This child's bound in d, and the parent's, put back below.
            let bound = if above {
                &mut walk.cell.lo[d]
            } else {
                &mut walk.cell.hi[d]
            };
            let parent = std::mem::replace(bound, value);
            let set = if above != above_lighter { h } else { l };
            let span = if N > 0 {
                span.clone()
            } else {
                tighten(set, span.clone())
            };
            let leaf = n.has(if above { ABOVE_LEAF } else { BELOW_LEAF });
            let rank = if above {
                at.rank + (n.end_below - at.inner)
            } else {
                at.rank
            };
            let held = range.lo[d] <= walk.cell.lo[d] && range.hi[d] >= walk.cell.hi[d];
            let covered = (at.covered & !(1 << d)) | (u8::from(held) << d);
            if leaf || (V::WHOLE_NODES && covered == ALL_DIMS) {
                walk.visitor.set(leaf.then_some(rank), set, span);
            } else {
                let child = At {
                    inner: if above { n.end_below } else { at.inner + 1 },
                    set,
                    span,
                    rank,
                    covered,
                };
                D::recurse::<V, N>(self, walk, child, rest);
            }
            let bound = if above {
                &mut walk.cell.lo[d]
            } else {
                &mut walk.cell.hi[d]
            };
            *bound = parent;
        }
    }

    /// The preorder rank of the leaf holding the ray point `p` (inside the
    /// root cell: a point on a split value goes above, as queries do), and
    /// its set into `out` (of the tree's words) when given.
    pub(crate) fn leaf(&self, p: [f32; DIMS], out: Option<&mut [u64]>) -> u32 {
        self.leaf_cell(p, out).0
    }

    /// As [`CodedTree::leaf`], with the leaf's cell.
    pub(crate) fn leaf_cell(&self, p: [f32; DIMS], mut out: Option<&mut [u64]>) -> (u32, Cell) {
        let words = self.words;
        if let Some(out) = out.as_deref_mut() {
            out.copy_from_slice(&self.root_set);
        }
        if self.inner.is_empty() {
            return (0, self.root);
        }
        let mut scratch = Vec::new();
        if out.is_some() {
            scratch = SCRATCH.try_with(StdCell::take).unwrap_or_default();
            if scratch.len() < 2 * words {
                scratch.resize(2 * words, 0);
            }
        }
        let (mut k, mut cell, mut rank) = (0u32, self.root, 0u32);
        loop {
            let n = self.inner[k as usize];
            let d = n.dim();
            let value = self.value(n, &cell);
            let above = p[d] >= value;
            if let Some(out) = out.as_deref_mut()
                && n.has(CACHED)
            {
                let lighter_taken = above == n.has(ABOVE_LIGHTER);
                let at = n.offset as usize + if lighter_taken { 0 } else { words };
                out.copy_from_slice(&self.cache[at..at + words]);
            } else if let Some(out) = out.as_deref_mut() {
                // `out` holds the node's set: the child taken replaces it.
                let (l, h) = scratch[..2 * words].split_at_mut(words);
                let pos = lighter::<Soft>(&self.code, n.offset as usize, out, l, 0..words);
                if above == n.has(ABOVE_LIGHTER) {
                    out.copy_from_slice(l);
                } else {
                    heavier::<Soft>(&self.code, pos, out, l, h, 0..words);
                    out.copy_from_slice(h);
                }
            }
            let (below_cell, above_cell) = cell.split(d, value);
            if above {
                rank += n.end_below - k;
                cell = above_cell;
                if n.has(ABOVE_LEAF) {
                    break;
                }
                k = n.end_below;
            } else {
                cell = below_cell;
                if n.has(BELOW_LEAF) {
                    break;
                }
                k += 1;
            }
        }
        if out.is_some() {
            let _ = SCRATCH.try_with(|s| s.set(scratch));
        }
        (rank, cell)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bitset::ObjectSet;
    use crate::geom::cell::grid_value;
    use crate::tree::Split;
    use rand::{Rng, RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    /// A random tree in preorder with the union property: leaves' sets at
    /// random (dense, sparse or empty), internal nodes the union.
    fn random_tree(
        rng: &mut Pcg64,
        objects: usize,
        depth: u32,
        nodes: &mut Vec<Node>,
    ) -> ObjectSet {
        let at = nodes.len();
        nodes.push(Node {
            split: None,
            set: ObjectSet::new(objects),
        });
        let set = if depth > 0 && rng.random_bool(0.8) {
            let below = random_tree(rng, objects, depth - 1, nodes);
            let above_at = nodes.len() as u32;
            let above = random_tree(rng, objects, depth - 1, nodes);
            nodes[at].split = Some(Split {
                dim: rng.random_range(0..DIMS as u8),
                code: rng.random_range(1..1024),
                above: above_at,
            });
            let mut set = below;
            set.union_with(&above);
            set
        } else {
            let mut set = ObjectSet::new(objects);
            let p = [0.0, 0.02, 0.3, 0.9, 1.0][rng.random_range(0..5)];
            // Sparse sets in one stretch of the objects, as cells see.
            let (a, b) = (rng.random_range(0..objects), rng.random_range(0..objects));
            for o in a.min(b)..=a.max(b) {
                if rng.random_bool(p) {
                    set.insert(o);
                }
            }
            set
        };
        nodes[at].set = set.clone();
        set
    }

    /// The reference: the walk over decoded sets (the query before the
    /// sets were kept coded).
    fn reference(
        nodes: &[Node],
        i: usize,
        cell: Cell,
        range: &Cell,
        whole: bool,
        out: &mut Vec<(usize, ObjectSet)>,
    ) {
        let n = &nodes[i];
        let covered = covers(range, &cell);
        match n.split {
            Some(s) if !(whole && covered) => {
                let d = s.dim as usize;
                let v = grid_value(cell.lo[d], cell.hi[d], s.code, 10);
                let (below, above) = cell.split(d, v);
                if range.lo[d] < v {
                    reference(nodes, i + 1, below, range, whole, out);
                }
                if range.hi[d] >= v {
                    reference(nodes, s.above as usize, above, range, whole, out);
                }
            }
            _ => out.push((i, n.set.clone())),
        }
    }

    fn random_range(rng: &mut Pcg64, root: &Cell) -> Cell {
        let mut c = *root;
        for d in 0..DIMS {
            let (a, b) = (rng.random::<f32>(), rng.random::<f32>());
            let (a, b) = if rng.random_bool(0.3) {
                (a, a)
            } else {
                (a.min(b), a.max(b))
            };
            let w = root.hi[d] - root.lo[d];
            c.lo[d] = root.lo[d] + a * w;
            c.hi[d] = root.lo[d] + b * w;
        }
        c
    }

    #[test]
    fn coded_sets_answer_as_the_decoded_ones() {
        let mut rng = Pcg64::seed_from_u64(3);
        let root = Cell {
            lo: [0.0, 0.0, 0.0, -3.0, 0.0],
            hi: [8.0, 4.0, 2.0, 3.0, 3.0],
        };
        for trial in 0..300 {
            let objects = [1, 5, 63, 64, 65, 200, 700][trial % 7];
            let mut nodes = Vec::new();
            let depth = rng.random_range(0..9);
            random_tree(&mut rng, objects, depth, &mut nodes);
            // No level, some, every level decoded, and the default.
            let levels = [Some(0), Some(2), Some(64), None][trial % 4];
            let mut tree = CodedTree::with_cache(root, 10, objects, &nodes, levels).unwrap();
            if levels == Some(64) {
                assert_eq!(tree.code, [0, 0], "trial {trial}: nothing left coded");
            }
            let leaves: Vec<usize> = (0..nodes.len())
                .filter(|&i| nodes[i].split.is_none())
                .collect();
            assert_eq!(tree.node_count(), nodes.len());
            for bmi2 in [false, tree.bmi2] {
                tree.bmi2 = bmi2;
                for _ in 0..20 {
                    let range = random_range(&mut rng, &root);
                    let mut want = Vec::new();
                    reference(&nodes, 0, root, &range, true, &mut want);
                    let mut union = ObjectSet::new(objects);
                    for (_, s) in &want {
                        union.union_with(s);
                    }
                    let mut out = vec![0; objects.div_ceil(64)];
                    tree.union(&range, &mut out);
                    assert_eq!(out, union.words(), "trial {trial}");
                    // Leaves with their ranks.
                    let mut want = Vec::new();
                    reference(&nodes, 0, root, &range, false, &mut want);
                    let (mut ranks, mut sets) = (Vec::new(), Vec::new());
                    tree.leaves_met(&range, &mut ranks, &mut sets);
                    let mut got: Vec<(usize, &[u64])> = ranks
                        .iter()
                        .enumerate()
                        .map(|(k, &r)| {
                            (
                                leaves[r as usize],
                                &sets[k * tree.words..(k + 1) * tree.words],
                            )
                        })
                        .collect();
                    let want: Vec<(usize, &[u64])> =
                        want.iter().map(|(i, s)| (*i, s.words())).collect();
                    got.sort_unstable();
                    assert_eq!(got, want, "trial {trial}");
                    // One point's leaf.
                    let p = random_range(&mut rng, &root).lo;
                    let mut at = Vec::new();
                    reference(&nodes, 0, root, &Cell { lo: p, hi: p }, false, &mut at);
                    let (i, set) = at.last().unwrap();
                    let mut words = vec![0; tree.words];
                    let rank = tree.leaf(p, Some(&mut words));
                    assert_eq!((leaves[rank as usize], words.as_slice()), (*i, set.words()));
                    assert_eq!(tree.leaf(p, None), rank);
                }
            }
        }
    }

    #[test]
    fn a_tree_whose_children_do_not_make_up_the_parent_is_refused() {
        let root = Cell {
            lo: [0.0; DIMS],
            hi: [1.0; DIMS],
        };
        let set = |bits: &[usize]| {
            let mut s = ObjectSet::new(4);
            bits.iter().for_each(|&b| {
                s.insert(b);
            });
            s
        };
        let nodes = vec![
            Node {
                split: Some(Split {
                    dim: 0,
                    code: 512,
                    above: 2,
                }),
                set: set(&[0, 1, 2]),
            },
            Node {
                split: None,
                set: set(&[0]),
            },
            Node {
                split: None,
                set: set(&[1]),
            },
        ];
        let e = CodedTree::new(root, 10, 4, &nodes).unwrap_err();
        assert!(e.to_string().contains("node 0"), "{e}");
    }

    #[test]
    fn deposits_extract_and_bits_round_trip() {
        let mut rng = Pcg64::seed_from_u64(9);
        let mut pusher = BitPusher {
            words: Vec::new(),
            len: 0,
        };
        let mut pushed = Vec::new();
        for _ in 0..2000 {
            let mask: u64 = rng.random::<u64>() & rng.random::<u64>();
            let value: u64 = rng.random();
            let bits = extract(value, mask);
            // Bits above the mask's count are not read.
            let junk = rng
                .random::<u64>()
                .checked_shl(mask.count_ones())
                .unwrap_or(0);
            for bits in [bits, bits | junk] {
                assert_eq!(Soft::deposit(bits, mask), value & mask);
                #[cfg(target_arch = "x86_64")]
                if std::is_x86_feature_detected!("bmi2") {
                    assert_eq!(Bmi2::deposit(bits, mask), value & mask);
                }
            }
            let n = rng.random_range(0..=64u32);
            let v = if n == 64 {
                value
            } else {
                value & ((1 << n) - 1)
            };
            pushed.push((pusher.len, v, n));
            pusher.push(v, n);
        }
        pusher.words.push(0);
        for (pos, v, n) in pushed {
            if n > 0 {
                assert_eq!(read(&pusher.words, pos) & (u64::MAX >> (64 - n)), v);
            }
        }
        let _ = rng.next_u64();
    }
}
