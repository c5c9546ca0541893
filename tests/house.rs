//! The house's rules that the compiler does not keep (the crate walls it keeps itself: see the
//! manual's Architecture, docs/src/development/architecture.md): a thin `main`, no function with a long list of positional arguments,
//! and documentation that cites only files the repository has.

use std::path::{Path, PathBuf};

use crate::common::root;

/// The most positional arguments a function takes (`self` not counted): clippy's default
/// `too-many-arguments-threshold`. Beyond it, the arguments that travel together become a record.
const MAX_ARGUMENTS: usize = 7;

/// `src/main.rs` only dispatches: at most this many lines.
const MAX_MAIN_LINES: usize = 150;

/// Every `.rs` file under `dir`, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display())) {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The source folders of the house: `src/` and every `crates/*/src/`.
fn source_folders() -> Vec<PathBuf> {
    let mut out = vec![root().join("src")];
    let mut crates: Vec<PathBuf> = std::fs::read_dir(root().join("crates"))
        .unwrap()
        .map(|e| e.unwrap().path().join("src"))
        .collect();
    crates.sort();
    out.extend(crates);
    assert!(out.len() >= 6, "the house has its crates: {out:?}");
    out
}

/// The text of `source` without `//` comments (a comment may quote a signature).
fn code_of(source: &str) -> String {
    source
        .lines()
        .map(|l| match l.find("//") {
            Some(at) if !l[..at].contains('"') => &l[..at],
            _ => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every function of `code` with its number of positional arguments (`self` not counted).
fn argument_counts(code: &str) -> Vec<(String, usize)> {
    let bytes = code.as_bytes();
    let mut out = Vec::new();
    let mut at = 0;
    while let Some(found) = code[at..].find("fn ") {
        let start = at + found;
        at = start + 3;
        // `fn` as a word: not the end of an identifier (`hfn `).
        if start > 0 && (bytes[start - 1].is_ascii_alphanumeric() || bytes[start - 1] == b'_') {
            continue;
        }
        let name: String = code[at..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        if name.is_empty() {
            continue; // `fn(` in a type
        }
        // Skip the generics, then read the parenthesised list, counting top-level commas.
        let mut i = at + name.len();
        let mut angle = 0i32;
        while i < bytes.len() {
            match bytes[i] {
                b'<' => angle += 1,
                b'>' if bytes[i - 1] != b'-' => angle -= 1,
                b'(' if angle == 0 => break,
                _ => {}
            }
            i += 1;
        }
        let mut depth = 0i32;
        let mut args = vec![String::new()];
        for (k, &b) in bytes[i..].iter().enumerate() {
            let arrow = b == b'>' && k > 0 && bytes[i + k - 1] == b'-';
            match b {
                b'(' | b'[' | b'{' => depth += 1,
                b'<' => depth += 1,
                b')' | b']' | b'}' => depth -= 1,
                b'>' if !arrow => depth -= 1,
                _ => {}
            }
            if depth == 0 {
                break;
            }
            if b == b',' && depth == 1 {
                args.push(String::new());
            } else if k > 0 {
                args.last_mut().unwrap().push(b as char);
            }
        }
        let n = args
            .iter()
            .map(|a| a.trim())
            .filter(|a| !a.is_empty())
            .filter(|a| {
                let name = a.split(':').next().unwrap().trim();
                !matches!(name, "self" | "&self" | "&mut self" | "mut self")
                    && !name.starts_with("&'")
            })
            .count();
        out.push((name, n));
    }
    out
}

#[test]
fn the_argument_counter_counts_what_a_reader_counts() {
    let code = "fn a(x: u8, y: Vec<(u8, u8)>, f: impl Fn(&str) -> bool) -> u8 { 0 }\n\
                pub(crate) fn b<'a, T: Into<u8>>(&self, t: T, m: &'a [u8; 3]) {}\n\
                fn c() {}\n\
                fn d(\n    a: u8,\n    b: HashMap<String, Vec<u8>>,\n) {}\n";
    assert_eq!(
        argument_counts(code),
        [
            ("a".to_string(), 3),
            ("b".into(), 2),
            ("c".into(), 0),
            ("d".into(), 2)
        ]
    );
}

#[test]
fn no_function_takes_more_than_seven_positional_arguments() {
    let mut long = Vec::new();
    let mut functions = 0;
    for folder in source_folders() {
        for file in rust_files(&folder) {
            let source = std::fs::read_to_string(&file).unwrap();
            let rel = file.strip_prefix(root()).unwrap().display().to_string();
            if source.contains("too_many_arguments") {
                long.push(format!("{rel}: silences clippy::too_many_arguments"));
            }
            for (name, n) in argument_counts(&code_of(&source)) {
                functions += 1;
                if n > MAX_ARGUMENTS {
                    long.push(format!("{rel}: fn {name} takes {n} arguments"));
                }
            }
        }
    }
    assert!(functions > 1000, "only {functions} functions read");
    assert!(
        long.is_empty(),
        "at most {MAX_ARGUMENTS} positional arguments; group the ones that travel together:\n{}",
        long.join("\n")
    );
}

#[test]
fn main_only_dispatches() {
    let main = std::fs::read_to_string(root().join("src/main.rs")).unwrap();
    let lines = main.lines().count();
    assert!(lines <= MAX_MAIN_LINES, "src/main.rs has {lines} lines");
}

/// Every Markdown file under `dir`, at any depth.
fn markdown_under(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            markdown_under(&p, out);
        } else if p.extension().is_some_and(|x| x == "md") {
            out.push(p);
        }
    }
}

/// Paths in backticks in the repository's Markdown (the README and every page of the manual,
/// `docs/src/`) that name a source, test, doc or scenario file or folder of the
/// repository (`crates/files/src/output/tiff.rs`, `docs/src/guide/receiving.md`) exist: a moved
/// file leaves no stale citation behind. Links between pages are checked by
/// `docs/check_links.py` on the built book.
#[test]
fn the_documentation_cites_files_that_exist() {
    let mut docs = vec![root().join("README.md")];
    markdown_under(&root().join("docs/src"), &mut docs);
    let prefixes = [
        "src/",
        "crates/",
        "tests/",
        "docs/",
        "benches/",
        "examples/",
        "scenarios/",
        "deploy/",
        "schemas/",
        "golden/",
    ];
    let mut cited = 0;
    let mut stale = Vec::new();
    for doc in &docs {
        let text = std::fs::read_to_string(doc).unwrap();
        for (k, quoted) in text.split('`').enumerate() {
            // Odd pieces are inside backticks; a path is one word.
            if k % 2 == 0 || quoted.contains(char::is_whitespace) {
                continue;
            }
            let path = quoted.trim_end_matches(['.', ',', ':', ')']);
            if !prefixes.iter().any(|p| path.starts_with(p))
                || path.contains(['*', '<', '{', '$', '…'])
            {
                continue;
            }
            // `examples/x.rs` is cited by path; `examples/x` alone is a built binary's name.
            let is_file = Path::new(path).extension().is_some();
            if !is_file && !path.ends_with('/') {
                continue;
            }
            cited += 1;
            if !root().join(path).exists() {
                stale.push(format!(
                    "{}: `{path}`",
                    doc.strip_prefix(root()).unwrap().display()
                ));
            }
        }
    }
    assert!(cited > 50, "only {cited} paths cited");
    assert!(
        stale.is_empty(),
        "cited but not in the repository:\n{}",
        stale.join("\n")
    );
}
