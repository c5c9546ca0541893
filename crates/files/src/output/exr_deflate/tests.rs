use super::*;

/// Xorshift64: a fixed-seed generator for test data.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// Compresses `input`, inflates the stream with two independent inflaters (miniz_oxide and
/// libdeflate), checks both give `input` back, and returns the stream.
fn round_trip(input: &[u8], what: &str) -> Vec<u8> {
    let z = zlib_compress(input);
    let miniz = miniz_oxide::inflate::decompress_to_vec_zlib(&z)
        .unwrap_or_else(|e| panic!("{what}: miniz_oxide rejects the stream: {e:?}"));
    assert!(miniz == input, "{what}: miniz_oxide inflates other bytes");
    let mut out = vec![0u8; input.len()];
    let n = libdeflater::Decompressor::new()
        .zlib_decompress(&z, &mut out)
        .unwrap_or_else(|e| panic!("{what}: libdeflate rejects the stream: {e:?}"));
    assert!(
        n == input.len() && out == input,
        "{what}: libdeflate inflates other bytes"
    );
    z
}

/// The first deflate block's type (0 stored, 2 dynamic Huffman).
fn first_block_type(z: &[u8]) -> u8 {
    (z[2] >> 1) & 3
}

/// OpenEXR ZIP bytes of a 16-row block of a noisy image: Poisson-like counts around `mean`
/// (a sum of uniform draws), as `f32`, predicted as the EXR writer does.
fn noisy_block(rng: &mut Rng, width: usize, mean: u64) -> Vec<u8> {
    let samples: Vec<f32> = (0..16 * width)
        .map(|_| {
            let spread = (mean as f64).sqrt() as u64 * 2 + 1;
            let v = mean + (0..3).map(|_| rng.below(spread)).sum::<u64>() - 3 * (spread / 2);
            v.min(65_535) as f32
        })
        .collect();
    crate::output::exr::zip_predicted(&samples)
}

#[test]
fn zlib_header_and_adler32() {
    let z = round_trip(b"Wikipedia", "text");
    assert_eq!(&z[..2], &[0x78, 0x01]);
    assert_eq!(u16::from_be_bytes([z[0], z[1]]) % 31, 0);
    // Adler-32 of "Wikipedia" is 0x11E60398 (RFC 1950's example value on Wikipedia).
    assert_eq!(&z[z.len() - 4..], &[0x11, 0xE6, 0x03, 0x98]);
}

#[test]
fn empty_and_single_bytes() {
    round_trip(&[], "empty");
    for b in [0u8, 1, 128, 255] {
        round_trip(&[b], "one byte");
        round_trip(&[b, b], "two bytes");
        round_trip(&[b, b, b], "three bytes");
    }
}

#[test]
fn all_zero_and_all_equal_use_runs() {
    for len in [
        7, 8, 9, 15, 16, 17, 258, 259, 260, 261, 262, 4095, 4096, 92_160, 200_000,
    ] {
        for b in [0u8, 128, 0xAB] {
            let z = round_trip(&vec![b; len], "constant");
            // Two dynamic blocks of runs: about 5 bits per 258 bytes plus the headers.
            assert!(z.len() <= 100 + len / 200, "{len} × {b}: {} bytes", z.len());
        }
    }
}

/// Runs of every length around the match limits (3, 258, 2 · 258, …), between noise bytes,
/// including runs that end exactly at the end of a block.
#[test]
fn long_runs_around_the_match_limits() {
    let mut rng = Rng(7);
    for run in (1..20)
        .chain(250..270)
        .chain(510..530)
        .chain([1000, 5000, 70_000])
    {
        let mut data: Vec<u8> = (0..100).map(|_| rng.next() as u8).collect();
        data.extend(std::iter::repeat_n(rng.next() as u8, run));
        data.extend((0..50).map(|_| rng.next() as u8));
        data.extend(std::iter::repeat_n(0u8, run));
        round_trip(&data, &format!("run of {run}"));
    }
}

/// Random bytes do not compress: the blocks are stored, and the stream is raw plus a few
/// bytes of framing (including at the stored blocks' 65 535-byte limit).
#[test]
fn random_bytes_are_stored() {
    let mut rng = Rng(11);
    for len in [
        1usize, 100, 4095, 4096, 4097, 65_535, 65_536, 131_070, 131_071, 131_072, 300_001,
    ] {
        let data: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
        let z = round_trip(&data, "random");
        assert!(
            z.len() <= len + 6 + 2 * 5 * (len / 65_535 + 1) + 2,
            "{len}: {}",
            z.len()
        );
        assert_eq!(first_block_type(&z), 0, "{len}");
    }
}

/// Blocks of the kind the protocol writes (noisy counts as `f32` after OpenEXR's prediction,
/// 1440 and 240 samples wide) are coded as dynamic Huffman blocks well below raw size.
#[test]
fn noisy_exr_blocks_are_huffman_coded() {
    let mut rng = Rng(3);
    for (width, mean) in [(1440, 15_000), (1440, 59_000), (240, 2_000), (240, 30_000)] {
        let block = noisy_block(&mut rng, width, mean);
        let z = round_trip(&block, "noisy block");
        assert_eq!(first_block_type(&z), 2);
        assert!(
            z.len() * 10 < block.len() * 8,
            "{width} {mean}: {} of {}",
            z.len(),
            block.len()
        );
    }
}

/// Lengths at the split into two blocks and odd sizes, from small to large.
#[test]
fn lengths_at_block_boundaries() {
    let mut rng = Rng(5);
    for len in [
        2,
        3,
        4,
        5,
        255,
        256,
        257,
        SPLIT_AT_LEAST - 1,
        SPLIT_AT_LEAST,
        SPLIT_AT_LEAST + 1,
    ] {
        let skewed: Vec<u8> = (0..len)
            .map(|_| (rng.below(8) * rng.below(8)) as u8)
            .collect();
        round_trip(&skewed, &format!("skewed {len}"));
    }
}

/// A property loop with a fixed seed: inputs mixing noise of varying width, runs of varying
/// length and OpenEXR blocks, of random lengths, all round-trip through both inflaters.
#[test]
fn property_loop_round_trips() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for case in 0..300 {
        let len = [rng.below(64), rng.below(5000), rng.below(150_000)][case % 3] as usize;
        let mut data = Vec::with_capacity(len);
        while data.len() < len {
            let piece = 1 + rng.below(600) as usize;
            match rng.below(4) {
                0 => data.extend(std::iter::repeat_n(rng.next() as u8, piece)),
                1 => data.extend((0..piece).map(|_| rng.next() as u8)),
                2 => {
                    let bits = 1 + rng.below(8);
                    data.extend((0..piece).map(|_| (rng.next() % (1 << bits)) as u8 ^ 0x80))
                }
                _ => {
                    let (width, mean) = (1 + rng.below(40) as usize, rng.below(60_000));
                    data.extend(noisy_block(&mut rng, width, mean))
                }
            }
        }
        data.truncate(len);
        round_trip(&data, &format!("case {case}"));
    }
}

/// The same input gives the same stream (no state carried between calls).
#[test]
fn same_input_same_stream() {
    let mut rng = Rng(13);
    let block = noisy_block(&mut rng, 1440, 30_000);
    let first = zlib_compress(&block);
    zlib_compress(&[1, 2, 3]);
    assert!(zlib_compress(&block) == first);
}

#[test]
fn length_codes_follow_rfc_1951() {
    // Examples from RFC 1951, 3.2.5: length 3 is 257, 10 is 264, 11 is 265 + 1 extra bit 0,
    // 12 is 265 + 1, 227 is 284 + 5 bits 0, 257 is 284 + 30, 258 is 285.
    assert_eq!(LENGTH_CODES[3], (257, 0, 0));
    assert_eq!(LENGTH_CODES[10], (264, 0, 0));
    assert_eq!(LENGTH_CODES[11], (265, 1, 0));
    assert_eq!(LENGTH_CODES[12], (265, 1, 1));
    assert_eq!(LENGTH_CODES[227], (284, 5, 0));
    assert_eq!(LENGTH_CODES[257], (284, 5, 30));
    assert_eq!(LENGTH_CODES[258], (285, 0, 0));
}

#[test]
fn code_lengths_run_length_coding() {
    let lengths = [vec![0u8; 140], vec![5; 8], vec![0; 2], vec![3; 3]].concat();
    let coded = run_length_code(&lengths);
    assert_eq!(
        coded,
        [
            (18, 127),
            (0, 0),
            (0, 0),
            (5, 0),
            (16, 3),
            (5, 0),
            (0, 0),
            (0, 0),
            (3, 0),
            (3, 0),
            (3, 0)
        ]
    );
}
