//! Object flags (issue 15): what an object is to visibility beyond its
//! triangles, the overrides engines offer (Unity's "Occluder Static" and
//! "Occludee Static", Umbra's object flags), set at bake time and stored in
//! the `.v5d` object table (version 6).
//!
//! - **always visible** (a sky dome, a glass facade the renderer must never
//!   cull): the object is in every set of the tree. The builder does not
//!   test it and the oracles keep it.
//! - **never an occluder** (glass, foliage, a fence): rays pass through the
//!   object. It is still seen where a ray reaches it before any occluder,
//!   and it hides nothing: the builder's rays, the oracles' occluders and
//!   the ray truth all ignore it as a blocker.

use std::collections::HashMap;
use std::fmt;

/// The flags of one object: a small set of [`ObjectFlags::ALWAYS_VISIBLE`]
/// and [`ObjectFlags::NEVER_OCCLUDER`]. The default is none: an ordinary
/// object that is tested and occludes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ObjectFlags(u8);

impl ObjectFlags {
    /// No flag: tested, and an occluder.
    pub const NONE: ObjectFlags = ObjectFlags(0);
    /// In every set of the tree, never tested.
    pub const ALWAYS_VISIBLE: ObjectFlags = ObjectFlags(1);
    /// Hides nothing: rays pass through it.
    pub const NEVER_OCCLUDER: ObjectFlags = ObjectFlags(2);
    /// Every flag this version knows; a file with other bits is refused.
    const KNOWN: u8 = 3;

    /// The names of the flags, as a sidecar and `vis5d query --json` spell
    /// them, with their values.
    pub const NAMES: [(&'static str, ObjectFlags); 2] = [
        ("always_visible", ObjectFlags::ALWAYS_VISIBLE),
        ("never_occluder", ObjectFlags::NEVER_OCCLUDER),
    ];

    /// The flags of a stored byte, or `None` when it has a bit this
    /// version does not know.
    pub const fn from_bits(bits: u8) -> Option<ObjectFlags> {
        if bits & !Self::KNOWN == 0 {
            Some(ObjectFlags(bits))
        } else {
            None
        }
    }

    /// The stored byte.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// Whether every flag of `other` is set.
    pub const fn contains(self, other: ObjectFlags) -> bool {
        self.0 & other.0 == other.0
    }

    /// Both sets of flags.
    #[must_use]
    pub const fn union(self, other: ObjectFlags) -> ObjectFlags {
        ObjectFlags(self.0 | other.0)
    }

    /// Whether no flag is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// In every set of the tree.
    pub const fn always_visible(self) -> bool {
        self.contains(Self::ALWAYS_VISIBLE)
    }

    /// Hides what is behind it (the flag [`ObjectFlags::NEVER_OCCLUDER`]
    /// is not set).
    pub const fn occludes(self) -> bool {
        !self.contains(Self::NEVER_OCCLUDER)
    }

    /// The flag named `name` ([`ObjectFlags::NAMES`]).
    pub fn from_name(name: &str) -> Option<ObjectFlags> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == name)
            .map(|&(_, f)| f)
    }

    /// The names of the flags set, in [`ObjectFlags::NAMES`] order.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Self::NAMES
            .iter()
            .filter(move |(_, f)| self.contains(*f))
            .map(|&(n, _)| n)
    }
}

impl fmt::Display for ObjectFlags {
    /// The names joined by `|`, or `none`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_empty() {
            return f.write_str("none");
        }
        for (i, n) in self.names().enumerate() {
            if i > 0 {
                f.write_str("|")?;
            }
            f.write_str(n)?;
        }
        Ok(())
    }
}

/// Why a sidecar's flags cannot be applied.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FlagError {
    /// A key names no object.
    #[error(
        "no object has the id {0:?} (keys are the objects' default ids: the name, or name#k where names repeat)"
    )]
    Unknown(String),
    /// A flag's name is not one of [`ObjectFlags::NAMES`].
    #[error("{object:?}: unknown flag {flag:?} (the flags are always_visible and never_occluder)")]
    UnknownFlag {
        /// The key.
        object: String,
        /// The name given.
        flag: String,
    },
}

/// The flags of objects whose default ids are `ids` ([`super::default_ids`]),
/// from `user`, a map from default ids to flag names (a sidecar's
/// `{"sky": ["always_visible"], "window#2": ["never_occluder"]}`); objects
/// it does not name get none. Every key must name an object and every flag
/// must be known.
pub fn flags_from_names(
    ids: &[String],
    user: &HashMap<String, Vec<String>>,
) -> Result<Vec<ObjectFlags>, FlagError> {
    let index: HashMap<&str, usize> = ids
        .iter()
        .enumerate()
        .map(|(i, s)| (s.as_str(), i))
        .collect();
    let mut out = vec![ObjectFlags::NONE; ids.len()];
    // In key order, so that the error named is the same every run.
    let mut keys: Vec<&String> = user.keys().collect();
    keys.sort();
    for key in keys {
        let &i = index
            .get(key.as_str())
            .ok_or_else(|| FlagError::Unknown(key.clone()))?;
        for name in &user[key] {
            let f = ObjectFlags::from_name(name).ok_or_else(|| FlagError::UnknownFlag {
                object: key.clone(),
                flag: name.clone(),
            })?;
            out[i] = out[i].union(f);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_bits_round_trip() {
        for bits in 0..=ObjectFlags::KNOWN {
            let f = ObjectFlags::from_bits(bits).unwrap();
            assert_eq!(f.bits(), bits);
            let back = f
                .names()
                .map(|n| ObjectFlags::from_name(n).unwrap())
                .fold(ObjectFlags::NONE, ObjectFlags::union);
            assert_eq!(back, f);
        }
        assert_eq!(ObjectFlags::from_bits(4), None);
        assert_eq!(ObjectFlags::from_name("glass"), None);
        assert!(ObjectFlags::NONE.occludes() && !ObjectFlags::NONE.always_visible());
        let both = ObjectFlags::ALWAYS_VISIBLE.union(ObjectFlags::NEVER_OCCLUDER);
        assert!(both.always_visible() && !both.occludes());
        assert_eq!(both.to_string(), "always_visible|never_occluder");
        assert_eq!(ObjectFlags::NONE.to_string(), "none");
    }

    #[test]
    fn sidecar_names_objects_by_default_id() {
        let ids: Vec<String> = ["sky", "crate#1", "crate#2"].map(String::from).into();
        let user = |pairs: &[(&str, &[&str])]| -> HashMap<String, Vec<String>> {
            pairs
                .iter()
                .map(|(k, v)| (k.to_string(), v.iter().map(|s| s.to_string()).collect()))
                .collect()
        };
        let got = flags_from_names(
            &ids,
            &user(&[
                ("sky", &["always_visible", "never_occluder"]),
                ("crate#2", &["never_occluder"]),
            ]),
        )
        .unwrap();
        assert_eq!(
            got,
            [
                ObjectFlags::ALWAYS_VISIBLE.union(ObjectFlags::NEVER_OCCLUDER),
                ObjectFlags::NONE,
                ObjectFlags::NEVER_OCCLUDER
            ]
        );
        assert_eq!(
            flags_from_names(&ids, &user(&[("crate", &[])])),
            Err(FlagError::Unknown("crate".into()))
        );
        let err = flags_from_names(&ids, &user(&[("sky", &["glass"])])).unwrap_err();
        assert!(err.to_string().contains("unknown flag \"glass\""), "{err}");
    }
}
