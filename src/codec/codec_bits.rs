//! Bit streams: least significant bit of each byte first.

use super::CodecError;

/// Appends bits to a byte vector.
#[derive(Clone, Debug, Default)]
pub struct BitWriter {
    bytes: Vec<u8>,
    bits: u64,
}

impl BitWriter {
    /// An empty stream.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends one bit.
    pub fn push(&mut self, bit: bool) {
        let i = (self.bits / 8) as usize;
        if i == self.bytes.len() {
            self.bytes.push(0);
        }
        self.bytes[i] |= (bit as u8) << (self.bits % 8);
        self.bits += 1;
    }

    /// Appends the `count` low bits of `value`, lowest first.
    pub fn push_bits(&mut self, value: u64, count: u32) {
        for k in 0..count {
            self.push(value >> k & 1 == 1);
        }
    }

    /// The number of bits written.
    pub fn bit_len(&self) -> u64 {
        self.bits
    }

    /// The bytes (the last one padded with zero bits).
    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }
}

/// Reads bits from a byte slice holding `bits` bits.
#[derive(Clone, Debug)]
pub struct BitReader<'a> {
    bytes: &'a [u8],
    bits: u64,
    pos: u64,
}

impl<'a> BitReader<'a> {
    /// A reader of the first `bits` bits of `bytes` (`bits <= 8 * len`).
    pub fn new(bytes: &'a [u8], bits: u64) -> Self {
        debug_assert!(bits <= bytes.len() as u64 * 8);
        Self {
            bytes,
            bits,
            pos: 0,
        }
    }

    /// Bits left.
    pub fn remaining(&self) -> u64 {
        self.bits - self.pos
    }

    /// The next bit, or an error past the end.
    pub fn read(&mut self) -> Result<bool, CodecError> {
        if self.pos >= self.bits {
            return Err(CodecError::Corrupt(
                "the coded tree ends in the middle of a node".into(),
            ));
        }
        let b = self.bytes[(self.pos / 8) as usize] >> (self.pos % 8) & 1;
        self.pos += 1;
        Ok(b == 1)
    }

    /// The next `count` bits as a number, lowest first.
    pub fn read_bits(&mut self, count: u32) -> Result<u64, CodecError> {
        let mut v = 0u64;
        for k in 0..count {
            v |= (self.read()? as u64) << k;
        }
        Ok(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
