//! Noise stream derivation: which random numbers feed which image row.
//!
//! This is the project's own, documented derivation (docs/src/reference/conventions.md, "Determinism and seeds"). A reviewer can
//! reproduce every random number of every image with a SHA-256 and a ChaCha8 implementation in
//! any language:
//!
//! 1. **Key.** Build the string
//!    `rsasim/noise/v1/{seed}/{level}/{run}/{exposure}/{detector}` where `{seed}` is the scenario
//!    seed (`u64`), `{level}` the zero-based noise-level index (`u32`) and `{run}` the zero-based
//!    run index (`u32`), all three in plain decimal without sign, padding or separators, and
//!    `{exposure}` / `{detector}` the exposure and detector ids verbatim. Example:
//!    `rsasim/noise/v1/42/2/7/ap/det_a`. The key is SHA-256 of the UTF-8 bytes of that string
//!    (32 bytes, no trailing newline or NUL). Ids should not contain `/`, otherwise two different
//!    (exposure, detector) pairs could spell the same string; the scenario loader is expected to
//!    reject such ids.
//! 2. **Row stream.** Image row `j` (row 0 is the first row stored in the file) gets its own fresh
//!    ChaCha8 generator: the original (Bernstein) ChaCha block function with 8 rounds, 16 words of
//!    state: the constants `"expand 32-byte k"` (words 0–3), the 32 key bytes read as eight
//!    little-endian `u32` (words 4–11), a 64-bit block counter starting at 0 (word 12 = low half,
//!    word 13 = high half) and the 64-bit stream id `j` (word 14 = low half, word 15 = high half).
//!    This is `rand_chacha::ChaCha8Rng::from_seed(key)` followed by `set_stream(j)`.
//! 3. **Words.** The generator emits the 16 output words of block 0, then of block 1, and so on.
//!    A `u64` takes two consecutive words, the first as the low half:
//!    `u64 = w[2i] | (w[2i+1] << 32)`. The noise code only ever draws `u64`s.
//! 4. **Uniform doubles.** [`uniform`] maps one `u64` `x` to `(x >> 11) · 2⁻⁵³`, a multiple of
//!    2⁻⁵³ in `[0, 1)` (exact in binary64).
//!
//! Steps 1 to 4 are the recipe of every random stream of rsasim ([`crate::random`]: the key,
//! [`crate::random::keyed_stream`], [`crate::random::uniform01`]); this module names the noise's
//! keys.
//!
//! The electronic (read-out) noise of attenuation mode has its own keys, made the same way from
//! the label `rsasim/electronic/v1/{seed}/{level}/{run}/{exposure}/{detector}`
//! ([`NoiseKey::derive_electronic`]), with the same row streams; how its uniforms become normal
//! samples is in [`super::normal`].
//!
//! Because every row has its own generator, the output does not depend on the number of threads
//! or on the order in which rows are processed. How the uniforms become Poisson counts is in
//! [`super::poisson`]; which pixel takes which sample is in [`super`].

use rand_chacha::ChaCha8Rng;

use crate::random;
/// One uniform double in `[0, 1)` from one `u64`: `(next_u64() >> 11) as f64 · 2⁻⁵³`.
pub use crate::random::uniform01 as uniform;

/// The 32-byte ChaCha key of one noisy image (one scenario seed, noise level, run, exposure and
/// detector). See the module documentation for the exact derivation.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct NoiseKey([u8; 32]);

impl NoiseKey {
    /// Derives the key as SHA-256 of
    /// `format!("rsasim/noise/v1/{scenario_seed}/{noise_level_index}/{run_index}/{exposure_id}/{detector_id}")`.
    /// In frame `k` of a sequence, `exposure_id` is the exposure's id followed by `/f<k>`
    /// (`crate::expand::Run::noise_exposure`).
    pub fn derive(
        scenario_seed: u64,
        noise_level_index: u32,
        run_index: u32,
        exposure_id: &str,
        detector_id: &str,
    ) -> NoiseKey {
        NoiseKey::of_label(&format!(
            "rsasim/noise/v1/{scenario_seed}/{noise_level_index}/{run_index}/{exposure_id}/{detector_id}"
        ))
    }

    /// The key of one image's electronic (read-out) noise, a stream family of its own beside
    /// the quantum noise of [`NoiseKey::derive`]: SHA-256 of
    /// `format!("rsasim/electronic/v1/{scenario_seed}/{noise_level_index}/{run_index}/{exposure_id}/{detector_id}")`,
    /// the fields as in [`NoiseKey::derive`]. Row `j` draws from [`NoiseKey::row_rng`]`(j)` of
    /// this key, the same ChaCha8 derivation (module documentation).
    pub fn derive_electronic(
        scenario_seed: u64,
        noise_level_index: u32,
        run_index: u32,
        exposure_id: &str,
        detector_id: &str,
    ) -> NoiseKey {
        NoiseKey::of_label(&format!(
            "rsasim/electronic/v1/{scenario_seed}/{noise_level_index}/{run_index}/{exposure_id}/{detector_id}"
        ))
    }

    /// SHA-256 of the UTF-8 bytes of `label`.
    fn of_label(label: &str) -> NoiseKey {
        NoiseKey(random::key(label))
    }

    /// Wraps raw key bytes (for tests and for tools that replay a recorded key).
    pub fn from_bytes(bytes: [u8; 32]) -> NoiseKey {
        NoiseKey(bytes)
    }

    /// The raw 32 key bytes.
    pub fn as_bytes(&self) -> &[u8; 32] {
        &self.0
    }

    /// The key as 64 lowercase hexadecimal digits (suitable for manifests and logs).
    pub fn to_hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }

    /// A fresh generator for image row `row`: `ChaCha8Rng::from_seed(key)` then
    /// `set_stream(row)`, positioned at the start of the stream.
    pub fn row_rng(&self, row: u32) -> ChaCha8Rng {
        random::keyed_stream(self.0, u64::from(row))
    }
}

impl std::fmt::Debug for NoiseKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "NoiseKey({})", self.to_hex())
    }
}

/// A test generator that returns the same `u64` every time (for checking [`uniform`]'s edges).
#[cfg(test)]
pub(crate) struct FixedRng(pub u64);

#[cfg(test)]
impl rand_core::TryRng for FixedRng {
    type Error = core::convert::Infallible;
    fn try_next_u32(&mut self) -> Result<u32, Self::Error> {
        Ok(self.0 as u32)
    }
    fn try_next_u64(&mut self) -> Result<u64, Self::Error> {
        Ok(self.0)
    }
    fn try_fill_bytes(&mut self, _: &mut [u8]) -> Result<(), Self::Error> {
        unimplemented!("FixedRng gives whole u64s only")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::Rng;
    use sha2::{Digest, Sha256};

    /// Independent scalar ChaCha8 block function (RFC 7539 quarter round, 8 rounds, 64-bit
    /// counter and 64-bit nonce), used to check the documented derivation against rand_chacha.
    fn chacha8_block(key: &[u8; 32], counter: u64, nonce: u64) -> [u32; 16] {
        let mut s = [0u32; 16];
        s[..4].copy_from_slice(&[0x6170_7865, 0x3320_646e, 0x7962_2d32, 0x6b20_6574]);
        for i in 0..8 {
            s[4 + i] = u32::from_le_bytes(key[4 * i..4 * i + 4].try_into().unwrap());
        }
        s[12] = counter as u32;
        s[13] = (counter >> 32) as u32;
        s[14] = nonce as u32;
        s[15] = (nonce >> 32) as u32;
        let mut x = s;
        fn qr(x: &mut [u32; 16], a: usize, b: usize, c: usize, d: usize) {
            x[a] = x[a].wrapping_add(x[b]);
            x[d] = (x[d] ^ x[a]).rotate_left(16);
            x[c] = x[c].wrapping_add(x[d]);
            x[b] = (x[b] ^ x[c]).rotate_left(12);
            x[a] = x[a].wrapping_add(x[b]);
            x[d] = (x[d] ^ x[a]).rotate_left(8);
            x[c] = x[c].wrapping_add(x[d]);
            x[b] = (x[b] ^ x[c]).rotate_left(7);
        }
        for _ in 0..4 {
            qr(&mut x, 0, 4, 8, 12);
            qr(&mut x, 1, 5, 9, 13);
            qr(&mut x, 2, 6, 10, 14);
            qr(&mut x, 3, 7, 11, 15);
            qr(&mut x, 0, 5, 10, 15);
            qr(&mut x, 1, 6, 11, 12);
            qr(&mut x, 2, 7, 8, 13);
            qr(&mut x, 3, 4, 9, 14);
        }
        for i in 0..16 {
            x[i] = x[i].wrapping_add(s[i]);
        }
        x
    }

    #[test]
    fn key_is_sha256_of_documented_label() {
        // Independently computed: printf 'rsasim/noise/v1/42/2/7/ap/det_a' | sha256sum
        let key = NoiseKey::derive(42, 2, 7, "ap", "det_a");
        assert_eq!(key.to_hex(), EXPECTED_KEY_HEX);
        assert_ne!(key, NoiseKey::derive(42, 2, 8, "ap", "det_a"));
        assert_ne!(key, NoiseKey::derive(43, 2, 7, "ap", "det_a"));
        assert_ne!(key, NoiseKey::derive(42, 1, 7, "ap", "det_a"));
        assert_ne!(key, NoiseKey::derive(42, 2, 7, "lat", "det_a"));
        assert_ne!(key, NoiseKey::derive(42, 2, 7, "ap", "det_b"));
    }

    #[test]
    fn electronic_key_is_sha256_of_its_own_label() {
        let key = NoiseKey::derive_electronic(42, 2, 7, "ap", "det_a");
        let want: [u8; 32] = Sha256::digest(b"rsasim/electronic/v1/42/2/7/ap/det_a").into();
        assert_eq!(key.as_bytes(), &want);
        assert_ne!(key, NoiseKey::derive(42, 2, 7, "ap", "det_a"));
        assert_ne!(key, NoiseKey::derive_electronic(42, 2, 8, "ap", "det_a"));
    }

    const EXPECTED_KEY_HEX: &str =
        "cf97ee1b7535e32afe1cfc6fe628cbf83d921ce19e8008ede09335a00e065658";

    #[test]
    fn row_rng_matches_reference_chacha8() {
        let key = NoiseKey::derive(42, 2, 7, "ap", "det_a");
        for row in [0u32, 1, 1439, u32::MAX] {
            let mut rng = key.row_rng(row);
            // 200 u64 = 400 words = 25 blocks: crosses rand_chacha's 4-block buffer several times.
            let words: Vec<u32> = (0..25u64)
                .flat_map(|b| chacha8_block(key.as_bytes(), b, u64::from(row)))
                .collect();
            for i in 0..200 {
                let expected = u64::from(words[2 * i]) | (u64::from(words[2 * i + 1]) << 32);
                assert_eq!(rng.next_u64(), expected, "row {row}, u64 #{i}");
            }
        }
    }

    #[test]
    fn rows_are_fresh_and_distinct() {
        let key = NoiseKey::derive(1, 0, 0, "e", "d");
        let a: Vec<u64> = (0..4).map(|_| key.row_rng(3).next_u64()).collect();
        assert!(a.iter().all(|&v| v == a[0]), "a fresh generator per call");
        assert_ne!(key.row_rng(3).next_u64(), key.row_rng(4).next_u64());
    }

    #[test]
    fn uniform_is_53_bit_and_in_unit_interval() {
        assert_eq!(uniform(&mut FixedRng(0)), 0.0);
        assert_eq!(uniform(&mut FixedRng(u64::MAX)), 1.0 - 2f64.powi(-53));
        assert_eq!(uniform(&mut FixedRng(1 << 63)), 0.5);
        assert_eq!(uniform(&mut FixedRng((1 << 11) - 1)), 0.0);
        let mut rng = NoiseKey::derive(0, 0, 0, "", "").row_rng(0);
        let mean = (0..100_000).map(|_| uniform(&mut rng)).sum::<f64>() / 100_000.0;
        assert!((mean - 0.5).abs() < 5.0 * (1.0 / 12.0f64 / 100_000.0).sqrt());
    }
}
