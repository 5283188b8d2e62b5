//! Procedural test scenes, generated from a seed, whose visibility is easy
//! to reason about: sealed rooms, streets, a forest, a machine behind a
//! grating, two dense forests (crowns open and closed). They stand in for
//! the test scenes of papers/003 sec. 8 (a 159-object two-room apartment,
//! an 18-apartment block, a copy machine), which are not available.
//!
//! Units are metres, z is up, coordinates are rounded to the millimetre. The same kind, seed and replication give the
//! same scene (and the same OBJ bytes) on every machine: all randomness
//! comes from one seeded PCG stream, drawn in a fixed order.
//!
//! `replicate = k` places k identical copies of the scene, each object
//! named `copy<i>/<name>`: apartments and offices are stacked into a block
//! (3 copies per floor, as many floors as needed), cities, forests and
//! machines are tiled on the ground in a square grid.

mod apartment;
mod city;
mod forest;
mod grove;
mod machine;
mod office;
pub mod shapes;
mod thicket;

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use glam::Vec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::{Scene, SceneBuilder, SceneFormat, Triangle};
use crate::geom::Aabb;

/// The kinds of procedural scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SceneKind {
    /// Two furnished rooms joined by a door: ~170 objects, ~3,000 triangles
    /// (the apartment of papers/003 sec. 8).
    Apartment,
    /// A floor of offices on both sides of a corridor.
    Office,
    /// Blocks of buildings of varied heights along a street grid.
    City,
    /// Trees made of a trunk and many small leaf triangles, on the ground.
    Forest,
    /// A closed casing with a ventilation grating and many internal parts
    /// (the copy machine of papers/003 sec. 8).
    Machine,
    /// A dense forest: trees 2.5 m apart with crowns of leaf triangles down
    /// to half a metre, where only many leaves together hide a tree.
    Thicket,
    /// A dense forest whose crowns are closed shells of overlapping leaf
    /// clusters, with a winding trail through it: trees a few rows from
    /// the trail are really hidden, and only many leaves together hide
    /// them.
    Grove,
}

impl SceneKind {
    /// Every kind, in documentation order.
    pub const ALL: [SceneKind; 7] = [
        SceneKind::Apartment,
        SceneKind::Office,
        SceneKind::City,
        SceneKind::Forest,
        SceneKind::Machine,
        SceneKind::Thicket,
        SceneKind::Grove,
    ];

    /// The kind's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Apartment => "apartment",
            SceneKind::Office => "office",
            SceneKind::City => "city",
            SceneKind::Forest => "forest",
            SceneKind::Machine => "machine",
            SceneKind::Thicket => "thicket",
            SceneKind::Grove => "grove",
        }
    }

    /// Whether copies are stacked into floors (buildings) rather than
    /// tiled on the ground.
    fn stacks(self) -> bool {
        matches!(self, SceneKind::Apartment | SceneKind::Office)
    }
}

impl fmt::Display for SceneKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A scene kind name that is not one of [`SceneKind::ALL`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown scene kind {0:?}: expected one of apartment, office, city, forest, machine, thicket, grove"
)]
pub struct UnknownSceneKind(pub String);

impl FromStr for SceneKind {
    type Err = UnknownSceneKind;
    fn from_str(s: &str) -> Result<Self, UnknownSceneKind> {
        SceneKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| UnknownSceneKind(s.to_owned()))
    }
}

/// A scene under construction: named triangle soups in order.
#[derive(Default)]
pub(crate) struct Model {
    objects: Vec<(String, Vec<Triangle>)>,
}

impl Model {
    /// Starts an object and returns its triangle list.
    pub(crate) fn object(&mut self, name: impl Into<String>) -> &mut Vec<Triangle> {
        self.objects.push((name.into(), Vec::new()));
        &mut self.objects.last_mut().expect("just pushed").1
    }

    fn bounds(&self) -> Aabb {
        Aabb::from_points(
            self.objects
                .iter()
                .flat_map(|(_, t)| t.iter().flatten().copied()),
        )
    }
}

/// Generates a scene of `kind` from `seed`, replicated `replicate` times
/// (`replicate` 0 is treated as 1).
pub fn generate(kind: SceneKind, seed: u64, replicate: u32) -> Scene {
    let mut rng = Pcg64::seed_from_u64(seed);
    let model = match kind {
        SceneKind::Apartment => apartment::generate(&mut rng),
        SceneKind::Office => office::generate(&mut rng),
        SceneKind::City => city::generate(&mut rng),
        SceneKind::Forest => forest::generate(&mut rng),
        SceneKind::Machine => machine::generate(&mut rng),
        SceneKind::Thicket => thicket::generate(&mut rng),
        SceneKind::Grove => grove::generate(&mut rng),
    };
    let copies = replicate.max(1);
    let offsets = copy_offsets(kind, model.bounds(), copies);
    let mut b = SceneBuilder::new(SceneFormat::Procedural);
    for (c, offset) in offsets.iter().enumerate() {
        for (name, tris) in &model.objects {
            if copies == 1 {
                b.begin_object(name.clone());
            } else {
                b.begin_object(format!("copy{c}/{name}"));
            }
            for t in tris {
                b.push_triangle(t.map(|v| millimetres(v + *offset)))
                    .expect("procedural coordinates are finite");
            }
        }
    }
    b.finish(Path::new(kind.name()))
        .expect("procedural scenes have triangles")
}

/// `v` rounded to the millimetre: shorter OBJ files, same scene after a
/// round trip through text.
fn millimetres(v: Vec3) -> Vec3 {
    (v * 1000.0).round() / 1000.0
}

/// Where each copy goes: stacked floors of 3 for buildings, a square grid
/// on the ground otherwise, with a gap between copies.
fn copy_offsets(kind: SceneKind, bounds: Aabb, copies: u32) -> Vec<Vec3> {
    let size = bounds.size();
    let (cols, step) = if kind.stacks() {
        (copies.min(3), Vec3::new(size.x + 0.3, 0.0, size.z + 0.3))
    } else {
        let gap = 0.1 * size.x.max(size.y);
        let cols = (copies as f64).sqrt().ceil() as u32;
        (cols, Vec3::new(size.x + gap, size.y + gap, 0.0))
    };
    (0..copies)
        .map(|i| {
            let (col, row) = ((i % cols) as f32, (i / cols) as f32);
            if kind.stacks() {
                Vec3::new(col * step.x, 0.0, row * step.z)
            } else {
                Vec3::new(col * step.x, row * step.y, 0.0)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_parse_by_name() {
        for k in SceneKind::ALL {
            assert_eq!(k.name().parse::<SceneKind>(), Ok(k));
        }
        let message = "castle".parse::<SceneKind>().unwrap_err().to_string();
        for k in SceneKind::ALL {
            assert!(message.contains(k.name()), "{message}");
        }
    }

    #[test]
    fn same_seed_same_scene_other_seed_other_scene() {
        for k in SceneKind::ALL {
            let a = generate(k, 1, 1);
            let b = generate(k, 1, 1);
            let c = generate(k, 2, 1);
            a.validate().unwrap();
            assert_eq!(a.triangles(), b.triangles(), "{k}");
            assert_ne!(a.triangles(), c.triangles(), "{k}");
        }
    }

    #[test]
    fn replication_copies_every_object_without_overlap() {
        let one = generate(SceneKind::Apartment, 5, 1);
        let block = generate(SceneKind::Apartment, 5, 18);
        block.validate().unwrap();
        assert_eq!(block.objects().len(), 18 * one.objects().len());
        assert_eq!(block.triangles().len(), 18 * one.triangles().len());
        assert_eq!(
            block.objects()[0].name,
            format!("copy0/{}", one.objects()[0].name)
        );
        // 3 per floor, 6 floors: the block is 3 apartments wide and 6 high.
        let (s1, s18) = (one.bounds().size(), block.bounds().size());
        assert!(
            (s18.x - (3.0 * s1.x + 2.0 * 0.3)).abs() < 1e-3,
            "{s18} {s1}"
        );
        assert!(
            (s18.z - (6.0 * s1.z + 5.0 * 0.3)).abs() < 1e-3,
            "{s18} {s1}"
        );
        assert_eq!(s18.y, s1.y);
        let n = one.objects().len();
        for c in 1..18 {
            let a = block.objects()[(c - 1) * n].bounds;
            let b = block.objects()[c * n].bounds;
            assert!(a != b, "copy {c} sits on copy {}", c - 1);
        }
    }
}
