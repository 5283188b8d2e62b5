//! The error of every `validate()`: a structure breaks one of its
//! invariants (a tree's cells do not partition their parent, a hierarchy
//! misses an object, ...).
//!
//! `validate()` checks what the code that made the structure promises; a
//! failure is a bug in vis5d (or a structure assembled by hand), not bad
//! input, which the loaders and the `.v5d` reader refuse with their own
//! errors first.

/// A broken invariant, found by a `validate()`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{structure}: {what} (a broken invariant: a bug in vis5d, or a structure not made by it; \
     please report it with the input that produced it)"
)]
pub struct InvariantError {
    /// The structure checked ("tree", "scene", ...).
    pub structure: &'static str,
    /// The first invariant found broken, and where.
    pub what: String,
}

impl InvariantError {
    /// The error for `structure`, saying `what` is broken.
    pub fn new(structure: &'static str, what: impl Into<String>) -> Self {
        Self {
            structure,
            what: what.into(),
        }
    }
}
