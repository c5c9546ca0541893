//! A zlib encoder made for OpenEXR ZIP blocks of noisy images (the `zip` compression of the
//! EXR files): Huffman codes built from each block's own byte counts, plus run-length matches at
//! distance 1. It is written here only because speed requires it.
//!
//! ## Why not a general deflate library
//!
//! After OpenEXR's predictor (bytes split into even and odd halves, then differences), the
//! blocks of a noisy 16-bit image held as `f32` are mostly noise bytes with a skewed histogram
//! and almost no repeated strings: libdeflate at its fastest level (1.26, through `libdeflater`,
//! the encoder of 0.5.0) spent most of its time looking for matches that barely exist, and was
//! still 47 % of the CPU time of the binary protocol. fdeflate (0.3.7) is fast but uses fixed
//! code tables made for PNG, which make these blocks larger than raw. miniz_oxide (0.8, 0.9)
//! and zlib-rs (0.6) in their Huffman-only modes are slower than libdeflate. The measurements
//! are in docs/src/results/speed.md ("The EXR encoder") and `examples/encoder_levels.rs`.
//!
//! ## The stream
//!
//! A zlib header (`78 01`), deflate blocks, the Adler-32 of the input (`simd-adler32`, pinned;
//! its value is fixed by RFC 1950 whatever instructions compute it). Input of
//! [`SPLIT_AT_LEAST`] bytes or more is coded as two deflate blocks, its first and second half,
//! which after OpenEXR's byte split hold different bytes of each sample and so have different
//! histograms; shorter input is one block. Each block is a dynamic-Huffman block (RFC 1951,
//! 3.2.7) whose literal/length and distance codes are built from the block's own symbol counts
//! (length-limited to 15 bits, canonical, [`huffman`]), or a stored block where that would be
//! smaller. Runs of one byte value are found wherever eight equal bytes are aligned to the
//! scan's eight-byte steps (so every run of 15 or more, and shorter ones by luck); a run is
//! coded as its first byte and matches at distance 1 of at most 258 bytes. Everything that
//! decides a byte is integer code on the input alone: the stream is the same on every platform.
//!
//! Matches at other distances were measured on the protocol's blocks: repeats of 4 bytes or
//! more at distance 2 or at one row cover only 2–13 % of the bytes of the noisy images, at one
//! half-block none. libdeflate's output is a quarter smaller through string matches at many
//! distances, which cost a search at every byte; this encoder does not search.

mod bits;
pub mod huffman;

use bits::BitWriter;

/// Input at least this long is coded as two deflate blocks (its halves).
pub const SPLIT_AT_LEAST: usize = 4096;

/// Deflate's longest match.
const MAX_MATCH: usize = 258;
/// Literal/length alphabet size (0–255 literals, 256 end of block, 257–285 lengths).
const LITLEN_SYMBOLS: usize = 286;
const END_OF_BLOCK: usize = 256;
/// Order in which the code-length code's lengths are sent (RFC 1951, 3.2.7).
const CODE_LENGTH_ORDER: [usize; 19] = [
    16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15,
];

/// For each match length 3..=258: its length symbol (257–285), extra bit count and extra value.
const LENGTH_CODES: [(u16, u8, u16); MAX_MATCH + 1] = length_codes();

const fn length_codes() -> [(u16, u8, u16); MAX_MATCH + 1] {
    // Base length and extra bits of symbols 257..=285 (RFC 1951, 3.2.5).
    const BASE: [u16; 29] = [
        3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59, 67, 83, 99, 115,
        131, 163, 195, 227, 258,
    ];
    const EXTRA: [u8; 29] = [
        0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0,
    ];
    let mut table = [(0u16, 0u8, 0u16); MAX_MATCH + 1];
    let mut symbol = 0;
    while symbol < 29 {
        let span = if symbol == 28 {
            1
        } else {
            1u16 << EXTRA[symbol]
        };
        let mut k = 0;
        while k < span {
            let length = BASE[symbol] + k;
            // Length 258 has its own symbol (285); 284's range stops at 257.
            if length as usize <= MAX_MATCH && !(symbol == 27 && length == 258) {
                table[length as usize] = (257 + symbol as u16, EXTRA[symbol], k);
            }
            k += 1;
        }
        symbol += 1;
    }
    table
}

/// `input` as a zlib stream (RFC 1950) as described in the module documentation.
pub fn zlib_compress(input: &[u8]) -> Vec<u8> {
    let plans: Vec<BlockPlan> = if input.len() >= SPLIT_AT_LEAST {
        let (first, second) = input.split_at(input.len() / 2);
        vec![BlockPlan::new(first), BlockPlan::new(second)]
    } else {
        vec![BlockPlan::new(input)]
    };
    let bound: usize = plans.iter().map(|p| p.bytes_bound()).sum::<usize>() + 16;
    let mut w = BitWriter::with_capacity(bound);
    w.put_bytes(&[0x78, 0x01]);
    let last = plans.len() - 1;
    for (i, plan) in plans.iter().enumerate() {
        plan.write(&mut w, i == last);
    }
    let mut out = w.finish();
    out.extend_from_slice(&simd_adler32::adler32(&input).to_be_bytes());
    out
}

/// One deflate block: where its runs are, its symbol counts, its codes and its size.
struct BlockPlan<'a> {
    data: &'a [u8],
    /// `(position, length)` of each match at distance 1, in order.
    matches: Vec<(u32, u16)>,
    litlen_lengths: Vec<u8>,
    dist_lengths: Vec<u8>,
    /// The code-length code's lengths and the run-length coded code lengths.
    header: Header,
    /// Whether a dynamic block is smaller than stored blocks.
    dynamic: bool,
    dynamic_bits: u64,
}

impl<'a> BlockPlan<'a> {
    fn new(data: &'a [u8]) -> Self {
        let matches = find_runs(data);
        let mut litlen = byte_counts(data);
        litlen.resize(LITLEN_SYMBOLS, 0);
        litlen[END_OF_BLOCK] = 1;
        let mut dist = [0u32; 30];
        for &(pos, len) in &matches {
            let byte = data[pos as usize];
            litlen[usize::from(byte)] -= u32::from(len);
            litlen[usize::from(LENGTH_CODES[usize::from(len)].0)] += 1;
            dist[0] += 1;
        }
        // A complete distance code needs two symbols (zlib sends two when it uses fewer).
        let dist_counts = [dist[0].max(1), 1];
        let litlen_lengths = huffman::code_lengths(&litlen, 15);
        let dist_lengths = huffman::code_lengths(&dist_counts, 15);
        let header = Header::new(&litlen_lengths, &dist_lengths);
        let mut bits = 3 + header.bits();
        for (s, &c) in litlen.iter().enumerate() {
            bits += u64::from(c) * u64::from(litlen_lengths[s]);
        }
        for &(_, len) in &matches {
            bits += u64::from(LENGTH_CODES[usize::from(len)].1) + u64::from(dist_lengths[0]);
        }
        BlockPlan {
            data,
            matches,
            dynamic: bits < stored_bits(data.len()),
            litlen_lengths,
            dist_lengths,
            header,
            dynamic_bits: bits,
        }
    }

    /// Bytes this block takes at most (rounded up, plus a byte of bit alignment).
    fn bytes_bound(&self) -> usize {
        if self.dynamic {
            self.dynamic_bits.div_ceil(8) as usize + 1
        } else {
            (stored_bits(self.data.len()) / 8) as usize + 1
        }
    }

    fn write(&self, w: &mut BitWriter, last: bool) {
        if !self.dynamic {
            write_stored(w, self.data, last);
            return;
        }
        w.put_flush(u64::from(last) | (0b10 << 1), 3);
        self.header.write(w);
        let codes = huffman::canonical_codes(&self.litlen_lengths);
        // Code and length of every literal/length symbol, packed for the inner loop.
        let table: Vec<(u64, u32)> = codes
            .iter()
            .zip(&self.litlen_lengths)
            .map(|(&c, &l)| (u64::from(c), u32::from(l)))
            .collect();
        let dist_code = huffman::canonical_codes(&self.dist_lengths)[0];
        let dist_bits = u32::from(self.dist_lengths[0]);
        let mut at = 0usize;
        for &(pos, len) in &self.matches {
            write_literals(w, &table, &self.data[at..pos as usize]);
            let (symbol, extra_bits, extra) = LENGTH_CODES[usize::from(len)];
            let (code, bits) = table[usize::from(symbol)];
            w.put(code, bits);
            w.put(u64::from(extra), u32::from(extra_bits));
            w.put(u64::from(dist_code), dist_bits);
            w.flush();
            at = pos as usize + usize::from(len);
        }
        write_literals(w, &table, &self.data[at..]);
        let (code, bits) = table[END_OF_BLOCK];
        w.put_flush(code, bits);
    }
}

/// Bits of `len` bytes as stored blocks (header, alignment, LEN/NLEN per 65 535 bytes).
fn stored_bits(len: usize) -> u64 {
    let blocks = len.div_ceil(65_535).max(1) as u64;
    8 * (len as u64 + 5 * blocks) + 8
}

fn write_stored(w: &mut BitWriter, data: &[u8], last: bool) {
    let mut chunks: Vec<&[u8]> = data.chunks(65_535).collect();
    if chunks.is_empty() {
        chunks.push(&[]);
    }
    let count = chunks.len();
    for (i, chunk) in chunks.into_iter().enumerate() {
        w.put_flush(u64::from(last && i + 1 == count), 3);
        w.align_to_byte();
        let len = chunk.len() as u16;
        w.put_bytes(&len.to_le_bytes());
        w.put_bytes(&(!len).to_le_bytes());
        w.put_bytes(chunk);
    }
}

/// Writes `bytes` as literals, three codes (at most 45 bits) per flush.
#[inline(always)]
fn write_literals(w: &mut BitWriter, table: &[(u64, u32)], bytes: &[u8]) {
    let mut triples = bytes.chunks_exact(3);
    for t in &mut triples {
        let (c0, l0) = table[usize::from(t[0])];
        let (c1, l1) = table[usize::from(t[1])];
        let (c2, l2) = table[usize::from(t[2])];
        w.put(c0, l0);
        w.put(c1, l1);
        w.put(c2, l2);
        w.flush();
    }
    for &b in triples.remainder() {
        let (c, l) = table[usize::from(b)];
        w.put_flush(c, l);
    }
}

/// How often each byte value occurs (four interleaved tables, so that equal neighbours do not
/// wait on each other's increments).
fn byte_counts(data: &[u8]) -> Vec<u32> {
    let mut t = [[0u32; 256]; 4];
    let mut quads = data.chunks_exact(4);
    for q in &mut quads {
        t[0][usize::from(q[0])] += 1;
        t[1][usize::from(q[1])] += 1;
        t[2][usize::from(q[2])] += 1;
        t[3][usize::from(q[3])] += 1;
    }
    for &b in quads.remainder() {
        t[0][usize::from(b)] += 1;
    }
    (0..256)
        .map(|i| t[0][i] + t[1][i] + t[2][i] + t[3][i])
        .collect()
}

/// The matches at distance 1 that code the runs of one byte value: wherever the eight bytes at
/// a scan step are equal, the run is extended both ways, its first byte stays a literal and the
/// rest becomes matches of at most 258 bytes (never leaving a tail of 1 or 2, which no match can
/// code: such a tail stays literal).
fn find_runs(data: &[u8]) -> Vec<(u32, u16)> {
    let mut matches = Vec::new();
    let (mut i, mut free_from) = (0usize, 0usize);
    while i + 8 <= data.len() {
        let word = u64::from_le_bytes([
            data[i],
            data[i + 1],
            data[i + 2],
            data[i + 3],
            data[i + 4],
            data[i + 5],
            data[i + 6],
            data[i + 7],
        ]);
        if word != u64::from(data[i]) * 0x0101_0101_0101_0101 {
            i += 8;
            continue;
        }
        let byte = data[i];
        let mut start = i;
        while start > free_from && data[start - 1] == byte {
            start -= 1;
        }
        let mut end = i + 8;
        while end < data.len() && data[end] == byte {
            end += 1;
        }
        let mut at = start + 1;
        let mut left = end - at;
        while left >= 3 {
            let mut len = left.min(MAX_MATCH);
            if (1..3).contains(&(left - len)) {
                len = left - 3;
            }
            matches.push((at as u32, len as u16));
            at += len;
            left -= len;
        }
        free_from = end;
        i = end;
    }
    matches
}

/// The code-length part of a dynamic block header (RFC 1951, 3.2.7).
struct Header {
    /// Literal/length and distance code lengths sent (HLIT + 257, HDIST + 1).
    hlit: usize,
    hdist: usize,
    /// Run-length coded code lengths: (symbol 0–18, its extra value).
    symbols: Vec<(u8, u8)>,
    /// The code-length code's lengths.
    lengths: Vec<u8>,
    /// How many code-length code lengths are sent (HCLEN + 4, 4–19).
    count: usize,
}

impl Header {
    fn new(litlen_lengths: &[u8], dist_lengths: &[u8]) -> Self {
        let hlit = sent_lengths(litlen_lengths, 257);
        let hdist = sent_lengths(dist_lengths, 1);
        let all: Vec<u8> = litlen_lengths[..hlit]
            .iter()
            .chain(&dist_lengths[..hdist])
            .copied()
            .collect();
        let symbols = run_length_code(&all);
        let mut counts = [0u32; 19];
        for &(s, _) in &symbols {
            counts[usize::from(s)] += 1;
        }
        // Keep the code-length code complete when a single symbol is used.
        if counts.iter().filter(|&&c| c > 0).count() < 2 {
            let spare = if counts[0] == 0 { 0 } else { 1 };
            counts[spare] = 1;
        }
        let lengths = huffman::code_lengths(&counts, 7);
        let count = (4..=19)
            .rev()
            .find(|&n| lengths[CODE_LENGTH_ORDER[n - 1]] != 0)
            .unwrap_or(4);
        Header {
            hlit,
            hdist,
            symbols,
            lengths,
            count,
        }
    }

    /// Its size in bits, from HLIT to the last code length.
    fn bits(&self) -> u64 {
        14 + 3 * self.count as u64
            + self
                .symbols
                .iter()
                .map(|&(s, _)| u64::from(self.lengths[usize::from(s)]) + u64::from(extra_bits(s)))
                .sum::<u64>()
    }

    fn write(&self, w: &mut BitWriter) {
        w.put_flush(
            (self.hlit - 257) as u64
                | ((self.hdist - 1) as u64) << 5
                | ((self.count - 4) as u64) << 10,
            14,
        );
        for &s in &CODE_LENGTH_ORDER[..self.count] {
            w.put_flush(u64::from(self.lengths[s]), 3);
        }
        let codes = huffman::canonical_codes(&self.lengths);
        for &(s, extra) in &self.symbols {
            let i = usize::from(s);
            w.put(u64::from(codes[i]), u32::from(self.lengths[i]));
            w.put_flush(u64::from(extra), extra_bits(s));
        }
    }
}

/// Extra bits after a code-length symbol: 16 repeats the previous length 3–6 times, 17 and 18
/// send 3–10 and 11–138 zeros.
fn extra_bits(symbol: u8) -> u32 {
    match symbol {
        16 => 2,
        17 => 3,
        18 => 7,
        _ => 0,
    }
}

/// How many of `lengths` are sent: up to the last non-zero one, at least `min`.
fn sent_lengths(lengths: &[u8], min: usize) -> usize {
    lengths
        .iter()
        .rposition(|&l| l != 0)
        .map_or(min, |last| (last + 1).max(min))
}

/// Code lengths as code-length symbols: zeros in runs by 17 and 18, other repeats by 16.
fn run_length_code(lengths: &[u8]) -> Vec<(u8, u8)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < lengths.len() {
        let value = lengths[i];
        let run = lengths[i..].iter().take_while(|&&l| l == value).count();
        i += run;
        let mut left = run;
        if value == 0 {
            while left >= 11 {
                let n = left.min(138);
                out.push((18, (n - 11) as u8));
                left -= n;
            }
            if left >= 3 {
                out.push((17, (left - 3) as u8));
                left = 0;
            }
        } else {
            out.push((value, 0));
            left -= 1;
            while left >= 3 {
                let n = left.min(6);
                out.push((16, (n - 3) as u8));
                left -= n;
            }
        }
        out.extend(std::iter::repeat_n((value, 0), left));
    }
    out
}

#[cfg(test)]
mod tests;
