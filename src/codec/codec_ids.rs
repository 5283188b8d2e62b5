//! Stable object ids (issue 15): what an engine keys its objects by,
//! stored in the `.v5d` object table (version 5).
//!
//! An object's index is its load order, which a change to the model
//! shifts, and its name may repeat (`["floor", "crate", "crate"]`). Its id
//! is unique in the file: by default its name when the name is unique,
//! else the name and its occurrence, `crate#1`, `crate#2` (in scene
//! order; more `#` where that is someone else's name). The model may give
//! an object its own id (a glTF node's `extras.vis5d.id`:
//! [`crate::scene::Object::id`]), and a build can replace any id by one
//! the user supplies (`vis5d build --ids FILE.json`, a JSON object from
//! default ids to ids: what the engine calls the objects), in that order.

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

/// Whether `id` may be an object's id: 1 to [`MAX_ID_BYTES`] bytes, no
/// NUL byte.
pub fn is_valid_id(id: &str) -> bool {
    !id.is_empty() && id.len() <= MAX_ID_BYTES && !id.contains('\0')
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
    let defaults = ids.to_vec();
    replace_ids(&defaults, ids, user)
}

/// As [`apply_user_ids`], for objects whose ids need not be their default
/// ids (a model's own ids applied already): `user`'s keys name objects by
/// their default ids `defaults` ([`default_ids`], one per object), and
/// its values replace the same objects' `ids`. Every key must name an
/// object, and the ids must stay valid ([`is_valid_id`]) and unique.
///
/// # Panics
/// When `defaults` and `ids` differ in length.
pub fn replace_ids(
    defaults: &[String],
    ids: &mut [String],
    user: &HashMap<String, String>,
) -> Result<(), IdError> {
    assert_eq!(defaults.len(), ids.len(), "one default id per object");
    let index: HashMap<&str, usize> = defaults
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
        if !is_valid_id(id) {
            return Err(IdError::Invalid(id.clone()));
        }
        changes.push((i, id.clone()));
    }
    for (i, id) in changes {
        ids[i] = id;
    }
    match first_duplicate(ids) {
        Some((_, j)) => Err(IdError::Duplicate(ids[j].clone())),
        None => Ok(()),
    }
}

/// The first pair `(i, j)`, `i < j`, of equal ids (the smallest `j`), if
/// any.
pub fn first_duplicate(ids: &[String]) -> Option<(usize, usize)> {
    let mut seen: HashMap<&str, usize> = HashMap::new();
    for (j, id) in ids.iter().enumerate() {
        if let Some(&i) = seen.get(id.as_str()) {
            return Some((i, j));
        }
        seen.insert(id, j);
    }
    None
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
        // Keys stay the default ids when the ids are a model's own.
        let defaults = default_ids(["floor", "door"]);
        let mut ids: Vec<String> = ["floor", "door-17"].map(String::from).into();
        let user: HashMap<String, String> = [("door".to_owned(), "d".to_owned())].into();
        replace_ids(&defaults, &mut ids, &user).unwrap();
        assert_eq!(ids, ["floor", "d"]);
        let by_model_id: HashMap<String, String> = [("d".to_owned(), "x".to_owned())].into();
        assert_eq!(
            replace_ids(&defaults, &mut ids, &by_model_id),
            Err(IdError::Unknown("d".into()))
        );
        assert_eq!(first_duplicate(&default_ids(["a", "b"])), None);
        let three: Vec<String> = ["a", "b", "a"].map(String::from).into();
        assert_eq!(first_duplicate(&three), Some((0, 2)));
        for bad in ["", "a\0b", &"x".repeat(MAX_ID_BYTES + 1)] {
            assert!(!is_valid_id(bad));
            let user: HashMap<String, String> = [("floor".to_owned(), bad.to_owned())].into();
            assert!(matches!(
                apply_user_ids(&mut ids.clone(), &user),
                Err(IdError::Invalid(_))
            ));
        }
    }
}
