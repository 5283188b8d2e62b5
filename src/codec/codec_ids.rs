//! Stable object ids (issue 15): what an engine keys its objects by,
//! stored in the `.v5d` object table (version 5).
//!
//! An object's index is its load order, which a change to the model
//! shifts, and its name may repeat (`["floor", "crate", "crate"]`). Its id
//! is unique in the file: by default its name when the name is unique,
//! else the name and its occurrence, `crate#1`, `crate#2` (in scene
//! order; more `#` where that is someone else's name). A build can replace
//! any default id by one the user supplies (`vis5d build --ids
//! FILE.json`, a JSON object from default ids to ids: what the engine
//! calls the objects).

use std::collections::{HashMap, HashSet};

/// The longest id, in bytes.
pub const MAX_ID_BYTES: usize = 1024;

/// The default ids of objects named `names`, in order: the name when it is
/// unique, else `name#k` for its k-th occurrence (from 1), with more `#`
/// when that is taken; a NUL in a name becomes U+FFFD in its id (ids hold
/// no NUL, for C). Unique.
pub fn default_ids<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<String> {
    let owned: Vec<String> = names
        .into_iter()
        .map(|n| n.replace('\0', "\u{FFFD}"))
        .collect();
    let names: Vec<&str> = owned.iter().map(String::as_str).collect();
    let mut count: HashMap<&str, usize> = HashMap::new();
    for n in &names {
        *count.entry(n).or_default() += 1;
    }
    let mut taken: HashSet<String> = names
        .iter()
        .filter(|n| count[*n] == 1)
        .map(|n| n.to_string())
        .collect();
    let mut seen: HashMap<&str, usize> = HashMap::new();
    names
        .iter()
        .map(|&n| {
            if count[n] == 1 {
                return n.to_owned();
            }
            let k = seen.entry(n).or_default();
            *k += 1;
            let mut id = format!("{n}#{k}");
            while taken.contains(&id) {
                id.insert(n.len(), '#');
            }
            taken.insert(id.clone());
            id
        })
        .collect()
}

/// Why user ids cannot be applied.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IdError {
    /// A key names no object.
    #[error(
        "no object has the id {0:?} (keys are the objects' default ids: the name, or name#k where names repeat)"
    )]
    Unknown(String),
    /// Two objects would share an id.
    #[error("two objects would have the id {0:?}")]
    Duplicate(String),
    /// An id is empty, too long or holds a NUL.
    #[error("the id {0:?} is empty, longer than 1024 bytes or holds a NUL byte")]
    Invalid(String),
}

/// Replaces the ids `ids` (default ids, as [`default_ids`] gives them) by
/// `user`'s values where `user` has a key for them; every key must name an
/// object, and the ids must stay unique, non-empty, at most
/// [`MAX_ID_BYTES`] long and free of NUL bytes.
pub fn apply_user_ids(ids: &mut [String], user: &HashMap<String, String>) -> Result<(), IdError> {
    let index: HashMap<&str, usize> = ids
        .iter()
        .enumerate()
        .map(|(i, s)| (s.as_str(), i))
        .collect();
    let mut changes = Vec::new();
    let mut keys: Vec<&String> = user.keys().collect();
    keys.sort();
    for key in keys {
        let &i = index
            .get(key.as_str())
            .ok_or_else(|| IdError::Unknown(key.clone()))?;
        let id = &user[key];
        if id.is_empty() || id.len() > MAX_ID_BYTES || id.contains('\0') {
            return Err(IdError::Invalid(id.clone()));
        }
        changes.push((i, id.clone()));
    }
    for (i, id) in changes {
        ids[i] = id;
    }
    let mut seen = HashSet::new();
    for id in ids.iter() {
        if !seen.insert(id.as_str()) {
            return Err(IdError::Duplicate(id.clone()));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_names_get_their_occurrence_and_user_ids_replace_defaults() {
        assert_eq!(default_ids(["a\0b"]), ["a\u{FFFD}b"]);
        let ids = default_ids(["floor", "crate", "crate", "crate#1", "lamp"]);
        assert_eq!(ids, ["floor", "crate##1", "crate#2", "crate#1", "lamp"]);
        let mut ids = default_ids(["floor", "crate", "crate"]);
        assert_eq!(ids, ["floor", "crate#1", "crate#2"]);
        let user: HashMap<String, String> =
            [("crate#2".to_owned(), "crate-blue".to_owned())].into();
        apply_user_ids(&mut ids, &user).unwrap();
        assert_eq!(ids, ["floor", "crate#1", "crate-blue"]);
        let clash: HashMap<String, String> = [("floor".to_owned(), "crate#1".to_owned())].into();
        assert_eq!(
            apply_user_ids(&mut ids.clone(), &clash),
            Err(IdError::Duplicate("crate#1".into()))
        );
        let unknown: HashMap<String, String> = [("crate".to_owned(), "x".to_owned())].into();
        assert_eq!(
            apply_user_ids(&mut ids.clone(), &unknown),
            Err(IdError::Unknown("crate".into()))
        );
        for bad in ["", "a\0b", &"x".repeat(MAX_ID_BYTES + 1)] {
            let user: HashMap<String, String> = [("floor".to_owned(), bad.to_owned())].into();
            assert!(matches!(
                apply_user_ids(&mut ids.clone(), &user),
                Err(IdError::Invalid(_))
            ));
        }
    }
}
