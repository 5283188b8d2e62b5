//! Prefetch (papers/001 sec. 6.1): what changes from one answer to the
//! next, and what a whole region of positions may see.
//!
//! An engine that streams geometry, or keeps per-object state on the GPU,
//! wants the *changes*: the objects entering the answer (load, upload,
//! start drawing) and those leaving it (may be dropped). [`Pvs::delta`]
//! gives them for any two answers of the file (two views, two leaves,
//! this frame and the last), [`Pvs::leaf_delta`] for the leaves holding
//! two ray points. [`Pvs::query_positions`] answers everything visible
//! from some point of a box of positions in any direction: what to have
//! loaded before the camera gets into the box. None of them allocates: the
//! sets and the [`Delta`] are made once ([`Pvs::new_set`],
//! [`Pvs::new_delta`]) and reused.

use std::f32::consts::PI;

use glam::DVec3;

use super::{Answer, Pvs, SetSizeError};
use crate::bitset::ObjectSet;
use crate::geom::Aabb;
use crate::geom::cell::DIMS;

/// What changes from one answer to another.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Delta {
    /// The objects in the new answer and not in the old one.
    pub entering: ObjectSet,
    /// The objects in the old answer and not in the new one.
    pub leaving: ObjectSet,
}

impl Pvs {
    /// An empty [`Delta`] of the file's size, to reuse across frames.
    pub fn new_delta(&self) -> Delta {
        Delta {
            entering: self.new_set(),
            leaving: self.new_set(),
        }
    }

    /// The change from the answer `from` to the answer `to` (both of the
    /// file's size), written into `delta`: `entering = to \ from`,
    /// `leaving = from \ to`. An error, `delta` untouched, for a set of
    /// another size.
    pub fn delta(
        &self,
        from: &ObjectSet,
        to: &ObjectSet,
        delta: &mut Delta,
    ) -> Result<(), SetSizeError> {
        for set in [from, to, &delta.entering, &delta.leaving] {
            self.check_set(set)?;
        }
        self.delta_words(from.words(), to.words(), delta);
        Ok(())
    }

    /// The change from the set of the leaf holding the ray point `from`
    /// to that of the leaf holding `to` (x, y, z, theta, phi, local
    /// coordinates; [`Pvs::leaf_set`]), written into `delta`;
    /// [`Answer::Everything`] when either point lies outside the root cell
    /// (its set is then every object).
    pub fn leaf_delta(
        &self,
        from: [f32; DIMS],
        to: [f32; DIMS],
        delta: &mut Delta,
    ) -> Result<Answer, SetSizeError> {
        self.check_set(&delta.entering)?;
        self.check_set(&delta.leaving)?;
        // The two leaves' sets, then the differences in place.
        let answer_a = self.leaf_into(from, delta.leaving.words_mut());
        let answer_b = self.leaf_into(to, delta.entering.words_mut());
        for (e, l) in delta
            .entering
            .words_mut()
            .iter_mut()
            .zip(delta.leaving.words_mut().iter_mut())
        {
            let (a, b) = (*l, *e);
            *e = b & !a;
            *l = a & !b;
        }
        Ok(answer_a.max(answer_b))
    }

    fn delta_words(&self, from: &[u64], to: &[u64], delta: &mut Delta) {
        let words = from.iter().zip(to);
        for ((e, l), (a, b)) in delta
            .entering
            .words_mut()
            .iter_mut()
            .zip(delta.leaving.words_mut().iter_mut())
            .zip(words)
        {
            *e = b & !a;
            *l = a & !b;
        }
    }

    /// Every object visible from some point of the box `positions` (the
    /// tree's frame) in any direction, into `out` (cleared first): what to
    /// stream in before the camera enters the box. [`Answer::Everything`]
    /// when the box reaches outside the view box.
    pub fn query_positions(
        &self,
        positions: &Aabb,
        out: &mut ObjectSet,
    ) -> Result<Answer, SetSizeError> {
        self.query_range(positions, (-PI, PI), (0.0, PI), out)
    }

    /// As [`Pvs::query_positions`], for the box `[min, max]` in f64 world
    /// coordinates (rounded outwards into the tree's frame).
    pub fn query_positions_world(
        &self,
        min: DVec3,
        max: DVec3,
        out: &mut ObjectSet,
    ) -> Result<Answer, SetSizeError> {
        let local = self.frame().box_to_local(min, max);
        self.query_positions(&local, out)
    }
}
