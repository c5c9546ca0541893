//! Deflate's bit packing (RFC 1951, 3.1.1): codes written least significant bit first into a
//! 64-bit accumulator, flushed eight bytes at a time into a buffer sized in advance.

/// A bit writer over a zero-filled buffer whose length the caller has bounded: every flush
/// stores eight bytes, so the buffer needs eight bytes of slack past the last one written.
pub struct BitWriter {
    out: Vec<u8>,
    pos: usize,
    acc: u64,
    filled: u32,
}

impl BitWriter {
    /// A writer with room for `bytes` bytes of output (plus its own slack).
    pub fn with_capacity(bytes: usize) -> Self {
        BitWriter {
            out: vec![0; bytes + 16],
            pos: 0,
            acc: 0,
            filled: 0,
        }
    }

    /// Adds the `bits` low bits of `value` (already in the order they are to be sent). At most
    /// 56 bits may be added between two [`BitWriter::flush`] calls.
    #[inline(always)]
    pub fn put(&mut self, value: u64, bits: u32) {
        self.acc |= value << self.filled;
        self.filled += bits;
    }

    /// Moves the whole bytes of the accumulator to the buffer; fewer than 8 bits stay.
    #[inline(always)]
    pub fn flush(&mut self) {
        let whole = (self.filled >> 3) as usize;
        self.out[self.pos..self.pos + 8].copy_from_slice(&self.acc.to_le_bytes());
        self.pos += whole;
        self.acc = if whole >= 8 {
            0
        } else {
            self.acc >> (whole * 8)
        };
        self.filled &= 7;
    }

    /// Adds `value`'s `bits` low bits and flushes (for headers: any width up to 56).
    pub fn put_flush(&mut self, value: u64, bits: u32) {
        self.put(value, bits);
        self.flush();
    }

    /// Pads with zero bits to the next byte boundary.
    pub fn align_to_byte(&mut self) {
        self.filled = (self.filled + 7) & !7;
        self.flush();
    }

    /// Copies `bytes` at a byte boundary (call [`BitWriter::align_to_byte`] first).
    pub fn put_bytes(&mut self, bytes: &[u8]) {
        self.out[self.pos..self.pos + bytes.len()].copy_from_slice(bytes);
        self.pos += bytes.len();
    }

    /// The written bytes, the last one padded with zero bits.
    pub fn finish(mut self) -> Vec<u8> {
        self.align_to_byte();
        self.out.truncate(self.pos);
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bits go out least significant first across byte boundaries, as RFC 1951 packs them.
    #[test]
    fn packs_least_significant_bit_first() {
        let mut w = BitWriter::with_capacity(8);
        w.put(0b1, 1);
        w.put(0b10, 2);
        w.put(0b11111, 5);
        w.put(0b1_0000_0001, 9);
        w.flush();
        w.put_flush(0x3, 2);
        w.align_to_byte();
        w.put_bytes(&[0xAB]);
        // 1, then 10 → bits 0..2 = 1,0,1; then 11111 → byte 0 = 0b1111_1101.
        // 9 bits 1_0000_0001 → byte 1 = 0x01, bit 0 of byte 2 = 1; then 11 → byte 2 = 0b111.
        assert_eq!(w.finish(), [0xFD, 0x01, 0x07, 0xAB]);
    }
}
