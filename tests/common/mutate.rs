//! A seeded mutator of input files for the mutation tests (`tests/mutation.rs`) and the longer
//! fuzzing driver (`examples/fuzz_inputs.rs`): the same seed gives the same mutant on any machine,
//! so every failure it finds is reproduced by its seed alone.
//!
//! Mutations are chosen to reach the places where parsers and checks go wrong: numbers replaced by
//! extremes (NaN, ±inf, 1e308, huge counts), strings replaced by hostile ones (paths out of the
//! folder, devices, reserved names, very long ids), structure broken (a line deleted, duplicated,
//! swapped; the file cut short), single bits flipped and bytes overwritten in binary files.
#![allow(dead_code)]

/// A small deterministic generator (SplitMix64): enough to drive mutations reproducibly, and
/// independent of any crate's stream so a dependency upgrade cannot change a test's mutants.
pub struct Rng(u64);

impl Rng {
    /// The generator for `seed`.
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x5851_f42d_4c95_7f2d)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A uniform index in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// One element of `items`.
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Numbers that break naive code: non-finite, overflowing, negative, zero, huge counts.
pub const HOSTILE_NUMBERS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-320",
    "0",
    "-0.0",
    "-1",
    "3.5",
    "65535",
    "65536",
    "1000000000",
    "4294967296",
    "18446744073709551616",
    "1e40",
];

/// Strings that break naive code: paths out of the folder, devices, reserved and over-long names,
/// separators, control and bidi characters, a BOM.
pub fn hostile_strings() -> Vec<String> {
    vec![
        String::new(),
        " ".into(),
        "../../../../etc/passwd".into(),
        "/etc/passwd".into(),
        "%2e%2e/%2e%2e/etc/passwd".into(),
        "/dev/zero".into(),
        "/proc/self/environ".into(),
        "a/b".into(),
        "a\\b".into(),
        "CON".into(),
        "x.".into(),
        "x".repeat(300),
        "y".repeat(5000),
        "\u{202e}evil".into(),
        "\u{feff}bom".into(),
        "tab\there".into(),
    ]
}

/// Tokens inserted anywhere in a text file.
const INSERTIONS: &[&str] = &[
    "\"", "[", "]", "{", "}", ",", "=", "\n", "#", "\u{feff}", "\0", "\\", "-", ".", "e", "[[",
];

/// One mutant of a text file (TOML, JSON, CSV, glTF): 1 to 3 mutations.
pub fn mutate_text(text: &str, rng: &mut Rng) -> String {
    let mut t = text.to_string();
    for _ in 0..1 + rng.below(3) {
        t = match rng.below(8) {
            0 => replace_nth_number(&t, rng),
            1 => replace_nth_string(&t, rng),
            2 => edit_lines(&t, rng, LineEdit::Delete),
            3 => edit_lines(&t, rng, LineEdit::Duplicate),
            4 => edit_lines(&t, rng, LineEdit::Swap),
            5 => {
                let at = char_boundary(&t, rng.below(t.len() + 1));
                t[..at].to_string()
            }
            6 => {
                let at = char_boundary(&t, rng.below(t.len() + 1));
                format!("{}{}{}", &t[..at], rng.pick(INSERTIONS), &t[at..])
            }
            _ => replace_nth_number(&t, rng),
        };
    }
    t
}

/// One mutant of a binary file (STL, GLB): bit flips, overwritten words (with NaN, ±inf, 1e38,
/// huge counts), cuts and extensions.
pub fn mutate_bytes(bytes: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for _ in 0..1 + rng.below(3) {
        if b.is_empty() {
            b.push(0);
        }
        match rng.below(5) {
            0 => {
                let i = rng.below(b.len());
                b[i] ^= 1 << rng.below(8);
            }
            1 | 2 => {
                let words: [[u8; 4]; 8] = [
                    f32::NAN.to_le_bytes(),
                    f32::INFINITY.to_le_bytes(),
                    f32::NEG_INFINITY.to_le_bytes(),
                    1e38f32.to_le_bytes(),
                    (-1e38f32).to_le_bytes(),
                    u32::MAX.to_le_bytes(),
                    0x8000_0000u32.to_le_bytes(),
                    0u32.to_le_bytes(),
                ];
                let w = rng.pick(&words);
                // Aligned words hit the fields of both STL (floats after an 84-byte header) and GLB.
                let i = (rng.below(b.len()) / 4) * 4;
                for (k, byte) in w.iter().enumerate() {
                    if let Some(slot) = b.get_mut(i + k) {
                        *slot = *byte;
                    }
                }
            }
            3 => {
                let cut = rng.below(b.len());
                b.truncate(cut);
            }
            _ => {
                let extra = 1 + rng.below(64);
                b.extend((0..extra).map(|_| rng.next_u64() as u8));
            }
        }
    }
    b
}

enum LineEdit {
    Delete,
    Duplicate,
    Swap,
}

fn edit_lines(t: &str, rng: &mut Rng, edit: LineEdit) -> String {
    let mut lines: Vec<&str> = t.split('\n').collect();
    if lines.is_empty() {
        return t.to_string();
    }
    let i = rng.below(lines.len());
    match edit {
        LineEdit::Delete => {
            lines.remove(i);
        }
        LineEdit::Duplicate => lines.insert(i, lines[i]),
        LineEdit::Swap => {
            let j = rng.below(lines.len());
            lines.swap(i, j);
        }
    }
    lines.join("\n")
}

/// Byte ranges of the numbers in `t` (an optional sign, digits, a fraction, an exponent).
fn number_spans(t: &str) -> Vec<(usize, usize)> {
    let b = t.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts =
            b[i].is_ascii_digit() || (b[i] == b'-' && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        let inside_word = i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
        if starts && !inside_word {
            let s = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit()
                    || matches!(b[i], b'.' | b'e' | b'E' | b'+' | b'-' | b'_'))
            {
                i += 1;
            }
            spans.push((s, i));
        } else {
            i += 1;
        }
    }
    spans
}

/// Byte ranges of the contents of the double-quoted strings in `t`.
fn string_spans(t: &str) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut open = None;
    let mut escaped = false;
    for (i, c) in t.char_indices() {
        match (c, open) {
            ('\\', Some(_)) if !escaped => {
                escaped = true;
                continue;
            }
            ('"', None) => open = Some(i + 1),
            ('"', Some(s)) if !escaped => {
                spans.push((s, i));
                open = None;
            }
            ('\n', Some(_)) => open = None,
            _ => {}
        }
        escaped = false;
    }
    spans
}

fn replace_nth_number(t: &str, rng: &mut Rng) -> String {
    let spans = number_spans(t);
    if spans.is_empty() {
        return t.to_string();
    }
    let (s, e) = *rng.pick(&spans);
    format!("{}{}{}", &t[..s], rng.pick(HOSTILE_NUMBERS), &t[e..])
}

fn replace_nth_string(t: &str, rng: &mut Rng) -> String {
    let spans = string_spans(t);
    if spans.is_empty() {
        return t.to_string();
    }
    let (s, e) = *rng.pick(&spans);
    let strings = hostile_strings();
    let with = rng
        .pick(&strings)
        .replace('\\', "\\\\")
        .replace('"', "\\\"");
    format!("{}{}{}", &t[..s], with, &t[e..])
}

fn char_boundary(t: &str, mut i: usize) -> usize {
    while !t.is_char_boundary(i) {
        i -= 1;
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_mutant() {
        let text = "a = [1.0, 2, -3e4]\nname = \"x\"\n";
        for seed in 0..50 {
            assert_eq!(
                mutate_text(text, &mut Rng::new(seed)),
                mutate_text(text, &mut Rng::new(seed))
            );
        }
    }

    #[test]
    fn numbers_and_strings_are_found() {
        let text = "a = [1.0, 2, -3e4]\nid_2 = \"x\\\"y\"\n";
        let numbers: Vec<&str> = number_spans(text)
            .iter()
            .map(|&(s, e)| &text[s..e])
            .collect();
        assert_eq!(numbers, ["1.0", "2", "-3e4"]);
        let strings: Vec<&str> = string_spans(text)
            .iter()
            .map(|&(s, e)| &text[s..e])
            .collect();
        assert_eq!(strings, ["x\\\"y"]);
    }
}
