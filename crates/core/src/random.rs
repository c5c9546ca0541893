//! The project's own derivation of random streams, so no dependency upgrade can move an output
//! byte (docs/src/reference/conventions.md, "Determinism and seeds"). Every random number rsasim draws comes
//! from here: the random draws of a scenario ([`stream`]) and the noise of every image row
//! (`noise::stream` names its keys and asks [`keyed_stream`] for the rows).
//!
//! A stream is named by a label string; its 32-byte ChaCha key is the SHA-256 of the label's
//! UTF-8 bytes ([`key`]), and the generator is ChaCha8 (`rand_chacha` 0.10, a fixed cipher) from
//! that key, on stream 0 or on a numbered stream. A uniform double in [0, 1) is
//! `(next_u64() >> 11) · 2⁻⁵³`.

use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use sha2::{Digest, Sha256};

/// The 32-byte ChaCha key of the streams named `label`: SHA-256 of its UTF-8 bytes.
pub fn key(label: &str) -> [u8; 32] {
    Sha256::digest(label.as_bytes()).into()
}

/// The ChaCha8 generator whose key is SHA-256(`label`), on stream 0.
pub fn stream(label: &str) -> ChaCha8Rng {
    ChaCha8Rng::from_seed(key(label))
}

/// Stream `id` of the ChaCha8 generator keyed `key`: `ChaCha8Rng::from_seed(key)` then
/// `set_stream(id)`, at the start of the stream.
pub fn keyed_stream(key: [u8; 32], id: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::from_seed(key);
    rng.set_stream(id);
    rng
}

/// A uniform double in [0, 1): the top 53 bits of the next 64-bit output,
/// `(next_u64() >> 11) · 2⁻⁵³` (exact in binary64).
#[inline]
pub fn uniform01(rng: &mut impl Rng) -> f64 {
    const SCALE: f64 = 1.0 / (1u64 << 53) as f64;
    (rng.next_u64() >> 11) as f64 * SCALE
}

/// A uniform double in [−half_width, +half_width).
pub fn symmetric(rng: &mut ChaCha8Rng, half_width: f64) -> f64 {
    (2.0 * uniform01(rng) - 1.0) * half_width
}

/// Standard normal samples by Box–Muller over the stream of `label` (for tests, here and in the
/// crates above).
#[doc(hidden)]
pub fn gaussians(label: &str, n: usize) -> Vec<f64> {
    let mut rng = stream(label);
    (0..n)
        .map(|_| {
            let u1 = 1.0 - uniform01(&mut rng);
            let u2 = uniform01(&mut rng);
            libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(std::f64::consts::TAU * u2)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_fixed_by_their_label() {
        let a: Vec<f64> = (0..4)
            .map({
                let mut r = stream("x");
                move |_| uniform01(&mut r)
            })
            .collect();
        let mut r = stream("x");
        assert!(a.iter().all(|&v| v == uniform01(&mut r)));
        assert!((0..1000).all(|_| (0.0..1.0).contains(&uniform01(&mut r))));
        assert_ne!(uniform01(&mut stream("y")), a[0]);
    }
}
