//! Input errors and warnings that name the file, line, column and key path, and say what is valid.
//!
//! Every stage that judges user input (the scenario, the meshes it names, the geometry it
//! describes) reports [`Diagnostic`]s. A [`Locator`] keeps the TOML text with the span of every key
//! and value, so a check that only knows a key path (`detectors[1].bpp`) still points the user at
//! the right line, and a parse error that only knows a byte offset still names its key path.

use std::borrow::Cow;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use toml::Spanned;
use toml::de::{DeTable, DeValue};

/// The longest piece of user text (a value, a quoted name, a source line) a message echoes, in
/// characters. Longer text is cut to this length and marked `… (N more bytes)`, so a 600 KB TOML
/// line or a 5 MB string never floods the terminal or a log.
pub const ECHO_MAX_CHARS: usize = 200;

/// `text` cut to [`ECHO_MAX_CHARS`] characters, with `… (N more bytes)` saying how much was left
/// out. Every module that echoes a user's value in a message calls this (or relies on
/// [`Diagnostic`]'s `Display`, which applies it to quoted text and the source line).
pub fn cut(text: &str) -> Cow<'_, str> {
    cut_at(text, ECHO_MAX_CHARS)
}

/// `text` cut to `max_chars` characters, with `… (N more bytes)` appended when anything was cut.
fn cut_at(text: &str, max_chars: usize) -> Cow<'_, str> {
    // A value cut once keeps its marker and its true count when it is cut again.
    if let Some(at) = text.rfind("… (")
        && text.ends_with(" more bytes)")
        && text[..at].chars().count() <= max_chars
    {
        return Cow::Borrowed(text);
    }
    match text.char_indices().nth(max_chars) {
        None => Cow::Borrowed(text),
        Some((end, _)) => Cow::Owned(format!(
            "{}… ({} more bytes)",
            &text[..end],
            text.len() - end
        )),
    }
}

/// A message with every quoted piece (between backticks or double quotes) longer than
/// [`ECHO_MAX_CHARS`] cut, and the whole message bounded at four times that: the words that say
/// what is wrong stay, the echoed value shrinks.
fn cut_message(message: &str) -> Cow<'_, str> {
    if message.chars().count() <= ECHO_MAX_CHARS {
        return Cow::Borrowed(message);
    }
    let mut out = String::new();
    let mut rest = message;
    while let Some(open) = rest.find(['`', '"']) {
        let quote = &rest[open..open + 1];
        out.push_str(&rest[..=open]);
        rest = &rest[open + 1..];
        match rest.find(quote) {
            Some(close) => {
                out.push_str(&cut(&rest[..close]));
                out.push_str(quote);
                rest = &rest[close + 1..];
            }
            None => {
                out.push_str(&cut(rest));
                rest = "";
            }
        }
    }
    out.push_str(rest);
    Cow::Owned(cut_at(&out, 4 * ECHO_MAX_CHARS).into_owned())
}

/// The part of a source line shown under a message: at most [`ECHO_MAX_CHARS`] characters around
/// the 1-based column `col`, and the caret's column within that excerpt.
fn source_excerpt(line: &str, col: usize) -> (String, usize) {
    let chars = line.chars().count();
    if chars <= ECHO_MAX_CHARS {
        return (line.to_string(), col);
    }
    let start = col.saturating_sub(1 + ECHO_MAX_CHARS / 4).min(chars);
    let skipped: usize = line.chars().take(start).map(char::len_utf8).sum();
    let window = &line[skipped..];
    let cut_window = cut(window);
    if start == 0 {
        (cut_window.into_owned(), col)
    } else {
        let lead = format!("({skipped} bytes before) …");
        let caret = col - start + lead.chars().count();
        (format!("{lead}{cut_window}"), caret)
    }
}

/// How serious a diagnostic is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    /// The input cannot be run; nothing is written.
    Error,
    /// The input runs, but probably not as the user meant.
    Warning,
}

/// One segment of a key path: a table key or an array index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Segment {
    /// A key of a table.
    Key(String),
    /// An index into an array (0-based, as the user counts `[[tables]]` from the top).
    Index(usize),
}

/// A path to a value in the scenario, printed as `detectors[1].pixel_pitch_mm`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct KeyPath(pub Vec<Segment>);

impl KeyPath {
    /// The empty path (the whole document).
    pub fn root() -> Self {
        KeyPath(Vec::new())
    }

    /// This path extended by a key.
    pub fn key(&self, key: &str) -> Self {
        let mut p = self.clone();
        p.0.push(Segment::Key(key.to_string()));
        p
    }

    /// This path extended by an array index.
    pub fn index(&self, i: usize) -> Self {
        let mut p = self.clone();
        p.0.push(Segment::Index(i));
        p
    }
}

impl fmt::Display for KeyPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (n, seg) in self.0.iter().enumerate() {
            match seg {
                Segment::Key(k) if n == 0 => write!(f, "{k}")?,
                Segment::Key(k) => write!(f, ".{k}")?,
                Segment::Index(i) => write!(f, "[{i}]")?,
            }
        }
        Ok(())
    }
}

/// An error or warning about user input, located in a file.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// The file the problem is in.
    pub file: PathBuf,
    /// 1-based line and column, when known.
    pub line_col: Option<(usize, usize)>,
    /// The key path of the offending value, when known.
    pub key_path: Option<KeyPath>,
    /// What is wrong.
    pub message: String,
    /// What would be valid, or what to do next.
    pub help: Option<String>,
    /// The source line, for display under the message.
    pub source_line: Option<String>,
}

impl Diagnostic {
    /// An error about a whole file (no position inside it).
    pub fn file_error(file: &Path, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Error,
            file: file.to_path_buf(),
            line_col: None,
            key_path: None,
            message: message.into(),
            help: None,
            source_line: None,
        }
    }

    /// Adds a hint on what would be valid.
    pub fn with_help(mut self, help: impl Into<String>) -> Self {
        self.help = Some(help.into());
        self
    }

    /// Whether this is an error (not a warning).
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        write!(f, "{kind}: {}", self.file.display())?;
        if let Some((line, col)) = self.line_col {
            write!(f, ":{line}:{col}")?;
        }
        if let Some(path) = self.key_path.as_ref().filter(|p| !p.0.is_empty()) {
            write!(f, ": `{path}`")?;
        }
        write!(f, ": {}", cut_message(&self.message))?;
        if let (Some(src), Some((line, col))) = (&self.source_line, self.line_col) {
            let (src, col) = source_excerpt(src, col);
            let gutter = line.to_string().len();
            write!(
                f,
                "\n{:gutter$} |\n{line} | {src}\n{:gutter$} | {:>col$}",
                "", "", "^"
            )?;
        }
        if let Some(help) = &self.help {
            write!(f, "\n  = help: {}", cut_message(help))?;
        }
        Ok(())
    }
}

/// The text of a TOML file with the span of every key and value, to turn key paths into
/// line/column positions and byte offsets into key paths.
pub struct Locator {
    file: PathBuf,
    text: String,
    /// The byte offset at which each line starts: a line number is a binary search, not a scan
    /// of the text (a file with 90,000 errors would otherwise cost 90,000 scans).
    line_starts: Vec<usize>,
    root: Option<Spanned<DeTable<'static>>>,
}

impl Locator {
    /// Indexes `text` (the contents of `file`). A text that does not parse gets a locator that
    /// only knows line/column arithmetic.
    pub fn new(file: &Path, text: &str) -> Self {
        // The spanned tree borrows the text; leak a copy so the locator owns it for its lifetime.
        // Scenario files are small and parsed once per process.
        let leaked: &'static str = Box::leak(text.to_string().into_boxed_str());
        let root = DeTable::parse(leaked).ok();
        Locator {
            file: file.to_path_buf(),
            text: text.to_string(),
            line_starts: std::iter::once(0)
                .chain(text.match_indices('\n').map(|(i, _)| i + 1))
                .collect(),
            root,
        }
    }

    /// The parsed document with the span of every key and value, when the text parses as TOML.
    pub fn document(&self) -> Option<&DeTable<'static>> {
        self.root.as_ref().map(Spanned::get_ref)
    }

    /// The file this locator indexes.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// The span of the value at `path`, or of its deepest ancestor that is present (a missing
    /// key points at the table that should hold it).
    pub fn span_of(&self, path: &KeyPath) -> Option<Range<usize>> {
        self.walk(path).0
    }

    /// Whether the document holds a value at exactly `path` (the user wrote it).
    pub fn has(&self, path: &KeyPath) -> bool {
        self.walk(path).1
    }

    /// Follows `path` down the document: the span of the deepest value reached, and whether the
    /// whole path was found.
    fn walk(&self, path: &KeyPath) -> (Option<Range<usize>>, bool) {
        let Some(root) = self.root.as_ref() else {
            return (None, false);
        };
        let mut span = None;
        let mut table: Option<&DeTable> = Some(root.get_ref());
        let mut value: Option<&Spanned<DeValue>> = None;
        for seg in &path.0 {
            let next = match (seg, table, value.map(|v| v.get_ref())) {
                (Segment::Key(k), Some(t), _) => t.get(k.as_str()),
                (Segment::Index(i), _, Some(DeValue::Array(a))) => a.get(*i),
                _ => None,
            };
            let Some(next) = next else {
                return (span, false);
            };
            span = Some(next.span());
            table = match next.get_ref() {
                DeValue::Table(t) => Some(t),
                _ => None,
            };
            value = Some(next);
        }
        (span, true)
    }

    /// The key path of the innermost key or value whose span contains byte `offset`.
    ///
    /// Array-of-tables spans cover only their headers, so this searches the whole tree depth first.
    pub fn path_at(&self, offset: usize) -> Option<KeyPath> {
        fn walk(v: &DeValue, offset: usize, path: &mut KeyPath) -> bool {
            type Child<'a> = (Segment, Option<Range<usize>>, &'a Spanned<DeValue<'a>>);
            let children: Vec<Child> = match v {
                DeValue::Table(t) => t
                    .iter()
                    .map(|(k, v)| (Segment::Key(k.get_ref().to_string()), Some(k.span()), v))
                    .collect(),
                DeValue::Array(a) => a
                    .iter()
                    .enumerate()
                    .map(|(i, v)| (Segment::Index(i), None, v))
                    .collect(),
                _ => return false,
            };
            for (seg, key_span, child) in children {
                path.0.push(seg);
                if walk(child.get_ref(), offset, path) {
                    return true;
                }
                if key_span.is_some_and(|s| s.contains(&offset)) || child.span().contains(&offset) {
                    return true;
                }
                path.0.pop();
            }
            false
        }
        let root = self.root.as_ref()?;
        let mut path = KeyPath::root();
        walk(&DeValue::Table(root.get_ref().clone()), offset, &mut path);
        (!path.0.is_empty()).then_some(path)
    }

    /// 1-based (line, column) of a byte offset, and the text of that line.
    pub fn line_col(&self, offset: usize) -> ((usize, usize), String) {
        let mut offset = offset.min(self.text.len());
        while !self.text.is_char_boundary(offset) {
            offset -= 1;
        }
        // The last line starting at or before `offset`; line_starts[0] is 0.
        let line = self.line_starts.partition_point(|&start| start <= offset);
        let line_start = self.line_starts[line - 1];
        let col = self.text[line_start..offset].chars().count() + 1;
        let line_text = self.text[line_start..]
            .lines()
            .next()
            .unwrap_or("")
            .to_string();
        ((line, col), line_text)
    }

    /// A diagnostic at the value `path` points to.
    pub fn at(&self, severity: Severity, path: KeyPath, message: impl Into<String>) -> Diagnostic {
        let (line_col, source_line) = match self.span_of(&path) {
            Some(span) => {
                let (lc, text) = self.line_col(span.start);
                (Some(lc), Some(text))
            }
            None => (None, None),
        };
        Diagnostic {
            severity,
            file: self.file.clone(),
            line_col,
            key_path: Some(path),
            message: message.into(),
            help: None,
            source_line,
        }
    }

    /// An error at `path`.
    pub fn error(&self, path: KeyPath, message: impl Into<String>) -> Diagnostic {
        self.at(Severity::Error, path, message)
    }

    /// A warning at `path`.
    pub fn warning(&self, path: KeyPath, message: impl Into<String>) -> Diagnostic {
        self.at(Severity::Warning, path, message)
    }

    /// A diagnostic at a byte span (a parse error), with the key path found there.
    pub fn error_at_span(
        &self,
        span: Option<Range<usize>>,
        message: impl Into<String>,
    ) -> Diagnostic {
        let (line_col, source_line, key_path) = match span {
            Some(span) => {
                let (lc, text) = self.line_col(span.start);
                (Some(lc), Some(text), self.path_at(span.start))
            }
            None => (None, None, None),
        };
        Diagnostic {
            severity: Severity::Error,
            file: self.file.clone(),
            line_col,
            key_path,
            message: message.into(),
            help: None,
            source_line,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str =
        "name = \"x\"\n\n[[detectors]]\nid = \"a\"\n\n[[detectors]]\nid = \"b\"\nbpp = 17\n";

    #[test]
    fn long_values_and_lines_are_cut_with_the_count_of_what_was_left_out() {
        let long = "x".repeat(600_000);
        assert_eq!(cut("short"), "short");
        let c = cut(&long);
        assert!(c.len() < 300 && c.ends_with("… (599800 more bytes)"), "{c}");
        // Cutting again keeps the true count (a module cuts a value, the display cuts messages).
        assert_eq!(cut(&c), c);
        // Multi-byte characters are never split.
        assert!(cut(&"é".repeat(300)).ends_with("… (200 more bytes)"));
        let doc = format!("name = \"{long}\"\nbpp = 17\n");
        let loc = Locator::new(Path::new("s.toml"), &doc);
        let d = loc
            .error(
                KeyPath::root().key("name"),
                format!("`{long}` is not a valid id"),
            )
            .with_help(format!("not \"{long}\""));
        let s = d.to_string();
        assert!(s.len() < 2_000, "{} bytes", s.len());
        assert!(s.contains("more bytes)` is not a valid id"), "{s}");
        assert!(s.contains("1 | name = \"xxx"), "{s}");
        // A value far into a long line: the excerpt shows it, and the caret points at it.
        let doc = format!("a = [{}]\nb = 1\n", "1, ".repeat(10_000) + "\"z\"");
        let loc = Locator::new(Path::new("s.toml"), &doc);
        let off = doc.find("\"z\"").unwrap();
        let d = loc.error_at_span(Some(off..off + 3), "wrong type");
        let s = d.to_string();
        let lines: Vec<&str> = s.lines().collect();
        let (src, caret) = (lines[2], lines[3]);
        let at = src.find("\"z\"").expect("the value is in the excerpt");
        let chars_before = src[..at].chars().count();
        assert_eq!(caret.find('^'), Some(chars_before), "{s}");
        assert!(src.contains("bytes before) …"), "{src}");
    }

    #[test]
    fn key_paths_print_like_toml_access() {
        let p = KeyPath::root().key("detectors").index(1).key("bpp");
        assert_eq!(p.to_string(), "detectors[1].bpp");
    }

    #[test]
    fn spans_of_key_paths_point_at_the_right_line() {
        let loc = Locator::new(Path::new("s.toml"), DOC);
        let d = loc.error(KeyPath::root().key("detectors").index(1).key("bpp"), "bad");
        assert_eq!(d.line_col, Some((8, 7)));
        assert_eq!(d.source_line.as_deref(), Some("bpp = 17"));
        // A missing key points at its table.
        let d = loc.error(
            KeyPath::root().key("detectors").index(0).key("source"),
            "missing",
        );
        assert_eq!(d.line_col.map(|lc| lc.0), Some(3));
    }

    #[test]
    fn line_and_column_of_every_offset_agree_with_counting_by_hand() {
        // Counted the slow way (newlines before the offset; characters since the last one) for
        // every byte of a text with multi-byte characters, an empty line and no final newline.
        let text = "a = 1\n\nname = \"Müller µm\"\n# ä\nx = 2";
        let loc = Locator::new(Path::new("s.toml"), text);
        for offset in 0..=text.len() + 3 {
            let mut at = offset.min(text.len());
            while !text.is_char_boundary(at) {
                at -= 1;
            }
            let before = &text[..at];
            let line = before.matches('\n').count() + 1;
            let start = before.rfind('\n').map_or(0, |i| i + 1);
            let col = text[start..at].chars().count() + 1;
            let line_text = text[start..].lines().next().unwrap_or("");
            assert_eq!(
                loc.line_col(offset),
                ((line, col), line_text.to_string()),
                "offset {offset}"
            );
        }
    }

    #[test]
    fn offsets_map_back_to_key_paths() {
        let loc = Locator::new(Path::new("s.toml"), DOC);
        let off = DOC.find("17").unwrap();
        assert_eq!(loc.path_at(off).unwrap().to_string(), "detectors[1].bpp");
    }

    #[test]
    fn display_names_file_line_path_and_help() {
        let loc = Locator::new(Path::new("s.toml"), DOC);
        let d = loc
            .error(
                KeyPath::root().key("detectors").index(1).key("bpp"),
                "bpp 17 is out of range",
            )
            .with_help("bpp must be 1..=16");
        let s = d.to_string();
        assert!(
            s.starts_with("error: s.toml:8:7: `detectors[1].bpp`: bpp 17 is out of range"),
            "{s}"
        );
        assert!(
            s.contains("8 | bpp = 17") && s.contains("help: bpp must be 1..=16"),
            "{s}"
        );
    }
}
