//! The three codings of a visibility tree (papers/003 sec. 6, DESIGN.md
//! "Coding").
//!
//! The tree is written in preorder. Each node starts with a header:
//!
//! ```text
//! leaf:      0
//! internal:  1  dim (3 bits)  code (q bits)  [first (1 bit), sibling coding only]
//! ```
//!
//! (all fields least significant bit first). The sets:
//!
//! - [`Coding::Leaves`] ("leaves only"): each leaf header is followed by its
//!   set, n bits (bit i = object i). Internal sets are not stored; the
//!   decoder rebuilds them as unions.
//! - [`Coding::Parent`] ("children relative to the parent"): the root's set
//!   comes first, n bits. Each internal header is followed by the sets of
//!   its two children (below, then above), each coded relative to the
//!   parent: one bit per object of the parent's set, in object order,
//!   v(B)[v(A)] then v(C)[v(A)].
//! - [`Coding::Sibling`] ("heavier sibling relative to the lighter one
//!   too"): as `Parent`, but the lighter child (fewer objects; the below
//!   child on a tie) is coded first, relative to the parent, and the
//!   heavier one only at the objects of the parent that the lighter child
//!   also holds, v(C)[v(B)[v(A)]]: an object of the parent missing from
//!   the lighter child is in the heavier one, since v(A) = v(B) u v(C). The
//!   `first` bit says which child was coded first (1: the above child).
//!
//! Worked example (the paper's): v(A) = 0111000, v(B) = 0011000,
//! v(C) = 0101000 take 14, 13 and 12 set bits (`tests::papers_example`).
//!
//! Decoding is defensive: every read is bounds-checked, codes and
//! dimensions are validated, the depth is capped at [`MAX_DEPTH`], the node
//! count at the caller's limit, and a decoded `Parent` tree must satisfy
//! the union property like every built tree.

use std::fmt;
use std::str::FromStr;

use super::CodecError;
use super::codec_bits::{BitReader, BitWriter};
use crate::bitset::ObjectSet;
use crate::geom::cell::{Cell, DIMS};
use crate::tree::{MAX_DEPTH, MAX_GRID_BITS, Node, Split, VisTree};

/// How the sets of a tree are coded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Coding {
    /// Leaves only, n bits each (the paper's first method).
    Leaves,
    /// Every node relative to its parent (the second method).
    Parent,
    /// As `Parent`, the heavier sibling also relative to the lighter one
    /// (the third method).
    Sibling,
}

impl Coding {
    /// The three codings, in the paper's order.
    pub const ALL: [Coding; 3] = [Coding::Leaves, Coding::Parent, Coding::Sibling];

    /// The name used by `--coding` and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Coding::Leaves => "leaf",
            Coding::Parent => "parent",
            Coding::Sibling => "sibling",
        }
    }

    /// The byte stored in the file.
    pub fn to_byte(self) -> u8 {
        match self {
            Coding::Leaves => 0,
            Coding::Parent => 1,
            Coding::Sibling => 2,
        }
    }

    /// The coding of a file byte.
    pub fn from_byte(b: u8) -> Option<Coding> {
        Coding::ALL.into_iter().find(|c| c.to_byte() == b)
    }
}

impl fmt::Display for Coding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A coding name that is not `leaf`, `parent` or `sibling`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown coding {0:?}: expected leaf, parent or sibling")]
pub struct UnknownCoding(pub String);

impl FromStr for Coding {
    type Err = UnknownCoding;
    fn from_str(s: &str) -> Result<Self, UnknownCoding> {
        Coding::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| UnknownCoding(s.to_owned()))
    }
}

/// The size of a coded tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CodeSize {
    /// Header bits: leaf/internal, dimension, split code, sibling order.
    pub structure_bits: u64,
    /// Set bits (the quantity of the paper's worked example).
    pub set_bits: u64,
}

impl CodeSize {
    /// All bits.
    pub fn total_bits(&self) -> u64 {
        self.structure_bits + self.set_bits
    }

    /// All bits, rounded up to bytes.
    pub fn bytes(&self) -> u64 {
        self.total_bits().div_ceil(8)
    }
}

fn write_full(w: &mut BitWriter, set: &ObjectSet, size: &mut CodeSize) {
    for o in 0..set.capacity() {
        w.push(set.contains(o));
    }
    size.set_bits += set.capacity() as u64;
}

fn write_relative(w: &mut BitWriter, set: &ObjectSet, parent: &ObjectSet, size: &mut CodeSize) {
    for o in parent.iter() {
        w.push(set.contains(o));
        size.set_bits += 1;
    }
}

/// Writes `heavy` at the objects of `parent` that `light` also holds.
fn write_relative2(
    w: &mut BitWriter,
    heavy: &ObjectSet,
    parent: &ObjectSet,
    light: &ObjectSet,
    size: &mut CodeSize,
) {
    for o in parent.iter().filter(|&o| light.contains(o)) {
        w.push(heavy.contains(o));
        size.set_bits += 1;
    }
}

/// Codes `tree` (which must satisfy [`VisTree::validate`]).
pub fn encode(tree: &VisTree, coding: Coding) -> (BitWriter, CodeSize) {
    let mut w = BitWriter::new();
    let mut size = CodeSize::default();
    if coding != Coding::Leaves {
        write_full(&mut w, &tree.nodes()[0].set, &mut size);
    }
    encode_node(tree, 0, coding, &mut w, &mut size);
    (w, size)
}

fn encode_node(tree: &VisTree, i: usize, coding: Coding, w: &mut BitWriter, size: &mut CodeSize) {
    let node = &tree.nodes()[i];
    let Some(s) = node.split else {
        w.push(false);
        size.structure_bits += 1;
        if coding == Coding::Leaves {
            write_full(w, &node.set, size);
        }
        return;
    };
    let q = tree.grid_bits();
    w.push(true);
    w.push_bits(s.dim as u64, 3);
    w.push_bits(s.code as u64, q);
    size.structure_bits += 4 + q as u64;
    let (below, above) = (
        &tree.nodes()[i + 1].set,
        &tree.nodes()[s.above as usize].set,
    );
    match coding {
        Coding::Leaves => {}
        Coding::Parent => {
            write_relative(w, below, &node.set, size);
            write_relative(w, above, &node.set, size);
        }
        Coding::Sibling => {
            let above_first = above.count() < below.count();
            w.push(above_first);
            size.structure_bits += 1;
            let (light, heavy) = if above_first {
                (above, below)
            } else {
                (below, above)
            };
            write_relative(w, light, &node.set, size);
            write_relative2(w, heavy, &node.set, light, size);
        }
    }
    encode_node(tree, i + 1, coding, w, size);
    encode_node(tree, s.above as usize, coding, w, size);
}

/// The size of `tree` in each coding, without keeping the bits.
pub fn code_size(tree: &VisTree, coding: Coding) -> CodeSize {
    encode(tree, coding).1
}

/// What a decode may allocate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DecodeLimits {
    /// The most nodes the tree may have.
    pub max_nodes: usize,
}

/// Decodes a tree of `objects` objects over `root`, coded with `coding`
/// and `grid_bits`-bit split codes, from `bits` bits of `bytes`. The bits
/// must be used up exactly.
pub fn decode(
    bytes: &[u8],
    bits: u64,
    coding: Coding,
    root: Cell,
    grid_bits: u32,
    objects: usize,
    limits: DecodeLimits,
) -> Result<VisTree, CodecError> {
    if bits > bytes.len() as u64 * 8 {
        return Err(CodecError::Corrupt(
            "the tree's bit length exceeds its bytes".into(),
        ));
    }
    if !(1..=MAX_GRID_BITS).contains(&grid_bits) {
        return Err(CodecError::Corrupt(format!(
            "grid bits {grid_bits} outside 1..={MAX_GRID_BITS}"
        )));
    }
    let mut d = Decoder {
        r: BitReader::new(bytes, bits),
        coding,
        grid_bits,
        objects,
        limits,
        nodes: Vec::new(),
    };
    let root_set = match coding {
        Coding::Leaves => None,
        _ => Some(d.read_full()?),
    };
    d.node(root, 0, root_set)?;
    if d.r.remaining() != 0 {
        return Err(CodecError::Corrupt(format!(
            "{} bits are left over after the tree",
            d.r.remaining()
        )));
    }
    let tree = VisTree::from_parts(root, grid_bits, objects, d.nodes);
    tree.validate().map_err(|e| {
        CodecError::Corrupt(format!("the decoded tree is inconsistent: {}", e.what))
    })?;
    Ok(tree)
}

struct Decoder<'a> {
    r: BitReader<'a>,
    coding: Coding,
    grid_bits: u32,
    objects: usize,
    limits: DecodeLimits,
    nodes: Vec<Node>,
}

impl Decoder<'_> {
    fn read_full(&mut self) -> Result<ObjectSet, CodecError> {
        if self.r.remaining() < self.objects as u64 {
            return Err(CodecError::Corrupt(
                "the coded tree ends in the middle of a set".into(),
            ));
        }
        let mut s = ObjectSet::new(self.objects);
        for o in 0..self.objects {
            if self.r.read()? {
                s.insert(o);
            }
        }
        Ok(s)
    }

    fn read_relative(
        &mut self,
        parent: &ObjectSet,
        filter: Option<&ObjectSet>,
    ) -> Result<ObjectSet, CodecError> {
        let mut s = ObjectSet::new(self.objects);
        for o in parent.iter() {
            let coded = filter.is_none_or(|f| f.contains(o));
            if !coded || self.r.read()? {
                s.insert(o);
            }
        }
        Ok(s)
    }

    /// Decodes the subtree of a node with cell `cell` whose set, when the
    /// coding gives it from the parent, is `known`; returns its set.
    fn node(
        &mut self,
        cell: Cell,
        depth: u32,
        known: Option<ObjectSet>,
    ) -> Result<ObjectSet, CodecError> {
        if self.nodes.len() >= self.limits.max_nodes {
            return Err(CodecError::TooLarge(format!(
                "the tree has more than {} nodes",
                self.limits.max_nodes
            )));
        }
        let me = self.nodes.len();
        let internal = self.r.read()?;
        if !internal {
            let set = match known {
                Some(s) => s,
                None => self.read_full()?,
            };
            self.nodes.push(Node {
                split: None,
                set: set.clone(),
            });
            return Ok(set);
        }
        if depth >= MAX_DEPTH {
            return Err(CodecError::Corrupt(format!(
                "the tree is deeper than {MAX_DEPTH}"
            )));
        }
        let dim = self.r.read_bits(3)? as usize;
        let code = self.r.read_bits(self.grid_bits)? as u32;
        if dim >= DIMS {
            return Err(CodecError::Corrupt(format!(
                "node {me} splits dimension {dim}"
            )));
        }
        if code == 0 {
            return Err(CodecError::Corrupt(format!("node {me} has split code 0")));
        }
        let split = Split {
            dim: dim as u8,
            code,
            above: 0,
        };
        self.nodes.push(Node {
            split: Some(split),
            set: ObjectSet::new(0),
        });
        let tree_value =
            crate::geom::cell::grid_value(cell.lo[dim], cell.hi[dim], code, self.grid_bits);
        if !(tree_value > cell.lo[dim] && tree_value < cell.hi[dim]) {
            return Err(CodecError::Corrupt(format!(
                "node {me} splits outside its cell"
            )));
        }
        let (below_cell, above_cell) = cell.split(dim, tree_value);
        let (below_known, above_known) = match (self.coding, &known) {
            (Coding::Leaves, _) => (None, None),
            (_, None) => unreachable!("parent-relative codings know every set"),
            (Coding::Parent, Some(parent)) => {
                let b = self.read_relative(parent, None)?;
                let a = self.read_relative(parent, None)?;
                (Some(b), Some(a))
            }
            (Coding::Sibling, Some(parent)) => {
                let above_first = self.r.read()?;
                let light = self.read_relative(parent, None)?;
                let heavy = self.read_relative(parent, Some(&light))?;
                if above_first {
                    (Some(heavy), Some(light))
                } else {
                    (Some(light), Some(heavy))
                }
            }
        };
        let below = self.node(below_cell, depth + 1, below_known)?;
        let above_index = self.nodes.len() as u32;
        let above = self.node(above_cell, depth + 1, above_known)?;
        let set = match known {
            Some(s) => s,
            None => {
                let mut u = below;
                u.union_with(&above);
                u
            }
        };
        self.nodes[me] = Node {
            split: Some(Split {
                above: above_index,
                ..split
            }),
            set: set.clone(),
        };
        Ok(set)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Aabb;
    use glam::Vec3;

    fn set(bits: &str) -> ObjectSet {
        let mut s = ObjectSet::new(bits.len());
        for (i, c) in bits.bytes().enumerate() {
            if c == b'1' {
                s.insert(i);
            }
        }
        s
    }

    fn root() -> Cell {
        Cell::all_directions(Aabb::new(Vec3::ZERO, Vec3::ONE))
    }

    const LIMITS: DecodeLimits = DecodeLimits { max_nodes: 1 << 20 };

    fn round_trip(tree: &VisTree) {
        for coding in Coding::ALL {
            let (w, size) = encode(tree, coding);
            assert_eq!(w.bit_len(), size.total_bits());
            let bits = w.bit_len();
            let bytes = w.into_bytes();
            let back = decode(
                &bytes,
                bits,
                coding,
                tree.root_cell(),
                tree.grid_bits(),
                tree.object_count(),
                LIMITS,
            )
            .unwrap_or_else(|e| panic!("{coding}: {e}"));
            assert_eq!(&back, tree, "{coding}");
        }
    }

    #[test]
    fn papers_example() {
        // A internal with children B and C, split at x = 1/2 (q = 4).
        let nodes = vec![
            Node {
                split: Some(Split {
                    dim: 0,
                    code: 8,
                    above: 2,
                }),
                set: set("0111000"),
            },
            Node {
                split: None,
                set: set("0011000"),
            },
            Node {
                split: None,
                set: set("0101000"),
            },
        ];
        let tree = VisTree::from_parts(root(), 4, 7, nodes);
        tree.validate().unwrap();
        let bits: Vec<u64> = Coding::ALL
            .iter()
            .map(|&c| code_size(&tree, c).set_bits)
            .collect();
        assert_eq!(bits, [14, 13, 12]);
        // Structure: 2 leaves (1 bit) + 1 internal (1 + 3 + 4), sibling
        // coding one more bit for the order.
        let structure: Vec<u64> = Coding::ALL
            .iter()
            .map(|&c| code_size(&tree, c).structure_bits)
            .collect();
        assert_eq!(structure, [10, 10, 11]);
        round_trip(&tree);
    }

    /// A random valid tree: random splits, random leaf sets, unions above.
    fn random_tree(seed: u64, objects: usize, max_depth: u32, q: u32) -> VisTree {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        fn grow(
            nodes: &mut Vec<Node>,
            next: &mut dyn FnMut() -> u64,
            depth: u32,
            max_depth: u32,
            objects: usize,
            q: u32,
        ) -> ObjectSet {
            let me = nodes.len();
            nodes.push(Node {
                split: None,
                set: ObjectSet::new(objects),
            });
            if depth < max_depth && !next().is_multiple_of(3) {
                let dim = (next() % 5) as u8;
                let code = 1 + (next() % ((1 << q) - 1)) as u32;
                let mut u = grow(nodes, next, depth + 1, max_depth, objects, q);
                let above = nodes.len() as u32;
                u.union_with(&grow(nodes, next, depth + 1, max_depth, objects, q));
                nodes[me] = Node {
                    split: Some(Split { dim, code, above }),
                    set: u.clone(),
                };
                u
            } else {
                let mut s = ObjectSet::new(objects);
                let density = next() % 4;
                for o in 0..objects {
                    if next() % 4 < density {
                        s.insert(o);
                    }
                }
                nodes[me].set = s.clone();
                s
            }
        }
        let mut nodes = Vec::new();
        grow(&mut nodes, &mut next, 0, max_depth, objects, q);
        VisTree::from_parts(root(), q, objects, nodes)
    }

    #[test]
    fn random_trees_round_trip_through_every_coding() {
        for seed in 0..60 {
            let objects = [1, 7, 64, 65, 200][seed as usize % 5];
            let q = [1, 4, 10, 16][seed as usize % 4];
            let tree = random_tree(seed, objects, 8, q);
            tree.validate().unwrap();
            round_trip(&tree);
        }
    }

    #[test]
    fn corrupt_streams_are_refused() {
        let tree = (0..)
            .map(|seed| random_tree(seed, 20, 6, 10))
            .find(|t| t.nodes().len() > 8)
            .unwrap();
        for coding in Coding::ALL {
            let (w, _) = encode(&tree, coding);
            let bits = w.bit_len();
            let bytes = w.into_bytes();
            // Truncated by a bit, extended by a bit, or a node limit.
            assert!(decode(&bytes, bits - 1, coding, root(), 10, 20, LIMITS).is_err());
            let mut longer = bytes.clone();
            longer.push(0);
            assert!(decode(&longer, bits + 1, coding, root(), 10, 20, LIMITS).is_err());
            let small = DecodeLimits {
                max_nodes: tree.nodes().len() - 1,
            };
            assert!(matches!(
                decode(&bytes, bits, coding, root(), 10, 20, small),
                Err(CodecError::TooLarge(_))
            ));
            // Every single-bit flip decodes to an error or to a valid tree.
            for k in 0..bits.min(400) {
                let mut b = bytes.clone();
                b[(k / 8) as usize] ^= 1 << (k % 8);
                if let Ok(t) = decode(&b, bits, coding, root(), 10, 20, LIMITS) {
                    t.validate().unwrap();
                }
            }
        }
    }
}
