//! Bit streams: least significant bit of each byte first.
//!
//! Bit k of the stream is bit `k % 8` of byte `k / 8`, which is the layout
//! of a `bitvec` [`BitSlice<u8, Lsb0>`]: the writer is a [`BitVec<u8,
//! Lsb0>`], the reader a view of the input bytes. A number of `count` bits
//! goes lowest bit first, so it is `BitField::store_le` / `load_le` on the
//! `count` bits it occupies. The last byte is padded with zero bits.

use bitvec::field::BitField;
use bitvec::order::Lsb0;
use bitvec::slice::BitSlice;
use bitvec::vec::BitVec;

use super::CodecError;

/// Appends bits to a byte vector.
#[derive(Clone, Debug, Default)]
pub struct BitWriter {
    bits: BitVec<u8, Lsb0>,
}

impl BitWriter {
    /// An empty stream.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends one bit.
    pub fn push(&mut self, bit: bool) {
        self.bits.push(bit);
    }

    /// Appends the `count` low bits of `value`, lowest first.
    ///
    /// # Panics
    /// When `count` is over 64.
    pub fn push_bits(&mut self, value: u64, count: u32) {
        assert!(count <= 64, "{count} bits do not fit in a u64");
        if count == 0 {
            return;
        }
        let start = self.bits.len();
        self.bits.resize(start + count as usize, false);
        self.bits[start..].store_le(value);
    }

    /// The number of bits written.
    pub fn bit_len(&self) -> u64 {
        self.bits.len() as u64
    }

    /// The bytes (the last one padded with zero bits).
    pub fn into_bytes(mut self) -> Vec<u8> {
        // Growing the vector zeroes new bytes already; this makes the
        // padding's value independent of how bitvec grows.
        self.bits.set_uninitialized(false);
        self.bits.into_vec()
    }
}

/// Reads bits from a byte slice holding `bits` bits.
#[derive(Clone, Debug)]
pub struct BitReader<'a> {
    /// The stream: the first `bits` bits of the bytes.
    bits: &'a BitSlice<u8, Lsb0>,
    /// The next bit to read.
    pos: usize,
}

impl<'a> BitReader<'a> {
    /// A reader of the first `bits` bits of `bytes`.
    ///
    /// # Panics
    /// When `bits > 8 * bytes.len()`.
    pub fn new(bytes: &'a [u8], bits: u64) -> Self {
        assert!(
            bits <= bytes.len() as u64 * 8,
            "{bits} bits do not fit in {} bytes",
            bytes.len()
        );
        Self {
            bits: &BitSlice::from_slice(bytes)[..bits as usize],
            pos: 0,
        }
    }

    /// Bits left.
    pub fn remaining(&self) -> u64 {
        (self.bits.len() - self.pos) as u64
    }

    /// The next bit, or an error past the end.
    #[inline]
    pub fn read(&mut self) -> Result<bool, CodecError> {
        let bit = *self.bits.get(self.pos).ok_or_else(overrun)?;
        self.pos += 1;
        Ok(bit)
    }

    /// The next `count` bits as a number, lowest first, or an error when
    /// fewer are left (the reader is then at the end).
    ///
    /// # Panics
    /// When `count` is over 64.
    pub fn read_bits(&mut self, count: u32) -> Result<u64, CodecError> {
        assert!(count <= 64, "{count} bits do not fit in a u64");
        if count == 0 {
            return Ok(0);
        }
        let end = self.pos + count as usize;
        let Some(field) = self.bits.get(self.pos..end) else {
            // Bit by bit, the stream ran out after the bits that were left.
            self.pos = self.bits.len();
            return Err(overrun());
        };
        self.pos = end;
        Ok(field.load_le())
    }
}

/// The error of a read past the end.
fn overrun() -> CodecError {
    CodecError::Corrupt("the coded tree ends in the middle of a node".into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    #[test]
    fn round_trip_and_overrun() {
        let mut w = BitWriter::new();
        w.push(true);
        w.push_bits(0b1011, 4);
        w.push_bits(0x3ff, 10);
        assert_eq!(w.bit_len(), 15);
        let bytes = w.into_bytes();
        assert_eq!(bytes.len(), 2);
        let mut r = BitReader::new(&bytes, 15);
        assert!(r.read().unwrap());
        assert_eq!(r.read_bits(4).unwrap(), 0b1011);
        assert_eq!(r.read_bits(10).unwrap(), 0x3ff);
        assert_eq!(r.remaining(), 0);
        assert!(r.read().is_err());
    }

    /// The packing the format specifies (notes/format.md), bit by bit:
    /// stream bit k is bit `k % 8` of byte `k / 8`.
    fn reference_pack(bits: &[bool]) -> Vec<u8> {
        let mut bytes = vec![0u8; bits.len().div_ceil(8)];
        for (k, &b) in bits.iter().enumerate() {
            bytes[k / 8] |= (b as u8) << (k % 8);
        }
        bytes
    }

    /// A value's `count` low bits, lowest first.
    fn low_bits(value: u64, count: u32) -> impl Iterator<Item = bool> {
        (0..count).map(move |k| value >> k & 1 == 1)
    }

    fn overrun_error() -> CodecError {
        CodecError::Corrupt("the coded tree ends in the middle of a node".into())
    }

    #[test]
    fn random_streams_round_trip_and_pack_lsb_first() {
        let mut rng = Pcg64::seed_from_u64(0xb175);
        for _ in 0..500 {
            // (value, count); count 0 is a single `push`.
            let items: Vec<(u64, u32)> = (0..rng.random_range(0..40))
                .map(|_| {
                    let count = rng.random_range(0..=64u32);
                    let value: u64 = rng.random();
                    (value, count)
                })
                .collect();
            let mut w = BitWriter::new();
            let mut reference = Vec::new();
            for &(value, count) in &items {
                if count == 0 {
                    w.push(value & 1 == 1);
                    reference.push(value & 1 == 1);
                } else {
                    // High bits past `count` must not leak into the stream.
                    w.push_bits(value, count);
                    reference.extend(low_bits(value, count));
                }
            }
            w.push_bits(u64::MAX, 0);
            assert_eq!(w.bit_len(), reference.len() as u64);
            let bytes = w.into_bytes();
            assert_eq!(bytes, reference_pack(&reference));

            let mut r = BitReader::new(&bytes, reference.len() as u64);
            for &(value, count) in &items {
                if count == 0 {
                    assert_eq!(r.read(), Ok(value & 1 == 1));
                } else {
                    let mask = u64::MAX >> (64 - count);
                    assert_eq!(r.read_bits(count), Ok(value & mask));
                }
            }
            assert_eq!(r.remaining(), 0);
            assert_eq!(r.read_bits(0), Ok(0));
            assert_eq!(r.read(), Err(overrun_error()));
            assert_eq!(r.read_bits(1), Err(overrun_error()));
        }
    }

    #[test]
    fn reads_past_the_end_fail_and_use_up_the_stream() {
        let mut rng = Pcg64::seed_from_u64(3);
        for _ in 0..200 {
            let bytes: Vec<u8> = (0..rng.random_range(0..12)).map(|_| rng.random()).collect();
            // The stream may stop inside the last byte; its padding is not
            // readable.
            let bits = rng.random_range(0..=bytes.len() * 8);
            let mut r = BitReader::new(&bytes, bits as u64);
            let skip = rng.random_range(0..=bits);
            for k in 0..skip {
                assert_eq!(r.read(), Ok(bytes[k / 8] >> (k % 8) & 1 == 1));
            }
            let left = bits - skip;
            assert_eq!(r.remaining(), left as u64);
            if left >= 64 {
                continue;
            }
            let count = rng.random_range(left + 1..=64) as u32;
            assert_eq!(r.read_bits(count), Err(overrun_error()));
            assert_eq!(r.remaining(), 0);
            assert_eq!(r.read(), Err(overrun_error()));
        }
    }

    #[test]
    fn the_committed_file_re_encodes_to_its_bytes() {
        // tests/v5d_corpus/ok_decodes.bin holds a file without its
        // checksum (tests/it/v5d.rs): decoding and encoding it again must
        // give the same bytes, bit streams included.
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/v5d_corpus/ok_decodes.bin"
        );
        let mut bytes = std::fs::read(path).expect("the committed corpus");
        bytes.extend_from_slice(&crate::codec::crc32(&bytes).to_le_bytes());
        let file = crate::codec::read_file(&bytes, crate::codec::ReadLimits::default())
            .expect("ok_decodes.bin decodes");
        // It is a version 1 file: written again it is the version written
        // (a frame origin and up axis, a bounds grid, unknown bounds per object, no leaf
        // records and no slices: two zero lengths after the tree), its
        // tree's bit stream unchanged, and written once more the same
        // bytes.
        assert_eq!(u16::from_le_bytes([bytes[8], bytes[9]]), 1);
        let v4 = crate::codec::write_file(&file);
        let tree_bytes = crate::codec::encode(&file.tree, file.coding)
            .0
            .into_bytes()
            .len();
        let tail = |b: &[u8], after: usize| {
            let body = &b[..b.len() - 4 - after];
            body[body.len() - (8 + tree_bytes)..].to_vec()
        };
        assert_eq!(tail(&v4, 8), tail(&bytes, 0));
        assert_eq!(v4[v4.len() - 12..v4.len() - 4], [0; 8]);
        let again = crate::codec::read_file(&v4, crate::codec::ReadLimits::default()).unwrap();
        assert_eq!(again, file);
        assert_eq!(crate::codec::write_file(&again), v4);
    }
}
