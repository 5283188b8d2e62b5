//! Sets of objects as bitsets: bit i stands for object i. The unit of every
//! potentially visible set, in the builder, the tree and the runtime answer.
//!
//! The storage is a `bitvec` [`BitVec<u64, Lsb0>`]: object i is bit `i % 64`
//! of word `i / 64`, the layout [`ObjectSet::words`] exposes and the runtime
//! query (`query::Pvs`) keeps per tree node and ORs into its answers.
//!
//! Invariant: the bits of the last word past the capacity are 0. bitvec
//! leaves them unspecified; here every constructor zeroes them and no
//! operation sets them, so whole words can be ORed, compared and hashed.
//!
//! Single bits, counts and the constructors go through bitvec. Whole-set
//! work runs on the raw words (`as_raw_slice`), as the hand-written set
//! did: unions, intersections and differences (bitvec has no and-not; the
//! runtime query ORs the raw words of `ObjectSet::words_mut`), and also
//! iteration, equality, hashing and cloning, where bitvec's generic
//! versions (`iter_ones`, `PartialEq`, `Hash` bit by bit, `Clone` through
//! `from_bitslice`) made decoding a `.v5d` file 2 to 2.5x slower
//! (notes/query.md, "bitvec").

use std::fmt;
use std::hash::{Hash, Hasher};

use bitvec::order::Lsb0;
use bitvec::slice::BitSlice;
use bitvec::vec::BitVec;

/// A set of object indices below a fixed capacity, one bit each.
#[derive(Default)]
pub struct ObjectSet {
    /// One bit per object; `bits.len()` is the capacity.
    bits: BitVec<u64, Lsb0>,
}

impl ObjectSet {
    /// The empty set over objects `0..len`.
    pub fn new(len: usize) -> Self {
        // `repeat(false, ..)` zeroes whole words, the tail included.
        Self {
            bits: BitVec::repeat(false, len),
        }
    }

    /// The set of all objects `0..len`.
    pub fn full(len: usize) -> Self {
        let mut s = Self::new(len);
        // `fill` writes the live bits only: the tail stays 0.
        s.bits.fill(true);
        s
    }

    /// The number of objects the set ranges over (not the number in it).
    pub fn capacity(&self) -> usize {
        self.bits.len()
    }

    /// The words, lowest objects first; bits past the capacity are 0.
    pub fn words(&self) -> &[u64] {
        self.bits.as_raw_slice()
    }

    /// The words, writable, for loops that OR whole words into the set (the
    /// runtime query's): the caller must leave bits past the capacity 0.
    #[inline]
    pub(crate) fn words_mut(&mut self) -> &mut [u64] {
        self.bits.as_raw_mut_slice()
    }

    /// The set as bits: bit i is object i.
    pub fn as_bitslice(&self) -> &BitSlice<u64, Lsb0> {
        &self.bits
    }

    /// A set over `len` objects from its words (lowest objects first);
    /// `None` when the word count is wrong or a bit past `len` is set.
    pub fn from_words(len: usize, words: Vec<u64>) -> Option<Self> {
        if words.len() != len.div_ceil(64) {
            return None;
        }
        let tail = len % 64;
        if tail != 0 && words.last().is_some_and(|&w| w >> tail != 0) {
            return None;
        }
        let mut bits = BitVec::from_vec(words);
        // Drops whole-word bits past `len`, which were checked to be 0.
        bits.truncate(len);
        Some(Self { bits })
    }

    /// Adds every object whose bit is set in `words` (same layout as
    /// [`ObjectSet::words`]); extra words, and bits past the capacity in
    /// the last word, are ignored.
    #[inline]
    pub fn union_words(&mut self, words: &[u64]) {
        let tail = self.bits.len() % 64;
        let raw = self.bits.as_raw_mut_slice();
        for (a, b) in raw.iter_mut().zip(words) {
            *a |= b;
        }
        if tail != 0
            && let Some(last) = raw.last_mut()
        {
            *last &= (1u64 << tail) - 1;
        }
    }

    /// Adds object `i`; returns whether it was new.
    ///
    /// # Panics
    /// When `i` is not below the capacity.
    pub fn insert(&mut self, i: usize) -> bool {
        let len = self.bits.len();
        assert!(i < len, "object {i} outside a set of {len}");
        !self.bits.replace(i, true)
    }

    /// Removes object `i`.
    pub fn remove(&mut self, i: usize) {
        if i < self.bits.len() {
            self.bits.set(i, false);
        }
    }

    /// Whether object `i` is in the set.
    pub fn contains(&self, i: usize) -> bool {
        self.bits.get(i).is_some_and(|b| *b)
    }

    /// The number of objects in the set.
    pub fn count(&self) -> usize {
        self.bits.count_ones()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.bits.not_any()
    }

    /// Removes every object.
    pub fn clear(&mut self) {
        self.words_mut().fill(0);
    }

    /// Adds every object of `other` (same capacity).
    pub fn union_with(&mut self, other: &ObjectSet) {
        debug_assert_eq!(self.capacity(), other.capacity());
        for (a, b) in self.words_mut().iter_mut().zip(other.words()) {
            *a |= b;
        }
    }

    /// Keeps only the objects also in `other` (same capacity).
    pub fn intersect_with(&mut self, other: &ObjectSet) {
        debug_assert_eq!(self.capacity(), other.capacity());
        for (a, b) in self.words_mut().iter_mut().zip(other.words()) {
            *a &= b;
        }
    }

    /// Removes the objects of `other` (same capacity).
    pub fn subtract(&mut self, other: &ObjectSet) {
        debug_assert_eq!(self.capacity(), other.capacity());
        for (a, b) in self.words_mut().iter_mut().zip(other.words()) {
            *a &= !b;
        }
    }

    /// Whether every object of `self` is in `other`.
    pub fn is_subset(&self, other: &ObjectSet) -> bool {
        self.capacity() == other.capacity()
            && self
                .words()
                .iter()
                .zip(other.words())
                .all(|(a, b)| a & !b == 0)
    }

    /// The objects in the set, in increasing order.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.words().iter().enumerate().flat_map(|(w, &word)| {
            let mut bits = word;
            std::iter::from_fn(move || {
                if bits == 0 {
                    return None;
                }
                let b = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                Some(w * 64 + b)
            })
        })
    }
}

impl Clone for ObjectSet {
    fn clone(&self) -> Self {
        // The words, tail included; `truncate` only sets the length.
        let mut bits = BitVec::from_vec(self.words().to_vec());
        bits.truncate(self.capacity());
        Self { bits }
    }
}

/// Equal capacities and words (the tails are 0 in both).
impl PartialEq for ObjectSet {
    fn eq(&self, other: &Self) -> bool {
        self.capacity() == other.capacity() && self.words() == other.words()
    }
}

impl Eq for ObjectSet {}

/// The capacity and the members (bitvec's own `Debug` prints addresses).
impl fmt::Debug for ObjectSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        struct Members<'a>(&'a ObjectSet);
        impl fmt::Debug for Members<'_> {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.debug_set().entries(self.0.iter()).finish()
            }
        }
        f.debug_struct("ObjectSet")
            .field("capacity", &self.capacity())
            .field("objects", &Members(self))
            .finish()
    }
}

/// Hashes the capacity and the words (bitvec hashes bit by bit); agrees
/// with `Eq` because bits past the capacity are 0.
impl Hash for ObjectSet {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.capacity().hash(state);
        self.words().hash(state);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;
    use std::collections::BTreeSet;
    use std::hash::{BuildHasher, RandomState};

    #[test]
    fn set_operations() {
        let mut a = ObjectSet::new(130);
        assert!(a.insert(0) && a.insert(64) && a.insert(129) && !a.insert(64));
        assert_eq!(a.iter().collect::<Vec<_>>(), [0, 64, 129]);
        assert!(a.contains(129) && !a.contains(1) && !a.contains(500));
        let mut b = ObjectSet::new(130);
        b.insert(64);
        b.insert(5);
        assert!(!b.is_subset(&a));
        let mut u = a.clone();
        u.union_with(&b);
        assert_eq!(u.count(), 4);
        assert!(a.is_subset(&u) && b.is_subset(&u));
        let mut i = a.clone();
        i.intersect_with(&b);
        assert_eq!(i.iter().collect::<Vec<_>>(), [64]);
        u.subtract(&a);
        assert_eq!(u.iter().collect::<Vec<_>>(), [5]);
        assert_eq!(ObjectSet::full(70).count(), 70);
        assert_eq!(
            ObjectSet::from_words(70, vec![1, 1 << 5]).unwrap().count(),
            2
        );
        assert!(ObjectSet::from_words(70, vec![1, 1 << 6]).is_none());
        assert!(ObjectSet::from_words(70, vec![1]).is_none());
        let mut w = ObjectSet::new(70);
        w.union_words(&[3, 4]);
        assert_eq!(w.iter().collect::<Vec<_>>(), [0, 1, 66]);
        assert!(ObjectSet::new(3).is_empty());
        assert_eq!(
            format!("{a:?}"),
            "ObjectSet { capacity: 130, objects: {0, 64, 129} }"
        );
    }

    #[test]
    #[should_panic(expected = "object 64 outside a set of 64")]
    fn insert_outside_the_capacity_panics() {
        ObjectSet::new(64).insert(64);
    }

    #[test]
    #[should_panic(expected = "object 0 outside a set of 0")]
    fn insert_into_an_empty_capacity_panics() {
        ObjectSet::new(0).insert(0);
    }

    const CAPACITIES: [usize; 7] = [0, 1, 63, 64, 65, 130, 1000];

    /// The set a model describes, built by inserts alone.
    fn of(len: usize, model: &BTreeSet<usize>) -> ObjectSet {
        let mut s = ObjectSet::new(len);
        for &i in model {
            s.insert(i);
        }
        s
    }

    /// The words of a model, built bit by bit.
    fn model_words(len: usize, model: &BTreeSet<usize>) -> Vec<u64> {
        let mut words = vec![0u64; len.div_ceil(64)];
        for &i in model {
            words[i / 64] |= 1 << (i % 64);
        }
        words
    }

    /// Every observation of `s` agrees with the model.
    fn check(s: &ObjectSet, len: usize, model: &BTreeSet<usize>) {
        assert_eq!(s.capacity(), len);
        assert_eq!(s.count(), model.len());
        assert_eq!(s.is_empty(), model.is_empty());
        assert!(s.iter().eq(model.iter().copied()), "{s:?} vs {model:?}");
        assert_eq!(s.words(), model_words(len, model));
        assert_eq!(s.as_bitslice().len(), len);
        for i in 0..len + 70 {
            assert_eq!(s.contains(i), model.contains(&i), "object {i}");
        }
        let back = ObjectSet::from_words(len, s.words().to_vec()).expect("valid words");
        assert_eq!(&back, s);
        let same = of(len, model);
        assert_eq!(&same, s);
        let h = RandomState::new();
        assert_eq!(h.hash_one(&same), h.hash_one(s));
    }

    /// A random subset of `0..len` holding each object with probability `p`.
    fn random_model(rng: &mut Pcg64, len: usize, p: f64) -> BTreeSet<usize> {
        (0..len).filter(|_| rng.random_bool(p)).collect()
    }

    #[test]
    fn matches_a_btreeset_on_random_operations() {
        let mut rng = Pcg64::seed_from_u64(0x0b17_5e75);
        for len in CAPACITIES {
            for _ in 0..30 {
                let (mut a, mut ma) = (ObjectSet::new(len), BTreeSet::new());
                let p = rng.random_range(0.0..1.0);
                let mut mb = random_model(&mut rng, len, p);
                let mut b = of(len, &mb);
                for _ in 0..120 {
                    // Indices reach past the capacity for the operations
                    // that accept them.
                    let i = rng.random_range(0..len + 70);
                    match rng.random_range(0..11) {
                        0..=2 if len > 0 => {
                            let i = i % len;
                            assert_eq!(a.insert(i), ma.insert(i));
                        }
                        3..=4 => {
                            a.remove(i);
                            ma.remove(&i);
                        }
                        5 => {
                            a.union_with(&b);
                            ma.extend(&mb);
                        }
                        6 => {
                            a.intersect_with(&b);
                            ma.retain(|i| mb.contains(i));
                        }
                        7 => {
                            a.subtract(&b);
                            ma.retain(|i| !mb.contains(i));
                        }
                        8 => {
                            // Extra words and bits past the capacity are
                            // ignored.
                            let mut words = model_words(len, &mb);
                            if len % 64 != 0 {
                                *words.last_mut().unwrap() |= u64::MAX << (len % 64);
                            }
                            words.push(rng.random());
                            a.union_words(&words);
                            ma.extend(&mb);
                        }
                        9 => {
                            let p = rng.random_range(0.0..1.0);
                            mb = random_model(&mut rng, len, p);
                            b = of(len, &mb);
                        }
                        _ => {
                            if rng.random_bool(0.2) {
                                a.clear();
                                ma.clear();
                            }
                        }
                    }
                    check(&a, len, &ma);
                    assert_eq!(a.is_subset(&b), ma.is_subset(&mb));
                    assert_eq!(b.is_subset(&a), mb.is_subset(&ma));
                    assert_eq!(a == b, ma == mb);
                }
                check(&b, len, &mb);
            }
        }
    }

    #[test]
    fn constructors_keep_the_tail_zero() {
        let mut rng = Pcg64::seed_from_u64(7);
        for len in CAPACITIES {
            let all: BTreeSet<usize> = (0..len).collect();
            check(&ObjectSet::full(len), len, &all);
            check(&ObjectSet::new(len), len, &BTreeSet::new());
            check(&ObjectSet::default(), 0, &BTreeSet::new());
            assert!(!ObjectSet::new(len).is_subset(&ObjectSet::new(len + 1)));
            let n = len.div_ceil(64);
            for _ in 0..50 {
                let words: Vec<u64> = (0..n).map(|_| rng.random()).collect();
                let model: BTreeSet<usize> = (0..n * 64)
                    .filter(|&i| words[i / 64] >> (i % 64) & 1 == 1)
                    .collect();
                let s = ObjectSet::from_words(len, words.clone());
                // Valid exactly when no bit past the capacity is set.
                assert_eq!(s.is_some(), model.iter().all(|&i| i < len), "{len}");
                if let Some(s) = s {
                    check(&s, len, &model);
                }
                // A wrong word count is refused.
                let mut more = words.clone();
                more.push(0);
                assert!(ObjectSet::from_words(len, more).is_none());
                if n > 0 {
                    assert!(ObjectSet::from_words(len, words[1..].to_vec()).is_none());
                }
            }
        }
    }
}
