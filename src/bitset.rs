//! Sets of objects as bitsets: bit i stands for object i. The unit of every
//! potentially visible set, in the builder, the tree and the runtime answer.

/// A set of object indices below a fixed capacity, one bit each.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct ObjectSet {
    words: Vec<u64>,
    len: usize,
}

impl ObjectSet {
    /// The empty set over objects `0..len`.
    pub fn new(len: usize) -> Self {
        Self {
            words: vec![0; len.div_ceil(64)],
            len,
        }
    }

    /// The set of all objects `0..len`.
    pub fn full(len: usize) -> Self {
        let mut s = Self::new(len);
        for i in 0..len {
            s.insert(i);
        }
        s
    }

    /// The number of objects the set ranges over (not the number in it).
    pub fn capacity(&self) -> usize {
        self.len
    }

    /// The words, lowest objects first; bits past the capacity are 0.
    pub fn words(&self) -> &[u64] {
        &self.words
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
        Some(Self { words, len })
    }

    /// Adds every object whose bit is set in `words` (same layout as
    /// [`ObjectSet::words`]); extra words are ignored.
    pub fn union_words(&mut self, words: &[u64]) {
        for (a, b) in self.words.iter_mut().zip(words) {
            *a |= b;
        }
    }

    /// Adds object `i`; returns whether it was new.
    ///
    /// # Panics
    /// When `i` is not below the capacity.
    pub fn insert(&mut self, i: usize) -> bool {
        assert!(i < self.len, "object {i} outside a set of {}", self.len);
        let (w, b) = (i / 64, 1u64 << (i % 64));
        let new = self.words[w] & b == 0;
        self.words[w] |= b;
        new
    }

    /// Removes object `i`.
    pub fn remove(&mut self, i: usize) {
        if i < self.len {
            self.words[i / 64] &= !(1u64 << (i % 64));
        }
    }

    /// Whether object `i` is in the set.
    pub fn contains(&self, i: usize) -> bool {
        i < self.len && self.words[i / 64] >> (i % 64) & 1 == 1
    }

    /// The number of objects in the set.
    pub fn count(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }

    /// Removes every object.
    pub fn clear(&mut self) {
        self.words.fill(0);
    }

    /// Adds every object of `other` (same capacity).
    pub fn union_with(&mut self, other: &ObjectSet) {
        debug_assert_eq!(self.len, other.len);
        for (a, b) in self.words.iter_mut().zip(&other.words) {
            *a |= b;
        }
    }

    /// Keeps only the objects also in `other` (same capacity).
    pub fn intersect_with(&mut self, other: &ObjectSet) {
        debug_assert_eq!(self.len, other.len);
        for (a, b) in self.words.iter_mut().zip(&other.words) {
            *a &= b;
        }
    }

    /// Removes the objects of `other` (same capacity).
    pub fn subtract(&mut self, other: &ObjectSet) {
        debug_assert_eq!(self.len, other.len);
        for (a, b) in self.words.iter_mut().zip(&other.words) {
            *a &= !b;
        }
    }

    /// Whether every object of `self` is in `other`.
    pub fn is_subset(&self, other: &ObjectSet) -> bool {
        self.len == other.len
            && self
                .words
                .iter()
                .zip(&other.words)
                .all(|(a, b)| a & !b == 0)
    }

    /// The objects in the set, in increasing order.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.words.iter().enumerate().flat_map(|(w, &word)| {
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

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
