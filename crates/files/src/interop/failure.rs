//! Why an export (`rsasim export`) or a camera folder (`rsasim camera`) failed: bad input, with
//! nothing written (exit 2), or a write error (exit 1).

use crate::diagnostic::Diagnostic;

/// Why an export or a camera folder failed: bad input (exit 2, nothing written) or a write error (exit 1).
#[derive(Debug)]
pub enum Error {
    /// Refused before writing.
    Input(Vec<Diagnostic>),
    /// Writing failed; nothing was committed.
    Write(String),
}

impl From<Vec<Diagnostic>> for Error {
    fn from(d: Vec<Diagnostic>) -> Self {
        Error::Input(d)
    }
}

impl From<Diagnostic> for Error {
    fn from(d: Diagnostic) -> Self {
        Error::Input(vec![d])
    }
}
