//! Length-limited Huffman code lengths and canonical deflate codes (RFC 1951, 3.2.2), built
//! from a block's own symbol counts with integer arithmetic only (no floats decide a length).

/// Code lengths for `counts` (0 for an unused symbol), none longer than `max_bits`.
///
/// A Huffman tree is built with two queues (leaves sorted by count, then symbol; a leaf goes
/// first when it weighs as much as an internal node, so ties are broken the same way on every
/// platform). Lengths over `max_bits` are then cut to `max_bits` and the Kraft sum brought back
/// to exactly 1 by the usual repair: take one code away at `max_bits` and split one shorter code
/// into two one bit longer, until the sum is 1. The lengths are finally handed out again by count
/// (rarest symbols longest). With two or more used symbols the code is complete (Kraft equality);
/// with one, that symbol gets length 1; with none, all lengths are 0.
pub fn code_lengths(counts: &[u32], max_bits: u8) -> Vec<u8> {
    let mut lengths = vec![0u8; counts.len()];
    let mut leaves: Vec<(u32, u16)> = counts
        .iter()
        .enumerate()
        .filter(|(_, c)| **c > 0)
        .map(|(s, &c)| (c, s as u16))
        .collect();
    leaves.sort_unstable();
    let n = leaves.len();
    if n == 0 {
        return lengths;
    }
    if n == 1 {
        lengths[usize::from(leaves[0].1)] = 1;
        return lengths;
    }
    // Nodes 0..n are the leaves in ascending order, n..2n-1 the internal nodes in creation
    // order (their weights never decrease, so the second queue stays sorted).
    let mut weight: Vec<u64> = leaves.iter().map(|&(c, _)| u64::from(c)).collect();
    weight.resize(2 * n - 1, 0);
    let mut parent = vec![0usize; 2 * n - 1];
    let (mut next_leaf, mut next_inner) = (0usize, n);
    for node in n..2 * n - 1 {
        let mut pick = || {
            if next_leaf < n && (next_inner >= node || weight[next_leaf] <= weight[next_inner]) {
                next_leaf += 1;
                next_leaf - 1
            } else {
                next_inner += 1;
                next_inner - 1
            }
        };
        let (a, b) = (pick(), pick());
        weight[node] = weight[a] + weight[b];
        parent[a] = node;
        parent[b] = node;
    }
    // Parents have higher indices than their children: depths in one descending pass.
    let mut depth = vec![0usize; 2 * n - 1];
    for node in (0..2 * n - 2).rev() {
        depth[node] = depth[parent[node]] + 1;
    }
    let max = usize::from(max_bits);
    let mut per_length = vec![0u64; max + 1];
    for &d in &depth[..n] {
        per_length[d.min(max)] += 1;
    }
    // Kraft sum in units of 2^-max; the uncut tree sums to exactly 2^max.
    let mut kraft: u64 = (1..=max).map(|l| per_length[l] << (max - l)).sum();
    while kraft > 1u64 << max {
        per_length[max] -= 1;
        if let Some(shorter) = (1..max).rev().find(|&l| per_length[l] > 0) {
            per_length[shorter] -= 1;
            per_length[shorter + 1] += 2;
        }
        kraft -= 1;
    }
    // Rarest first get the longest codes.
    let mut leaf = leaves.iter();
    for length in (1..=max).rev() {
        for _ in 0..per_length[length] {
            if let Some(&(_, symbol)) = leaf.next() {
                lengths[usize::from(symbol)] = length as u8;
            }
        }
    }
    lengths
}

/// Canonical deflate codes for `lengths` (RFC 1951, 3.2.2), each bit-reversed so that it can be
/// written least significant bit first, as deflate's bit packing wants.
pub fn canonical_codes(lengths: &[u8]) -> Vec<u16> {
    let max = lengths.iter().copied().max().unwrap_or(0) as usize;
    let mut per_length = vec![0u32; max + 1];
    for &l in lengths {
        per_length[usize::from(l)] += 1;
    }
    per_length[0] = 0;
    let mut next = vec![0u32; max + 2];
    let mut code = 0u32;
    for bits in 1..=max {
        code = (code + per_length[bits - 1]) << 1;
        next[bits] = code;
    }
    lengths
        .iter()
        .map(|&l| {
            if l == 0 {
                return 0;
            }
            let c = next[usize::from(l)];
            next[usize::from(l)] += 1;
            (c.reverse_bits() >> (32 - u32::from(l))) as u16
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kraft_units(lengths: &[u8], max: u8) -> u64 {
        lengths
            .iter()
            .filter(|&&l| l > 0)
            .map(|&l| 1u64 << (max - l))
            .sum()
    }

    /// Fibonacci counts make the unlimited Huffman tree as deep as the alphabet: the 15-bit
    /// limit has to cut it, and the result is still a complete code.
    #[test]
    fn fibonacci_counts_are_cut_to_15_bits_and_stay_complete() {
        let mut counts = vec![0u32; 30];
        let (mut a, mut b) = (1u32, 1u32);
        for c in &mut counts {
            *c = a;
            (a, b) = (b, a + b);
        }
        let unlimited = code_lengths(&counts, 40);
        assert_eq!(unlimited.iter().max(), Some(&29));
        let lengths = code_lengths(&counts, 15);
        assert_eq!(lengths.iter().max(), Some(&15));
        assert_eq!(kraft_units(&lengths, 15), 1 << 15);
        // More frequent symbols never get longer codes.
        for i in 1..counts.len() {
            assert!(lengths[i] <= lengths[i - 1]);
        }
    }

    /// A property loop with a fixed seed: random counts over deflate's alphabets (sparse and
    /// dense, skewed and flat) always give complete codes within the limit, and as short as
    /// the optimal (unlimited) Huffman code wherever the limit is not reached.
    #[test]
    fn random_counts_give_complete_limited_codes() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for round in 0..2000 {
            let size = [19usize, 30, 286][round % 3];
            let limit = if size == 19 { 7 } else { 15 };
            let counts: Vec<u32> = (0..size)
                .map(|_| {
                    let r = next();
                    match r % 4 {
                        0 => 0,
                        1 => (r >> 8) as u32 % 3,
                        2 => 1 << ((r >> 8) % 24),
                        _ => (r >> 8) as u32 % 100_000,
                    }
                })
                .collect();
            let used = counts.iter().filter(|&&c| c > 0).count();
            let lengths = code_lengths(&counts, limit);
            for (c, l) in counts.iter().zip(&lengths) {
                assert_eq!(*c == 0, *l == 0, "round {round}");
            }
            assert!(lengths.iter().all(|&l| l <= limit));
            if used >= 2 {
                assert_eq!(kraft_units(&lengths, limit), 1 << limit, "round {round}");
                let cost = |ls: &[u8]| -> u64 {
                    counts
                        .iter()
                        .zip(ls)
                        .map(|(&c, &l)| u64::from(c) * u64::from(l))
                        .sum()
                };
                let unlimited = code_lengths(&counts, 60);
                if unlimited.iter().all(|&l| l <= limit) {
                    assert_eq!(cost(&lengths), cost(&unlimited), "round {round}");
                }
            }
        }
    }

    /// RFC 1951's example (3.2.2): lengths (3, 3, 3, 3, 3, 2, 4, 4) for A..H give the codes
    /// 010, 011, 100, 101, 110, 00, 1110, 1111.
    #[test]
    fn canonical_codes_match_the_rfc_example() {
        let codes = canonical_codes(&[3, 3, 3, 3, 3, 2, 4, 4]);
        let expected = [0b010u16, 0b011, 0b100, 0b101, 0b110, 0b00, 0b1110, 0b1111];
        let lengths = [3u32, 3, 3, 3, 3, 2, 4, 4];
        for ((c, e), l) in codes.iter().zip(expected).zip(lengths) {
            assert_eq!(u32::from(*c), u32::from(e).reverse_bits() >> (32 - l));
        }
    }

    #[test]
    fn one_and_no_used_symbols() {
        assert_eq!(code_lengths(&[0, 5, 0], 15), [0, 1, 0]);
        assert_eq!(code_lengths(&[0, 0], 15), [0, 0]);
        assert_eq!(code_lengths(&[1, 1], 15), [1, 1]);
    }
}
