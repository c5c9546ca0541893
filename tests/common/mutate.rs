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
    fn the_same_seed_gives_the_same_received_mutant() {
        let text =
            "{\n  \"files\": [\n    {\n      \"path\": \"a\",\n      \"bytes\": 3\n    }\n  ]\n}\n";
        let strings = received_strings(std::path::Path::new("/top"));
        for seed in 0..200 {
            assert_eq!(
                mutate_received_text(text, &mut Rng::new(seed), &strings),
                mutate_received_text(text, &mut Rng::new(seed), &strings)
            );
        }
    }

    #[test]
    fn a_duplicated_entry_still_parses() {
        let text = "{\n  \"files\": [\n    {\n      \"path\": \"a\"\n    }\n  ]\n}\n";
        let mut seen = std::collections::BTreeSet::new();
        for seed in 0..40 {
            let t = duplicate_block(text, &mut Rng::new(seed));
            let v: serde_json::Value = serde_json::from_str(&t).unwrap();
            seen.insert(v["files"].as_array().unwrap().len());
        }
        assert!(seen.contains(&2) && seen.iter().any(|&n| n > 2), "{seen:?}");
    }

    #[cfg(unix)]
    #[test]
    fn a_resealed_manifest_passes_rsasims_own_check() {
        let text = b"{\n  \"format\": \"x\",\n  \"manifest_sha256\": \"00\",\n  \"runs\": 1\n}\n";
        let sealed = received::reseal(text).unwrap();
        let (recorded, recomputed) = rsasim::output::manifest::self_hash(&sealed).unwrap();
        assert_eq!(recorded, recomputed);
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

// ------------------------------------------------------------------------------------------------
// Received folders: the files a sender controls (`truth.json`, `sweep.json`, `study.json`,
// manifests, measured files, shard folders) and the commands that read them. Shared by
// `tests/mutation.rs` (a small budget in every `cargo test`) and `examples/fuzz_inputs.rs` (the long
// run). The lists above are left as they are so that the existing tests keep their mutants.
// ------------------------------------------------------------------------------------------------

/// Numbers for received files: [`HOSTILE_NUMBERS`], then counts past every cap, widths just past
/// `f64`'s integers and `i64`, a value just past `u64`, and tiny and ordinary ones.
pub fn received_numbers() -> &'static [&'static str] {
    static NUMBERS: std::sync::OnceLock<Vec<&'static str>> = std::sync::OnceLock::new();
    NUMBERS.get_or_init(|| {
        let beyond = [
            "1e-300",
            "100000000000",
            "9007199254740993",
            "-9223372036854775809",
            "2",
            "1",
            "1e6",
            "0.000001",
        ];
        HOSTILE_NUMBERS.iter().chain(&beyond).copied().collect()
    })
}

/// Strings for received files: [`hostile_strings`], then paths out of the folder that land in the
/// mutant's own `victim/` folder (relative at every depth, and absolute under `top`), names of
/// other entries (duplicates), control characters, Windows forms and over-long names.
pub fn received_strings(top: &std::path::Path) -> Vec<String> {
    let abs = top.display().to_string();
    let mut v = hostile_strings();
    v.extend(
        [
            "..",
            ".",
            "../victim",
            "../../victim",
            "../../../victim",
            "../../../../victim",
            "../../../../../victim",
            "../../../../../../victim/escaped",
            "x/../../victim",
            "runs/../../victim",
            "n0-r00",
            "p00",
            "shard-0-of-2",
            "manifest.json",
            "truth.json",
            "a\0b",
            "line\nbreak",
            "\r",
            "\u{1b}[2J",
            "C:\\victim",
            "\\\\server\\share\\x",
            "~",
            "-rf",
            "nul",
            "aux.json",
        ]
        .map(String::from),
    );
    v.push(format!("{abs}/victim"));
    v.push(format!("{abs}/victim/abs"));
    v.push(format!("{abs}/victim/victim.txt"));
    v.push("é".repeat(200));
    v.push("x".repeat(255));
    v.push("x".repeat(256));
    v
}

/// One mutant of a received text file (JSON, TOML, CSV): 1 to 3 mutations, weighted towards values
/// (numbers and strings, JSON-escaped so that the file still parses and the value reaches the
/// checks), duplicated entries and copied ids, then broken structure.
pub fn mutate_received_text(text: &str, rng: &mut Rng, strings: &[String]) -> String {
    let mut t = text.to_string();
    for _ in 0..1 + rng.below(3) {
        t = match rng.below(12) {
            0 | 1 | 11 => replace_number_from(&t, rng, received_numbers()),
            2..=4 => replace_string_from(&t, rng, strings),
            5 => copy_string(&t, rng),
            6 => duplicate_block(&t, rng),
            7 => replace_csv_field(&t, rng, strings),
            8 => {
                let edit = match rng.below(3) {
                    0 => LineEdit::Delete,
                    1 => LineEdit::Duplicate,
                    _ => LineEdit::Swap,
                };
                edit_lines(&t, rng, edit)
            }
            9 => {
                let at = char_boundary(&t, rng.below(t.len() + 1));
                t[..at].to_string()
            }
            _ => {
                let at = char_boundary(&t, rng.below(t.len() + 1));
                format!("{}{}{}", &t[..at], rng.pick(INSERTIONS), &t[at..])
            }
        };
    }
    t
}

fn replace_number_from(t: &str, rng: &mut Rng, numbers: &[&str]) -> String {
    let spans = number_spans(t);
    if spans.is_empty() {
        return t.to_string();
    }
    let (s, e) = *rng.pick(&spans);
    format!("{}{}{}", &t[..s], rng.pick(numbers), &t[e..])
}

/// A string's contents escaped for a JSON or TOML basic string.
fn escaped(s: &str) -> String {
    let quoted = serde_json::to_string(s).unwrap();
    quoted[1..quoted.len() - 1].to_string()
}

fn replace_string_from(t: &str, rng: &mut Rng, strings: &[String]) -> String {
    let spans = string_spans(t);
    if spans.is_empty() || strings.is_empty() {
        return t.to_string();
    }
    let (s, e) = *rng.pick(&spans);
    format!(
        "{}{}{}",
        &t[..s],
        escaped(rng.pick(strings).as_str()),
        &t[e..]
    )
}

/// One string's contents copied over another's: two runs, points or files with one id.
fn copy_string(t: &str, rng: &mut Rng) -> String {
    let spans = string_spans(t);
    if spans.len() < 2 {
        return t.to_string();
    }
    let from = *rng.pick(&spans);
    let (s, e) = *rng.pick(&spans);
    format!("{}{}{}", &t[..s], &t[from.0..from.1], &t[e..])
}

/// One entry given again, once or many times (up to about 20 MB in all, to reach the caps on
/// entries and any check that is quadratic in them): a pretty-printed JSON object or array that
/// stands alone on its lines (an element of an array), a TOML `[[table]]` up to the next header,
/// or else (CSV) one line.
fn duplicate_block(t: &str, rng: &mut Rng) -> String {
    let lines: Vec<&str> = t.split('\n').collect();
    let starts: Vec<usize> = (0..lines.len())
        .filter(|&i| {
            let l = lines[i].trim();
            let nested = lines[i].starts_with(' ');
            (nested && (l == "{" || l == "[")) || l.starts_with("[[")
        })
        .collect();
    let times = *rng.pick(&[1usize, 1, 1, 1, 50, 5000, 100_000]);
    let repeat = |block: Vec<String>| -> Vec<String> {
        let bytes: usize = block.iter().map(|l| l.len() + 1).sum::<usize>().max(1);
        let n = times.min((20 << 20) / bytes).max(1);
        let mut out = Vec::with_capacity(block.len() * n);
        for _ in 0..n {
            out.extend(block.iter().cloned());
        }
        out
    };
    if starts.is_empty() {
        let i = rng.below(lines.len());
        let mut out: Vec<String> = lines[..i].iter().map(|l| l.to_string()).collect();
        out.extend(repeat(vec![lines[i].to_string()]));
        out.extend(lines[i..].iter().map(|l| l.to_string()));
        return out.join("\n");
    }
    let i = *rng.pick(&starts);
    let indent = lines[i].len() - lines[i].trim_start().len();
    let mut block: Vec<String> = if lines[i].trim().starts_with("[[") {
        let end = (i + 1..lines.len())
            .find(|&j| lines[j].trim_start().starts_with('['))
            .unwrap_or(lines.len());
        lines[i..end].iter().map(|l| l.to_string()).collect()
    } else {
        let Some(end) = (i + 1..lines.len()).find(|&j| {
            let l = lines[j];
            l.len() - l.trim_start().len() == indent
                && (l.trim_start().starts_with('}') || l.trim_start().starts_with(']'))
        }) else {
            return t.to_string();
        };
        let mut b: Vec<String> = lines[i..=end].iter().map(|l| l.to_string()).collect();
        let last = b.last_mut().unwrap();
        if !last.trim_end().ends_with(',') {
            last.push(',');
        }
        b
    };
    let mut out: Vec<String> = lines[..i].iter().map(|l| l.to_string()).collect();
    out.extend(repeat(std::mem::take(&mut block)));
    out.extend(lines[i..].iter().map(|l| l.to_string()));
    out.join("\n")
}

/// One comma-separated field of one line replaced by a hostile string or number, unescaped.
fn replace_csv_field(t: &str, rng: &mut Rng, strings: &[String]) -> String {
    let mut lines: Vec<String> = t.split('\n').map(String::from).collect();
    if lines.is_empty() {
        return t.to_string();
    }
    let i = rng.below(lines.len());
    let mut fields: Vec<String> = lines[i].split(',').map(String::from).collect();
    let k = rng.below(fields.len());
    fields[k] = if rng.below(2) == 0 || strings.is_empty() {
        rng.pick(received_numbers()).to_string()
    } else {
        rng.pick(strings).clone()
    };
    lines[i] = fields.join(",");
    lines.join("\n")
}

/// The harness that mutates received folders and runs the commands that read them.
#[cfg(unix)]
pub mod received {
    use super::{Rng, mutate_bytes, mutate_received_text, received_strings};

    use std::collections::{BTreeMap, BTreeSet};
    use std::io::Read;
    use std::path::{Path, PathBuf};
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};

    use sha2::{Digest, Sha256};

    /// A group of files a mutant may change: name, weight, test on the path.
    type Group = (&'static str, u32, fn(&str) -> bool);

    /// A command that reads a received folder, with the folder it reads.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
    pub enum Kind {
        /// `export out --to xmalab --dir dest [--calibration-from measured.json]`
        ExportXmalab,
        /// `export out --to autoscoper --dir dest [--calibration-from measured.json]`
        ExportAutoscoper,
        /// `evaluate out --measured measured.json --report rep`
        Evaluate,
        /// `evaluate study --migration-csv migration.csv --report rep` (a clinical study)
        EvaluateStudy,
        /// `reconstruct out` (a scenario the reference program reconstructs)
        Reconstruct,
        /// `verify out`
        Verify,
        /// `merge shards/shard-0-of-2 shards/shard-1-of-2 --out merged [--copy]`
        Merge,
        /// `sweep sweep.toml --out S --merge` (a sweep written by two `--shard` tasks)
        SweepMerge,
        /// `evaluate S --measured measured.json --report rep` (a sweep folder)
        EvaluateSweep,
        /// `reconstruct S` (a sweep folder)
        ReconstructSweep,
    }

    impl Kind {
        pub const ALL: [Kind; 10] = [
            Kind::ExportXmalab,
            Kind::ExportAutoscoper,
            Kind::Evaluate,
            Kind::EvaluateStudy,
            Kind::Reconstruct,
            Kind::Verify,
            Kind::Merge,
            Kind::SweepMerge,
            Kind::EvaluateSweep,
            Kind::ReconstructSweep,
        ];

        pub fn name(self) -> &'static str {
            match self {
                Kind::ExportXmalab => "export-xmalab",
                Kind::ExportAutoscoper => "export-autoscoper",
                Kind::Evaluate => "evaluate",
                Kind::EvaluateStudy => "evaluate-study",
                Kind::Reconstruct => "reconstruct",
                Kind::Verify => "verify",
                Kind::Merge => "merge",
                Kind::SweepMerge => "sweep-merge",
                Kind::EvaluateSweep => "evaluate-sweep",
                Kind::ReconstructSweep => "reconstruct-sweep",
            }
        }

        pub fn from_name(name: &str) -> Option<Kind> {
            Kind::ALL.into_iter().find(|k| k.name() == name)
        }

        /// The received folder this command reads.
        pub fn fixture(self) -> FixtureKind {
            match self {
                Kind::ExportXmalab | Kind::ExportAutoscoper | Kind::Evaluate | Kind::Verify => {
                    FixtureKind::Scored
                }
                Kind::EvaluateStudy => FixtureKind::Study,
                Kind::Reconstruct => FixtureKind::Reconstructable,
                Kind::Merge => FixtureKind::Shards,
                Kind::SweepMerge => FixtureKind::SweepShards,
                Kind::EvaluateSweep => FixtureKind::SweepScored,
                Kind::ReconstructSweep => FixtureKind::SweepReconstructable,
            }
        }

        /// The files a mutant may change: (group, weight, test on the path relative to `work/`);
        /// a group whose name starts with `folder` chooses among folders instead.
        fn groups(self) -> Vec<Group> {
            fn truth(p: &str) -> bool {
                p.ends_with("/truth.json")
            }
            fn measured(p: &str) -> bool {
                p.ends_with("/measured.json")
            }
            fn image(p: &str) -> bool {
                p.ends_with(".tiff") || p.ends_with(".exr")
            }
            // Folder groups (their names start with `folder`) choose among the fixture's folders.
            fn run_or_phantoms(p: &str) -> bool {
                p.starts_with("out/runs/") || p == "out/phantoms"
            }
            fn point_or_run(p: &str) -> bool {
                let parts: Vec<&str> = p.split('/').collect();
                parts.len() >= 2
                    && parts[0] == "S"
                    && parts[1].starts_with('p')
                    && parts[1] != "points"
                    && (parts.len() == 2 || (parts.len() == 4 && parts[2] == "runs"))
            }
            match self {
                Kind::ExportXmalab | Kind::ExportAutoscoper => vec![
                    ("folder: run or phantoms", 8, run_or_phantoms),
                    ("truth.json", 35, truth),
                    ("manifest.json", 25, |p| p == "out/manifest.json"),
                    ("measured.json", 20, measured),
                    ("other", 20, |p| {
                        p.starts_with("out/")
                            && !truth(p)
                            && !measured(p)
                            && p != "out/manifest.json"
                    }),
                ],
                Kind::Evaluate => vec![
                    ("folder: run or phantoms", 8, run_or_phantoms),
                    ("truth.json", 30, truth),
                    ("measured.json", 35, measured),
                    ("manifest.json", 20, |p| p == "out/manifest.json"),
                    ("other", 15, |p| {
                        p == "out/scenario.toml" || p.starts_with("out/phantoms/")
                    }),
                ],
                Kind::EvaluateStudy => vec![
                    ("folder: run", 6, |p| p.starts_with("study/runs/")),
                    ("study.json", 45, |p| p == "study/study.json"),
                    ("migration.csv", 25, |p| p == "migration.csv"),
                    ("manifest.json", 15, |p| p == "study/manifest.json"),
                    ("other", 15, |p| truth(p) || p == "study/scenario.toml"),
                ],
                Kind::Reconstruct => vec![
                    ("folder: run or phantoms", 8, run_or_phantoms),
                    ("scenario.toml", 20, |p| p == "out/scenario.toml"),
                    ("phantoms", 25, |p| p.starts_with("out/phantoms/")),
                    ("image", 25, image),
                    ("manifest.json", 15, |p| p == "out/manifest.json"),
                    ("truth.json", 15, truth),
                ],
                Kind::Verify => vec![
                    ("folder: run or phantoms", 8, run_or_phantoms),
                    ("manifest.json", 70, |p| p == "out/manifest.json"),
                    ("other", 30, |p| {
                        p.starts_with("out/") && p != "out/manifest.json"
                    }),
                ],
                Kind::Merge => vec![
                    ("folder: shard or run", 8, |p| p.starts_with("shards/")),
                    ("manifest.json", 45, |p| {
                        p.starts_with("shards/") && p.ends_with("/manifest.json")
                    }),
                    ("truth.json", 20, truth),
                    ("scenario.toml", 10, |p| p.ends_with("/scenario.toml")),
                    ("other", 25, |p| {
                        p.starts_with("shards/")
                            && !p.ends_with("/manifest.json")
                            && !truth(p)
                            && !p.ends_with("/scenario.toml")
                    }),
                ],
                Kind::SweepMerge => vec![
                    ("folder: point's shards, shard or points", 8, |p| {
                        p.starts_with("S/shards/") && p.matches('/').count() <= 3 || p == "S/points"
                    }),
                    ("sweep file", 4, |p| p == "sweep.toml"),
                    ("sweep.json", 35, |p| p == "S/sweep.json"),
                    ("shard manifest.json", 35, |p| {
                        p.starts_with("S/shards/") && p.ends_with("/manifest.json")
                    }),
                    ("points/*.toml", 10, |p| {
                        p.starts_with("S/points/") && p.ends_with(".toml")
                    }),
                    ("other", 20, |p| {
                        (p.starts_with("S/shards/") && !p.ends_with("/manifest.json"))
                            || p.starts_with("S/points/inputs/")
                            || p == "S/sweep.toml"
                    }),
                ],
                Kind::EvaluateSweep => vec![
                    ("folder: point or run", 8, point_or_run),
                    ("sweep.json", 50, |p| p == "S/sweep.json"),
                    ("point manifest.json", 20, |p| {
                        p.starts_with("S/p") && p.ends_with("/manifest.json")
                    }),
                    ("truth or measured", 20, |p| truth(p) || measured(p)),
                    ("other", 10, |p| {
                        p.starts_with("S/points/") || p.ends_with("/scenario.toml")
                    }),
                ],
                Kind::ReconstructSweep => vec![
                    ("folder: point or run", 8, point_or_run),
                    ("sweep.json", 50, |p| p == "S/sweep.json"),
                    ("point manifest.json", 15, |p| {
                        p.starts_with("S/p") && p.ends_with("/manifest.json")
                    }),
                    ("point scenario or phantoms", 20, |p| {
                        p.ends_with("/scenario.toml") || p.contains("/phantoms/")
                    }),
                    ("image", 15, image),
                ],
            }
        }

        /// The command line (relative to `work/`) for a mutant of group `group`.
        fn args(self, group: &str, rng: &mut Rng) -> Vec<String> {
            let v = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
            match self {
                Kind::ExportXmalab | Kind::ExportAutoscoper => {
                    let to = if self == Kind::ExportXmalab {
                        "xmalab"
                    } else {
                        "autoscoper"
                    };
                    let mut a = v(&["export", "out", "--to", to, "--dir", "dest"]);
                    if group == "measured.json" || rng.below(4) == 0 {
                        a.extend(v(&["--calibration-from", "measured.json"]));
                    }
                    a
                }
                Kind::Evaluate => v(&[
                    "evaluate",
                    "out",
                    "--measured",
                    "measured.json",
                    "--report",
                    "rep",
                ]),
                Kind::EvaluateStudy => v(&[
                    "evaluate",
                    "study",
                    "--migration-csv",
                    "migration.csv",
                    "--report",
                    "rep",
                ]),
                Kind::Reconstruct => v(&["reconstruct", "out"]),
                Kind::Verify => v(&["verify", "out"]),
                Kind::Merge => {
                    let mut a = v(&[
                        "merge",
                        "shards/shard-0-of-2",
                        "shards/shard-1-of-2",
                        "--out",
                        "merged",
                    ]);
                    if rng.below(2) == 0 {
                        a.push("--copy".into());
                    }
                    a
                }
                Kind::SweepMerge => v(&["sweep", "sweep.toml", "--out", "S", "--merge"]),
                Kind::EvaluateSweep => v(&[
                    "evaluate",
                    "S",
                    "--measured",
                    "measured.json",
                    "--report",
                    "rep",
                ]),
                Kind::ReconstructSweep => v(&["reconstruct", "S"]),
            }
        }

        /// Whether exit code 1 is an answer of this command (reconstruct: nothing could be
        /// reconstructed, or a run failed as a whole).
        fn may_exit_1(self) -> bool {
            matches!(self, Kind::Reconstruct | Kind::ReconstructSweep)
        }

        /// Whether a change at `path` (relative to `work/`) is one this command may make when it
        /// succeeds: inside the output the user named, or a lock file beside it.
        fn may_write(self, path: &str, change: Change) -> bool {
            let under = |dir: &str| path == dir || path.starts_with(&format!("{dir}/"));
            let lock_beside = |dir: &str| path == format!(".{dir}.rsasim-lock");
            let is_lock = path
                .rsplit('/')
                .next()
                .is_some_and(|n| n.starts_with('.') && n.ends_with(".rsasim-lock"));
            let results = |prefix_depth: usize| {
                // <out>/runs/<run>/measured-rsasim-*.json, or S/<point>/runs/<run>/… for sweeps.
                let parts: Vec<&str> = path.split('/').collect();
                parts.len() == 4 + prefix_depth
                    && parts[1 + prefix_depth] == "runs"
                    && parts[3 + prefix_depth].starts_with("measured-rsasim-")
                    && parts[3 + prefix_depth].ends_with(".json")
            };
            match self {
                Kind::ExportXmalab | Kind::ExportAutoscoper => under("dest") || lock_beside("dest"),
                Kind::Evaluate | Kind::EvaluateStudy => under("rep") || lock_beside("rep"),
                Kind::Verify => false,
                Kind::Merge => under("merged") || lock_beside("merged"),
                Kind::Reconstruct => {
                    change != Change::Removed
                        && ((path.starts_with("out/") && results(0)) || lock_beside("out"))
                }
                Kind::ReconstructSweep => {
                    change != Change::Removed
                        && ((path.starts_with("S/") && results(1))
                            || lock_beside("S")
                            || (under("S") && is_lock))
                }
                Kind::SweepMerge => {
                    (under("S") && (change == Change::Added || is_lock)) || lock_beside("S")
                }
                Kind::EvaluateSweep => {
                    (under("S") && (change == Change::Added || is_lock))
                        || lock_beside("S")
                        || under("rep")
                        || lock_beside("rep")
                }
            }
        }

        /// The output the user named, which must not exist after exit 2 (None: the command
        /// writes into the folder it reads, whose tree must then be unchanged).
        fn new_output(self) -> Option<&'static str> {
            match self {
                Kind::ExportXmalab | Kind::ExportAutoscoper => Some("dest"),
                Kind::Evaluate | Kind::EvaluateStudy | Kind::EvaluateSweep => Some("rep"),
                Kind::Merge => Some("merged"),
                Kind::Reconstruct | Kind::ReconstructSweep | Kind::SweepMerge | Kind::Verify => {
                    None
                }
            }
        }
    }

    /// The received folders, each built once and copied for every mutant.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
    pub enum FixtureKind {
        /// `out/`: `tests/mutation/base.toml` run (4 runs of 64 × 80 px), a perfect
        /// `measured.json` (the truth) in every run folder.
        Scored,
        /// `study/`: `tests/scenarios/study.toml` (3 patients × 5 exams) with LZW images, and
        /// `migration.csv`: the true migrations as the relative-motion CSV.
        Study,
        /// `out/`: `tests/scenarios/reconstruct_uniplanar.toml` cut to 2 runs of 586 × 720 px
        /// without noise, which the reference program reconstructs.
        Reconstructable,
        /// `shards/shard-0-of-2`, `shards/shard-1-of-2`: the base scenario in 2 shards.
        Shards,
        /// `S/` written by `sweep sweep.toml --shard K/2` (2 points of the base scenario), and
        /// the sweep's inputs `sweep.toml`, `base.toml`, `ball.stl` beside it.
        SweepShards,
        /// `S/`: that sweep unsharded, with a perfect `measured.json` in every run folder.
        SweepScored,
        /// `S/`: a sweep of the reconstructable scenario (1 and 2 runs).
        SweepReconstructable,
    }

    /// What one rsasim process did.
    #[derive(Debug, Clone)]
    pub struct Ran {
        pub code: Option<i32>,
        pub stdout: String,
        pub stderr: String,
        pub timed_out: bool,
        pub elapsed: Duration,
    }

    impl Ran {
        /// The first line that says `error`, else the first non-empty line of stderr.
        pub fn first_line(&self) -> String {
            let lines = || self.stderr.lines().map(str::trim).filter(|l| !l.is_empty());
            if let Some(at) = self.stderr.find("panicked at") {
                let panic: Vec<&str> = self.stderr[at..].lines().take(2).collect();
                return panic.join(" ").chars().take(300).collect();
            }
            lines()
                .find(|l| l.starts_with("error"))
                .or_else(|| lines().next())
                .unwrap_or("")
                .chars()
                .take(300)
                .collect()
        }
    }

    /// A mutant that broke the contract, with what is needed to replay it.
    #[derive(Debug, Clone)]
    pub struct Failure {
        pub kind: &'static str,
        pub seed: Option<u64>,
        /// The file mutated, relative to the mutant's `work/` folder.
        pub file: String,
        /// How it was mutated (content, rehashed; a FIFO; a link…).
        pub mutation: String,
        pub args: Vec<String>,
        pub code: Option<i32>,
        pub timed_out: bool,
        pub why: String,
        pub first_line: String,
        pub stderr: String,
        /// Where the mutant was kept, if it was.
        pub kept: Option<PathBuf>,
    }

    impl std::fmt::Display for Failure {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            let seed = self
                .seed
                .map_or("none (unmutated)".to_string(), |s| s.to_string());
            writeln!(
                f,
                "{} mutant seed {seed}: {} [{}]: {}; exit {}",
                self.kind,
                self.file,
                self.mutation,
                self.why,
                match self.code {
                    _ if self.timed_out => "none (killed: hung)".to_string(),
                    Some(c) => c.to_string(),
                    None => "none (a signal)".to_string(),
                }
            )?;
            writeln!(f, "  rsasim {}", self.args.join(" "))?;
            if let Some(k) = &self.kept {
                writeln!(f, "  kept in {}", k.display())?;
            }
            let mut s = self.stderr.as_str();
            if s.len() > 1500 {
                let mut i = 1500;
                while !s.is_char_boundary(i) {
                    i -= 1;
                }
                s = &s[..i];
            }
            write!(f, "{s}")
        }
    }

    /// A received folder built once: `root/work` is copied for every mutant.
    pub struct Fixture {
        pub kind: FixtureKind,
        _dir: tempfile::TempDir,
        work: PathBuf,
        /// Every regular file of `work/`, relative, sorted.
        files: Vec<String>,
        /// Every folder of `work/`, relative, sorted.
        dirs: Vec<String>,
        /// Names an error may give for a file of the folder: every file's and folder's name.
        names: BTreeSet<String>,
    }

    /// Runs the binary, killing it after the limit; as `nobody` when this process is root, so
    /// that a mutant cannot write to system files (every write it may make lands under the
    /// mutant's own folder, which is open to all).
    pub struct Harness {
        pub bin: PathBuf,
        pub limit: Duration,
        /// Keep at most this many failing mutants in `$TMPDIR/rsasim-mutant-<kind>-<seed>`.
        pub keep: usize,
        kept: std::sync::atomic::AtomicUsize,
        as_nobody: bool,
    }

    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Change {
        Added,
        Removed,
        Modified,
    }

    /// One entry of a folder tree: its type, and for a regular file its size, time and hash.
    #[derive(Clone, Debug, PartialEq, Eq)]
    enum Entry {
        Dir,
        File {
            len: u64,
            mtime: Option<std::time::SystemTime>,
            sha: Option<[u8; 32]>,
        },
        Link(PathBuf),
        Other(u32),
    }

    /// Every entry under `dir`, by path relative to it (links not followed; files over 64 MB not
    /// hashed).
    fn snapshot(dir: &Path) -> BTreeMap<String, Entry> {
        use std::os::unix::fs::FileTypeExt;
        let mut out = BTreeMap::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            let Ok(rd) = std::fs::read_dir(&d) else {
                continue;
            };
            for e in rd.flatten() {
                let p = e.path();
                let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                let Ok(m) = std::fs::symlink_metadata(&p) else {
                    continue;
                };
                let ft = m.file_type();
                let entry = if ft.is_dir() {
                    stack.push(p.clone());
                    Entry::Dir
                } else if ft.is_symlink() {
                    Entry::Link(std::fs::read_link(&p).unwrap_or_default())
                } else if ft.is_file() {
                    let sha = (m.len() <= 64 << 20)
                        .then(|| std::fs::read(&p).ok())
                        .flatten()
                        .map(|b| Sha256::digest(&b).into());
                    Entry::File {
                        len: m.len(),
                        mtime: m.modified().ok(),
                        sha,
                    }
                } else {
                    let t = if ft.is_fifo() {
                        1
                    } else if ft.is_socket() {
                        2
                    } else {
                        3
                    };
                    Entry::Other(t)
                };
                out.insert(rel, entry);
            }
        }
        out
    }

    fn diff(
        before: &BTreeMap<String, Entry>,
        after: &BTreeMap<String, Entry>,
    ) -> Vec<(String, Change)> {
        let mut v = Vec::new();
        for (p, e) in before {
            match after.get(p) {
                None => v.push((p.clone(), Change::Removed)),
                Some(a) if a != e && !(matches!(a, Entry::Dir) && matches!(e, Entry::Dir)) => {
                    v.push((p.clone(), Change::Modified))
                }
                _ => {}
            }
        }
        for p in after.keys() {
            if !before.contains_key(p) {
                v.push((p.clone(), Change::Added));
            }
        }
        v
    }

    fn copy_tree(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap() {
            let e = e.unwrap();
            let t = e.file_type().unwrap();
            let dest = to.join(e.file_name());
            if t.is_dir() {
                copy_tree(&e.path(), &dest);
            } else if t.is_file() {
                std::fs::copy(e.path(), &dest).unwrap();
            }
        }
    }

    /// Gives everything under `dir` (and `dir`) to `nobody`, links included: the receiver owns
    /// the copy it received (the mutants run as `nobody` when this process is root).
    fn give_to_nobody(dir: &Path) {
        let _ = std::os::unix::fs::lchown(dir, Some(NOBODY), Some(NOBODY));
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let t = e.file_type().unwrap();
            if t.is_dir() {
                give_to_nobody(&e.path());
            } else {
                let _ = std::os::unix::fs::lchown(e.path(), Some(NOBODY), Some(NOBODY));
            }
        }
    }

    /// The user and group id of `nobody`.
    const NOBODY: u32 = 65534;

    /// Whether `nobody` may execute `bin`: every folder above it searchable by others (the
    /// checkout's folders belong to root here) and the file executable by others. A checkout
    /// under `mktemp -d` (mode 0700) fails here rather than with a bare "permission denied" from
    /// every mutant.
    fn nobody_can_run(bin: &Path) -> Result<(), String> {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let mode = |p: &Path| {
            std::fs::metadata(p)
                .map(|m| (m.permissions().mode(), m.uid()))
                .map_err(|e| format!("{}: {e}", p.display()))
        };
        // The binary itself first, then every folder above it.
        for path in bin.ancestors().filter(|p| !p.as_os_str().is_empty()) {
            let (path_mode, owner) = mode(path)?;
            if owner != NOBODY && path_mode & 0o001 == 0 {
                return Err(format!(
                    "{} has mode {:o}",
                    path.display(),
                    path_mode & 0o7777
                ));
            }
        }
        Ok(())
    }

    /// Every regular file under `dir`, relative with `/`, sorted.
    fn files_under(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = snapshot(dir)
            .into_iter()
            .filter(|(_, e)| matches!(e, Entry::File { .. }))
            .map(|(p, _)| p)
            .collect();
        v.sort();
        v
    }

    fn remove_locks(dir: &Path) {
        for f in files_under(dir) {
            if f.ends_with(".rsasim-lock") {
                std::fs::remove_file(dir.join(f)).unwrap();
            }
        }
    }

    /// Writes one fixed build (commit zero, clean tree) into every manifest under `dir`, resealed,
    /// so that a seed gives the same mutant whichever commit built the binary (the mutations count
    /// the numbers and strings of a file, and a commit hash holds some of both).
    fn normalize_builds(dir: &Path) {
        for f in files_under(dir) {
            if !(f == "manifest.json" || f.ends_with("/manifest.json")) {
                continue;
            }
            let path = dir.join(&f);
            let mut text = std::fs::read_to_string(&path).unwrap();
            const KEY: &str = "\"commit\": \"";
            if let Some(at) = text.find(KEY) {
                let start = at + KEY.len();
                let end = start + text[start..].find('"').unwrap();
                text.replace_range(start..end, &"0".repeat(40));
            }
            let text = text.replace("\"dirty\": \"true\"", "\"dirty\": \"false\"");
            std::fs::write(&path, reseal(text.as_bytes()).unwrap()).unwrap();
        }
    }

    fn hex(b: &[u8]) -> String {
        b.iter().map(|x| format!("{x:02x}")).collect()
    }

    /// Refills `"manifest_sha256"` with the SHA-256 of the bytes with its value emptied, as
    /// `crates/files/src/output/manifest.rs` defines it (and as anyone can). None when the field is gone.
    pub fn reseal(bytes: &[u8]) -> Option<Vec<u8>> {
        const KEY: &[u8] = b"\"manifest_sha256\": \"";
        let start = bytes.windows(KEY.len()).position(|w| w == KEY)? + KEY.len();
        let len = bytes[start..].iter().position(|&b| b == b'"')?;
        let mut unsealed = bytes[..start].to_vec();
        unsealed.extend_from_slice(&bytes[start + len..]);
        let sha = hex(&Sha256::digest(&unsealed));
        let mut out = bytes[..start].to_vec();
        out.extend_from_slice(sha.as_bytes());
        out.extend_from_slice(&bytes[start + len..]);
        Some(out)
    }

    /// Does what a hostile sender does after changing `file` (a path under `work`): records its
    /// new SHA-256 and size in the manifest of the nearest folder that lists it and reseals that
    /// manifest (or reseals the manifest itself), and records a point scenario's or the sweep
    /// file's new hash in `sweep.json`. Returns what it rehashed.
    pub fn rehash(work: &Path, file: &Path) -> Option<String> {
        let bytes = std::fs::read(file).ok()?;
        if file.file_name()? == "manifest.json" {
            let sealed = reseal(&bytes)?;
            std::fs::write(file, sealed).ok()?;
            return Some("resealed".into());
        }
        let sha = hex(&Sha256::digest(&bytes));
        let mut dir = file.parent()?;
        while dir.starts_with(work) {
            let rel = file
                .strip_prefix(dir)
                .ok()?
                .to_string_lossy()
                .replace('\\', "/");
            let manifest = dir.join("manifest.json");
            if let Ok(text) = std::fs::read(&manifest)
                && let Ok(mut m) = serde_json::from_slice::<serde_json::Value>(&text)
                && let Some(files) = m.get_mut("files").and_then(|f| f.as_array_mut())
                && let Some(entry) = files.iter_mut().find(|f| f["path"] == rel.as_str())
            {
                entry["sha256"] = sha.into();
                entry["bytes"] = (bytes.len() as u64).into();
                let mut out = serde_json::to_vec_pretty(&m).ok()?;
                out.push(b'\n');
                std::fs::write(&manifest, reseal(&out)?).ok()?;
                return Some(format!("rehashed into {}", manifest.display()));
            }
            let index = dir.join("sweep.json");
            if let Ok(text) = std::fs::read(&index)
                && let Ok(mut s) = serde_json::from_slice::<serde_json::Value>(&text)
            {
                let mut done = false;
                if rel == "sweep.toml" {
                    s["sweep_sha256"] = sha.clone().into();
                    done = true;
                }
                if let Some(points) = s.get_mut("points").and_then(|p| p.as_array_mut()) {
                    for p in points.iter_mut().filter(|p| p["scenario"] == rel.as_str()) {
                        p["scenario_sha256"] = sha.clone().into();
                        done = true;
                    }
                }
                if done {
                    let mut out = serde_json::to_vec_pretty(&s).ok()?;
                    out.push(b'\n');
                    std::fs::write(&index, out).ok()?;
                    return Some("rehashed into sweep.json".into());
                }
            }
            dir = dir.parent()?;
        }
        None
    }

    /// Exact results as a software would write them: the truth's poses (`truth` as JSON).
    pub fn perfect_measured(truth: &serde_json::Value) -> serde_json::Value {
        let pose = |v: &serde_json::Value| serde_json::json!({"id": v["id"], "position_mm": v["position_mm"], "rotation": v["rotation"]});
        let list = |key: &str| truth[key].as_array().cloned().unwrap_or_default();
        serde_json::json!({
            "format": "rsasim-measured/1",
            "run": truth["id"],
            "software": "Perfect 1.0",
            "sources": list("sources").iter()
                .map(|s| serde_json::json!({"id": s["id"], "position_mm": s["position_mm"]}))
                .collect::<Vec<_>>(),
            "detectors": list("detectors").iter().map(pose).collect::<Vec<_>>(),
            "phantoms": list("phantoms").iter().map(pose).collect::<Vec<_>>(),
        })
    }

    /// Writes a perfect `measured.json` beside every `truth.json` under `dir`.
    fn write_perfect_results(dir: &Path) {
        for f in files_under(dir) {
            if f.ends_with("/truth.json") || f == "truth.json" {
                let truth: serde_json::Value =
                    serde_json::from_slice(&std::fs::read(dir.join(&f)).unwrap()).unwrap();
                let m = perfect_measured(&truth);
                let to = dir.join(&f).with_file_name("measured.json");
                std::fs::write(to, serde_json::to_string_pretty(&m).unwrap()).unwrap();
            }
        }
    }

    /// The true migrations of `study.json` as the relative-motion CSV of `--migration-csv`.
    /// The true migration of every follow-up of `study` (a `study.json`) as another program's
    /// relative-motion CSV, the vendor file `evaluate --migration-csv` reads.
    pub fn migration_csv(study: &serde_json::Value) -> String {
        let mut csv =
            String::from("patient,exam,segment,tx_mm,ty_mm,tz_mm,rx_deg,ry_deg,rz_deg,mtpm_mm\n");
        for p in study["patients"].as_array().unwrap() {
            for m in p["migration"].as_array().unwrap() {
                let n = |v: &serde_json::Value, i: usize| v[i].as_f64().unwrap().to_string();
                let t = &m["translation_mm"];
                let r = &m["rotation_deg"];
                csv += &format!(
                    "{},{},{},{},{},{},{},{},{},{}\n",
                    p["id"].as_str().unwrap(),
                    m["exam"].as_str().unwrap(),
                    m["segment"].as_str().unwrap(),
                    n(t, 0),
                    n(t, 1),
                    n(t, 2),
                    n(r, 0),
                    n(r, 1),
                    n(r, 2),
                    m["mtpm_mm"].as_f64().unwrap()
                );
            }
        }
        csv
    }

    /// The repository root.
    fn root() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
    }

    /// The reconstructable scenario: `reconstruct_uniplanar.toml` with `runs` runs, 586 × 720 px,
    /// no noise, LZW, its mesh beside it.
    fn reconstructable(runs: &str) -> String {
        let text =
            std::fs::read_to_string(root().join("tests/scenarios/reconstruct_uniplanar.toml"))
                .unwrap();
        let mut out = text.clone();
        for (from, to) in [
            ("runs_per_level = 3", runs),
            ("noise_levels = [0.45]", "noise_levels = [0.0]"),
            ("tiff_compression = \"none\"", "tiff_compression = \"lzw\""),
            (
                "../../scenarios/models/femoral_component.glb",
                "femoral_component.glb",
            ),
            ("pixels = [1172, 1440]", "pixels = [586, 720]"),
            (
                "pixel_pitch_mm = [0.2986, 0.2986]",
                "pixel_pitch_mm = [0.5972, 0.5972]",
            ),
        ] {
            assert!(
                out.contains(from),
                "reconstruct_uniplanar.toml lacks {from:?}"
            );
            out = out.replace(from, to);
        }
        out
    }

    impl Harness {
        /// A harness for `bin`, killing a process after `limit`.
        pub fn new(bin: PathBuf, limit: Duration) -> Harness {
            // SAFETY: geteuid has no preconditions.
            let as_nobody = unsafe { libc::geteuid() } == 0;
            if as_nobody {
                if let Err(e) = nobody_can_run(&bin) {
                    panic!(
                        "the received-folder mutants run as `nobody` (this test runs as root), who cannot run {}: {e}; \
                         put the checkout and its target folder where others may enter (chmod o+x), \
                         or run the tests as a user other than root",
                        bin.display()
                    );
                }
            }
            Harness {
                bin,
                limit,
                keep: 10,
                kept: Default::default(),
                as_nobody,
            }
        }

        /// Runs the binary with `args` in `cwd` (as `nobody` when root), killing it after the
        /// limit. Keeps the first 64 KB of stdout and stderr.
        pub fn run(&self, cwd: &Path, args: &[String], drop_privileges: bool) -> Ran {
            use std::os::unix::process::CommandExt;
            let mut cmd = Command::new(&self.bin);
            cmd.args(args)
                .current_dir(cwd)
                .stdin(Stdio::null())
                .stdout(Stdio::piped())
                .stderr(Stdio::piped());
            // Its own process group, so that a hang is killed with any process it started.
            cmd.process_group(0);
            if drop_privileges && self.as_nobody {
                cmd.uid(NOBODY).gid(NOBODY);
            }
            let start = Instant::now();
            let mut child = cmd.spawn().expect("rsasim starts");
            let drain = |mut pipe: Box<dyn Read + Send>| {
                std::thread::spawn(move || {
                    let mut kept = Vec::new();
                    let mut buf = [0u8; 8192];
                    while let Ok(n) = pipe.read(&mut buf) {
                        if n == 0 {
                            break;
                        }
                        if kept.len() < 64 << 10 {
                            kept.extend_from_slice(&buf[..n]);
                        }
                    }
                    String::from_utf8_lossy(&kept).into_owned()
                })
            };
            let out = drain(Box::new(child.stdout.take().unwrap()));
            let err = drain(Box::new(child.stderr.take().unwrap()));
            let (status, timed_out) = loop {
                if let Some(status) = child.try_wait().unwrap() {
                    break (status, false);
                }
                if start.elapsed() > self.limit {
                    // SAFETY: a signal to the process group the child leads.
                    unsafe { libc::kill(-(child.id() as i32), libc::SIGKILL) };
                    child.kill().ok();
                    break (child.wait().unwrap(), true);
                }
                std::thread::sleep(Duration::from_millis(5));
            };
            let elapsed = start.elapsed();
            Ran {
                code: status.code(),
                stdout: out.join().unwrap(),
                stderr: err.join().unwrap(),
                timed_out,
                elapsed,
            }
        }

        /// Runs rsasim as this process (for the fixtures) and panics unless it exits 0.
        fn ok(&self, cwd: &Path, args: &[&str]) {
            let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
            let ran = self.run(cwd, &args, false);
            assert!(
                ran.code == Some(0),
                "fixture: rsasim {args:?} in {}: exit {:?}\n{}",
                cwd.display(),
                ran.code,
                ran.stderr
            );
        }

        /// Builds a received folder.
        pub fn fixture(&self, kind: FixtureKind) -> Fixture {
            let dir = tempfile::tempdir().unwrap();
            let src = dir.path().join("src");
            let work = dir.path().join("work");
            std::fs::create_dir_all(&src).unwrap();
            std::fs::create_dir_all(&work).unwrap();
            let base = |to: &Path| {
                std::fs::copy(
                    root().join("tests/mutation/base.toml"),
                    to.join("base.toml"),
                )
                .unwrap();
                std::fs::copy(
                    root().join("scenarios/golden/models/ball.stl"),
                    to.join("ball.stl"),
                )
                .unwrap();
            };
            let glb = |to: &Path| {
                std::fs::copy(
                    root().join("scenarios/models/femoral_component.glb"),
                    to.join("femoral_component.glb"),
                )
                .unwrap();
            };
            let w = work.to_str().unwrap();
            match kind {
                FixtureKind::Scored => {
                    base(&src);
                    self.ok(&src, &["base.toml", "--out", &format!("{w}/out")]);
                    write_perfect_results(&work.join("out"));
                }
                FixtureKind::Study => {
                    let text = std::fs::read_to_string(root().join("tests/scenarios/study.toml"))
                        .unwrap()
                        .replace("tiff_compression = \"none\"", "tiff_compression = \"lzw\"")
                        .replace(
                            "../../scenarios/models/femoral_component.glb",
                            "femoral_component.glb",
                        );
                    std::fs::write(src.join("study.toml"), text).unwrap();
                    glb(&src);
                    self.ok(&src, &["study.toml", "--out", &format!("{w}/study")]);
                    let study: serde_json::Value = serde_json::from_slice(
                        &std::fs::read(work.join("study/study.json")).unwrap(),
                    )
                    .unwrap();
                    std::fs::write(work.join("migration.csv"), migration_csv(&study)).unwrap();
                }
                FixtureKind::Reconstructable => {
                    std::fs::write(src.join("rec.toml"), reconstructable("runs_per_level = 2"))
                        .unwrap();
                    glb(&src);
                    self.ok(&src, &["rec.toml", "--out", &format!("{w}/out")]);
                }
                FixtureKind::Shards => {
                    base(&src);
                    for k in 0..2 {
                        let spec = format!("{k}/2");
                        let out = format!("{w}/shards");
                        self.ok(&src, &["base.toml", "--out", &out, "--shard", &spec]);
                    }
                }
                FixtureKind::SweepShards | FixtureKind::SweepScored => {
                    base(&work);
                    std::fs::write(
                        work.join("sweep.toml"),
                        "scenario = \"base.toml\"\n\n[[parameters]]\n\
                         key = \"sources.left.position_mm\"\n\
                         values = [[-342.0, 0.0, 939.7], [-330.0, 0.0, 945.0]]\n",
                    )
                    .unwrap();
                    if kind == FixtureKind::SweepShards {
                        for k in 0..2 {
                            let spec = format!("{k}/2");
                            self.ok(
                                &work,
                                &["sweep", "sweep.toml", "--out", "S", "--shard", &spec],
                            );
                        }
                    } else {
                        self.ok(&work, &["sweep", "sweep.toml", "--out", "S"]);
                        write_perfect_results(&work.join("S"));
                    }
                }
                FixtureKind::SweepReconstructable => {
                    std::fs::write(src.join("rec.toml"), reconstructable("runs_per_level = 1"))
                        .unwrap();
                    glb(&src);
                    std::fs::write(
                        src.join("sweep.toml"),
                        "scenario = \"rec.toml\"\n\n[[parameters]]\n\
                         key = \"protocol.runs_per_level\"\nvalues = [1, 2]\n",
                    )
                    .unwrap();
                    self.ok(&src, &["sweep", "sweep.toml", "--out", &format!("{w}/S")]);
                }
            }
            remove_locks(&work);
            normalize_builds(&work);
            let files = files_under(&work);
            let dirs = snapshot(&work)
                .into_iter()
                .filter(|(_, e)| matches!(e, Entry::Dir))
                .map(|(p, _)| p)
                .collect();
            let names = snapshot(&work)
                .keys()
                .filter_map(|p| p.rsplit('/').next().map(String::from))
                .filter(|n| {
                    n.len() >= 3
                        && n.chars()
                            .any(|c| c == '.' || c == '-' || c.is_ascii_digit())
                })
                .collect();
            Fixture {
                kind,
                _dir: dir,
                work,
                files,
                dirs,
                names,
            }
        }

        /// Copies the fixture for one mutant, mutates it (seed None: unmutated), runs `kind`'s
        /// command and checks the contract. Ok: the exit code.
        pub fn check(
            &self,
            kind: Kind,
            fixture: &Fixture,
            seed: Option<u64>,
        ) -> Result<i32, Box<Failure>> {
            assert_eq!(kind.fixture(), fixture.kind);
            let top_dir = tempfile::tempdir().unwrap();
            let top = top_dir.path();
            let work = top.join("l1/l2/l3/l4/work");
            copy_tree(&fixture.work, &work);
            std::fs::create_dir_all(top.join("victim/dir")).unwrap();
            std::fs::write(top.join("victim/victim.txt"), "victim\n").unwrap();
            let mut rng = Rng::new(seed.unwrap_or(0));
            let (file, mutation, group) = match seed {
                None => (String::new(), "unmutated".to_string(), "none"),
                Some(_) => {
                    let (file, group) = pick_file(kind, fixture, &mut rng);
                    let mutation = if work.join(&file).is_dir() {
                        mutate_dir(top, &work, &file, &mut rng)
                    } else {
                        mutate_file(top, &work, &file, &mut rng)
                    };
                    (file, mutation, group)
                }
            };
            let args = kind.args(group, &mut rng);
            if self.as_nobody {
                give_to_nobody(top);
            }
            let fail = |why: String, ran: &Ran| {
                let mut kept = None;
                if let Some(seed) = seed {
                    let n = self.kept.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    if n < self.keep {
                        let to = std::env::temp_dir()
                            .join(format!("rsasim-mutant-{}-{seed}", kind.name()));
                        let _ = std::fs::remove_dir_all(&to);
                        if std::fs::rename(top, &to).is_ok() {
                            kept = Some(to);
                        }
                    }
                }
                Box::new(Failure {
                    kind: kind.name(),
                    seed,
                    file: file.clone(),
                    mutation: mutation.clone(),
                    args: args.clone(),
                    code: ran.code,
                    timed_out: ran.timed_out,
                    why,
                    first_line: ran.first_line(),
                    stderr: ran.stderr.clone(),
                    kept,
                })
            };
            let before = snapshot(top);
            let ran = self.run(&work, &args, true);
            let after = snapshot(top);
            let prefix = "l1/l2/l3/l4/work/";
            let changes = diff(&before, &after);
            // What a process that broke off changed outside the output it was named (if anything).
            let stray = || {
                let v: Vec<(String, Change)> = changes
                    .iter()
                    .filter(|(p, c)| {
                        p.strip_prefix(prefix)
                            .is_none_or(|r| !kind.may_write(r, *c))
                    })
                    .cloned()
                    .collect();
                if v.is_empty() {
                    String::new()
                } else {
                    format!(" (and changed {})", show(&v))
                }
            };
            let allowed = match ran.code {
                _ if ran.timed_out => {
                    let why = format!("hung (killed after {:?}){}", self.limit, stray());
                    return Err(fail(why, &ran));
                }
                None => {
                    let why = format!("killed by a signal (abort?){}", stray());
                    return Err(fail(why, &ran));
                }
                Some(101) => return Err(fail(format!("panicked{}", stray()), &ran)),
                _ if ran.stderr.contains("panicked at") => {
                    return Err(fail(format!("panicked{}", stray()), &ran));
                }
                Some(0) => true,
                Some(1) if kind.may_exit_1() => true,
                Some(2) => false,
                Some(c) => {
                    let why = format!("exit {c}, not 0 or 2{}", stray());
                    return Err(fail(why, &ran));
                }
            };
            if !allowed {
                // Exit 2: nothing written, and an error naming a file of the folder.
                let lock_only = changes.iter().all(|(p, c)| {
                    *c == Change::Added
                        && p.rsplit('/')
                            .next()
                            .is_some_and(|n| n.ends_with(".rsasim-lock"))
                });
                if !changes.is_empty() && lock_only {
                    let why = format!("exit 2 but left a lock file: {}", show(&changes));
                    return Err(fail(why, &ran));
                }
                if !changes.is_empty() {
                    return Err(fail(format!("exit 2 but wrote {}", show(&changes)), &ran));
                }
                if let Some(out) = kind.new_output()
                    && work.join(out).exists()
                {
                    return Err(fail(format!("exit 2 but {out} exists"), &ran));
                }
                let said = format!("{}\n{}", ran.stderr, ran.stdout);
                let file_name = file.rsplit('/').next().unwrap_or("");
                let names_one = (!file_name.is_empty() && said.contains(file_name))
                    || fixture.names.iter().any(|n| said.contains(n.as_str()));
                if !names_one {
                    return Err(fail("exit 2 with an error that names no file".into(), &ran));
                }
                return Ok(2);
            }
            let outside: Vec<(String, Change)> = changes
                .iter()
                .filter(|(p, c)| match p.strip_prefix(prefix) {
                    Some(rel) => !kind.may_write(rel, *c),
                    None => true,
                })
                .cloned()
                .collect();
            if !outside.is_empty() {
                let why = format!(
                    "exit {:?} but changed what the user did not name: {}",
                    ran.code,
                    show(&outside)
                );
                return Err(fail(why, &ran));
            }
            if let Err(why) = self.check_written(kind, &work, &changes, prefix) {
                return Err(fail(why, &ran));
            }
            Ok(ran.code.unwrap())
        }

        /// After success: a written output with a manifest verifies, and no written table or
        /// camera file holds NaN or an infinity.
        fn check_written(
            &self,
            kind: Kind,
            work: &Path,
            changes: &[(String, Change)],
            prefix: &str,
        ) -> Result<(), String> {
            let written: Vec<&str> = changes
                .iter()
                .filter(|(_, c)| *c != Change::Removed)
                .filter_map(|(p, _)| p.strip_prefix(prefix))
                .collect();
            if let Some(out) = kind.new_output()
                && !work.join(out).is_dir()
            {
                return Err(format!("exit 0 but no {out} folder"));
            }
            // Folders that gained a manifest: the merged output, merged sweep points.
            let mut to_verify: BTreeSet<String> = BTreeSet::new();
            for p in &written {
                if let Some(dir) = p.strip_suffix("/manifest.json") {
                    to_verify.insert(dir.to_string());
                }
            }
            for dir in &to_verify {
                let ran = self.run(work, &["verify".to_string(), dir.clone()], true);
                if ran.code != Some(0) {
                    return Err(format!(
                        "the written {dir} does not verify: exit {:?}: {}{}",
                        ran.code,
                        ran.stdout.lines().take(5).collect::<Vec<_>>().join(" | "),
                        ran.first_line()
                    ));
                }
            }
            if kind == Kind::EvaluateStudy {
                let md = std::fs::read_to_string(work.join("rep/report.md")).unwrap_or_default();
                if !md.contains("## Clinical study: migration") {
                    return Err("exit 0 but the report has no migration section".into());
                }
            }
            for p in &written {
                let path = work.join(p);
                if !path.is_file() {
                    continue;
                }
                let ext = p.rsplit('.').next().unwrap_or("");
                let is_report =
                    p.ends_with(".csv") && (p.contains("rep/") || p.contains("/report-"));
                if is_report {
                    let text = std::fs::read_to_string(&path).unwrap_or_default();
                    if let Some(cell) = non_finite_cell(&text) {
                        return Err(format!("{p}: a non-finite cell: {cell}"));
                    }
                } else if matches!(kind, Kind::ExportXmalab | Kind::ExportAutoscoper)
                    && matches!(ext, "txt" | "csv" | "cfg" | "obj")
                {
                    let text = std::fs::read_to_string(&path).unwrap_or_default();
                    if let Some(bad) = non_finite_token(&text) {
                        return Err(format!("{p}: non-finite number {bad}"));
                    }
                }
            }
            Ok(())
        }
    }

    fn show(changes: &[(String, Change)]) -> String {
        let mut s: Vec<String> = changes
            .iter()
            .take(6)
            .map(|(p, c)| format!("{c:?} {}", p.strip_prefix("l1/l2/l3/l4/work/").unwrap_or(p)))
            .collect();
        if changes.len() > 6 {
            s.push(format!("… {} in all", changes.len()));
        }
        s.join(", ")
    }

    /// The first cell of a report CSV that is infinite, or NaN in a row with N ≥ 2 (NaN is the
    /// documented value of the precision and SD of a cell with a single residual; without an
    /// `n` column, any NaN). Quoted cells are read as CSV.
    pub fn non_finite_cell(csv: &str) -> Option<String> {
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(true)
            .from_reader(csv.as_bytes());
        let header: Vec<String> = reader.headers().ok()?.iter().map(String::from).collect();
        let n_col = header.iter().position(|h| h == "n");
        for (k, row) in reader.records().enumerate() {
            let Ok(row) = row else { continue };
            let single = n_col
                .and_then(|i| row.get(i))
                .and_then(|n| n.trim().parse::<u64>().ok())
                .is_some_and(|n| n < 2);
            for (i, cell) in row.iter().enumerate() {
                if let Ok(x) = cell.trim().parse::<f64>()
                    && (x.is_infinite() || (x.is_nan() && !single))
                {
                    let col = header.get(i).map_or("?", String::as_str);
                    return Some(format!("line {}, column {col}: {x}", k + 2));
                }
            }
        }
        None
    }

    /// The first token of `text` that reads as NaN or an infinity.
    fn non_finite_token(text: &str) -> Option<String> {
        text.split(|c: char| c.is_whitespace() || matches!(c, ',' | ';' | '=' | '(' | ')'))
            .find(|t| t.parse::<f64>().is_ok_and(|x| !x.is_finite()))
            .map(String::from)
    }

    /// Picks the group (by weight) and the file of the fixture to mutate.
    fn pick_file(kind: Kind, fixture: &Fixture, rng: &mut Rng) -> (String, &'static str) {
        let groups: Vec<_> = kind
            .groups()
            .into_iter()
            .map(|(name, w, test)| {
                let among = if name.starts_with("folder") {
                    &fixture.dirs
                } else {
                    &fixture.files
                };
                let files: Vec<&String> = among.iter().filter(|f| test(f.as_str())).collect();
                (name, w, files)
            })
            .filter(|(_, _, files)| !files.is_empty())
            .collect();
        let total: u32 = groups.iter().map(|(_, w, _)| w).sum();
        let mut at = rng.below(total as usize) as u32;
        for (name, w, files) in &groups {
            if at < *w {
                return ((*rng.pick(files)).clone(), name);
            }
            at -= w;
        }
        unreachable!()
    }

    /// Mutates `file` (relative to `work`): its text or bytes (85 %), or what it is (a FIFO, a
    /// link out of the folder or to a device or to itself, a folder, a sparse file past the size
    /// caps, nothing); then half the time rehashes it into the manifest. Returns a description.
    fn mutate_file(top: &Path, work: &Path, file: &str, rng: &mut Rng) -> String {
        let path = work.join(file);
        let original = std::fs::read(&path).unwrap();
        let strings = received_strings(top);
        let text = matches!(
            file.rsplit('.').next().unwrap_or(""),
            "json" | "toml" | "csv" | "md" | "txt" | "gltf"
        );
        let mut what = if rng.below(100) < 85 {
            let mutant = if text {
                match String::from_utf8(original.clone()) {
                    Ok(t) => mutate_received_text(&t, rng, &strings).into_bytes(),
                    Err(_) => mutate_bytes(&original, rng),
                }
            } else {
                mutate_bytes(&original, rng)
            };
            std::fs::remove_file(&path).unwrap();
            std::fs::write(&path, mutant).unwrap();
            "content".to_string()
        } else {
            std::fs::remove_file(&path).unwrap();
            match rng.below(7) {
                6 => "removed".to_string(),
                0 => {
                    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
                    // SAFETY: a valid C string path.
                    let r = unsafe { libc::mkfifo(c.as_ptr(), 0o666) };
                    assert_eq!(r, 0, "mkfifo {}", path.display());
                    "a FIFO".to_string()
                }
                1 => {
                    let copy = top.join("victim").join("copy");
                    std::fs::write(&copy, &original).unwrap();
                    std::os::unix::fs::symlink(&copy, &path).unwrap();
                    "a link to an identical copy outside the folder".to_string()
                }
                2 => {
                    std::os::unix::fs::symlink("/dev/zero", &path).unwrap();
                    "a link to /dev/zero".to_string()
                }
                3 => {
                    std::fs::create_dir(&path).unwrap();
                    "a folder".to_string()
                }
                4 => {
                    let f = std::fs::File::create(&path).unwrap();
                    f.set_len(300 << 20).unwrap();
                    "a sparse file of 300 MiB".to_string()
                }
                5 => {
                    std::os::unix::fs::symlink(path.file_name().unwrap(), &path).unwrap();
                    "a link to itself".to_string()
                }
                _ => unreachable!(),
            }
        };
        if rng.below(2) == 0 {
            let small = std::fs::symlink_metadata(&path)
                .is_ok_and(|m| m.file_type().is_file() && m.len() < 64 << 20);
            if small {
                match rehash(work, &path) {
                    Some(how) => {
                        what += &format!(", {}", how.replace(&format!("{}/", work.display()), ""))
                    }
                    None => what += ", not listed (no rehash)",
                }
            }
        }
        what
    }

    /// Mutates the folder `dir` (relative to `work`): replaced by a link to an identical copy
    /// outside the folder or to a sibling folder, by a file or a FIFO, removed, or given an
    /// unlisted file and folder. Returns a description.
    fn mutate_dir(top: &Path, work: &Path, dir: &str, rng: &mut Rng) -> String {
        let path = work.join(dir);
        match rng.below(6) {
            0 => {
                let copy = top.join("victim").join("copy-of-folder");
                copy_tree(&path, &copy);
                std::fs::remove_dir_all(&path).unwrap();
                std::os::unix::fs::symlink(&copy, &path).unwrap();
                "a link to an identical copy outside the folder".into()
            }
            1 => {
                let parent = path.parent().unwrap();
                let mut siblings: Vec<PathBuf> = std::fs::read_dir(parent)
                    .unwrap()
                    .flatten()
                    .map(|e| e.path())
                    .filter(|p| p.is_dir() && *p != path)
                    .collect();
                siblings.sort();
                if siblings.is_empty() {
                    std::fs::remove_dir_all(&path).unwrap();
                    return "removed".into();
                }
                let to = rng.pick(&siblings).file_name().unwrap().to_owned();
                std::fs::remove_dir_all(&path).unwrap();
                std::os::unix::fs::symlink(&to, &path).unwrap();
                format!("a link to its sibling {}", to.to_string_lossy())
            }
            2 => {
                std::fs::remove_dir_all(&path).unwrap();
                "removed".into()
            }
            3 => {
                std::fs::remove_dir_all(&path).unwrap();
                std::fs::write(&path, "{}\n").unwrap();
                "a file".into()
            }
            4 => {
                std::fs::write(path.join("extra.json"), "{}\n").unwrap();
                std::fs::create_dir_all(path.join("extra/runs")).unwrap();
                "given an unlisted file and folder".into()
            }
            _ => {
                std::fs::remove_dir_all(&path).unwrap();
                let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
                // SAFETY: a valid C string path.
                let r = unsafe { libc::mkfifo(c.as_ptr(), 0o666) };
                assert_eq!(r, 0, "mkfifo {}", path.display());
                "a FIFO".into()
            }
        }
    }
}
