//! The report as PDF: the HTML report printed by a headless Chromium-family browser (its print
//! stylesheet decides the page layout). The browser is found before anything is scored or
//! written; it prints into a private temporary folder, and the PDF's bytes are then written like
//! every other report file. PDF bytes are not reproducible (the browser stamps a creation date):
//! the HTML, Markdown, LaTeX and CSV files are the byte-stable reports.

use std::ffi::OsString;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Environment variable naming the browser to print with (a path, or a name looked up on PATH).
pub const BROWSER_ENV: &str = "RSASIM_BROWSER";

/// Browsers looked for on PATH, in this order, when [`BROWSER_ENV`] is not set.
pub const BROWSER_NAMES: [&str; 3] = ["chromium", "chromium-browser", "google-chrome"];

/// How long one print may take before the browser is stopped.
pub const PRINT_TIMEOUT: Duration = Duration::from_secs(120);

/// A headless browser that can print HTML to PDF.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Browser {
    /// The executable.
    pub path: PathBuf,
}

/// Why no browser was found: the message names what was looked for and what to install.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct NoBrowser {
    /// What was looked for, and where.
    pub message: String,
    /// What to do.
    pub help: String,
}

/// The browser of `$RSASIM_BROWSER`, else the first of [`BROWSER_NAMES`] on PATH.
pub fn find_browser() -> Result<Browser, NoBrowser> {
    let path_var = std::env::var_os("PATH").unwrap_or_default();
    find_browser_in(std::env::var_os(BROWSER_ENV), &path_var)
}

/// [`find_browser`] with the variable and the search path given (testable without touching the
/// process environment).
pub fn find_browser_in(
    chosen: Option<OsString>,
    path_var: &OsString,
) -> Result<Browser, NoBrowser> {
    let help = format!(
        "install Chromium (Debian/Ubuntu: apt-get install chromium), or set {BROWSER_ENV} to a \
Chromium or Chrome executable; without a browser, leave pdf out of --format and print report.html \
from any browser (its print stylesheet keeps every column)"
    );
    if let Some(chosen) = chosen.filter(|c| !c.is_empty()) {
        return lookup(Path::new(&chosen), path_var)
            .map(|path| Browser { path })
            .ok_or_else(|| NoBrowser {
                message: format!(
                    "--format pdf: {BROWSER_ENV}={} is not an executable file (nor a program on PATH)",
                    Path::new(&chosen).display()
                ),
                help: help.clone(),
            });
    }
    BROWSER_NAMES
        .iter()
        .find_map(|name| lookup(Path::new(name), path_var))
        .map(|path| Browser { path })
        .ok_or_else(|| NoBrowser {
            message: format!(
                "--format pdf needs a headless browser to print the HTML report, and none was \
found: looked for {} on PATH and for {BROWSER_ENV}",
                BROWSER_NAMES.join(", ")
            ),
            help,
        })
}

/// `name` itself when it has a folder part, else the first executable file of that name in the
/// folders of `path_var`.
fn lookup(name: &Path, path_var: &OsString) -> Option<PathBuf> {
    if name.components().count() > 1 || name.is_absolute() {
        return is_executable(name).then(|| name.to_path_buf());
    }
    std::env::split_paths(path_var)
        .map(|dir| dir.join(name))
        .find(|p| is_executable(p))
}

fn is_executable(path: &Path) -> bool {
    let Ok(meta) = std::fs::metadata(path) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        meta.is_file() && meta.permissions().mode() & 0o111 != 0
    }
    #[cfg(not(unix))]
    {
        meta.is_file()
    }
}

/// The command line that prints `html` (a local file) to `pdf`: headless, no GPU, no header or
/// footer lines, a private profile folder. `--no-sandbox` because the page is rsasim's own
/// report (no scripts, no network) and a sandbox cannot start as root (CI containers).
pub fn print_command(browser: &Browser, html: &Path, pdf: &Path, profile: &Path) -> Command {
    let mut c = Command::new(&browser.path);
    c.arg("--headless")
        .arg("--no-sandbox")
        .arg("--disable-gpu")
        .arg("--no-pdf-header-footer")
        .arg("--no-first-run")
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--print-to-pdf={}", pdf.display()))
        .arg(file_url(html));
    c
}

/// Prints the HTML document `html_text` to PDF with `browser` and returns the PDF's bytes. The
/// browser works in a private temporary folder that is removed afterwards; it is stopped after
/// [`PRINT_TIMEOUT`].
pub fn print_pdf(browser: &Browser, html_text: &str) -> std::io::Result<Vec<u8>> {
    let work = tempfile::Builder::new().prefix("rsasim-print-").tempdir()?;
    let html = work.path().join("report.html");
    let pdf = work.path().join("report.pdf");
    std::fs::write(&html, html_text)?;
    let mut child = print_command(browser, &html, &pdf, &work.path().join("profile"))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| {
            std::io::Error::new(
                e.kind(),
                format!("cannot start {}: {e}", browser.path.display()),
            )
        })?;
    // Drain stderr on a thread so a chatty browser never blocks on a full pipe.
    let mut stderr = child.stderr.take();
    let drain = std::thread::spawn(move || {
        let mut text = String::new();
        if let Some(e) = stderr.as_mut() {
            let _ = e.read_to_string(&mut text);
        }
        text
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if start.elapsed() > PRINT_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            return Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!(
                    "{} did not print the report within {} s",
                    browser.path.display(),
                    PRINT_TIMEOUT.as_secs()
                ),
            ));
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let log = drain.join().unwrap_or_default();
    let bytes = std::fs::read(&pdf).unwrap_or_default();
    if !status.success() || !bytes.starts_with(b"%PDF-") {
        let last: Vec<&str> = log.lines().rev().take(3).collect();
        return Err(std::io::Error::other(format!(
            "{} did not print the report ({status}){}",
            browser.path.display(),
            if last.is_empty() {
                String::new()
            } else {
                format!(
                    "; it said: {}",
                    last.into_iter().rev().collect::<Vec<_>>().join(" / ")
                )
            }
        )));
    }
    Ok(bytes)
}

/// A `file://` URL of `path` made absolute, every byte but unreserved ones and `/`
/// percent-encoded.
pub fn file_url(path: &Path) -> String {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut url = String::from("file://");
    for b in abs.to_string_lossy().bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'/' | b'-' | b'_' | b'.' | b'~') {
            url.push(b as char);
        } else {
            url.push_str(&format!("%{b:02X}"));
        }
    }
    url
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_urls_are_absolute_and_percent_encoded() {
        assert_eq!(
            file_url(Path::new("/tmp/a b/ré port#1.html")),
            "file:///tmp/a%20b/r%C3%A9%20port%231.html"
        );
        assert!(file_url(Path::new("x.html")).starts_with("file:///"));
    }

    #[cfg(unix)]
    #[test]
    fn the_browser_is_the_variable_or_the_first_name_on_path() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let make = |name: &str, mode: u32| {
            let p = dir.path().join(name);
            std::fs::write(&p, "#!/bin/sh\n").unwrap();
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(mode)).unwrap();
            p
        };
        let path_var = OsString::from(dir.path());
        // Nothing there: the message names every browser and the variable, and says what to install.
        let none = find_browser_in(None, &path_var).unwrap_err();
        for word in BROWSER_NAMES.iter().chain(&[BROWSER_ENV]) {
            assert!(none.message.contains(word), "{}", none.message);
        }
        assert!(none.help.contains("apt-get install chromium"));
        // A file that is not executable does not count; the second name does.
        make("chromium", 0o644);
        let chrome = make("google-chrome", 0o755);
        assert_eq!(find_browser_in(None, &path_var).unwrap().path, chrome);
        // The variable wins, by name on PATH or by path, and a wrong one is named.
        assert_eq!(
            find_browser_in(Some("google-chrome".into()), &path_var)
                .unwrap()
                .path,
            chrome
        );
        assert_eq!(
            find_browser_in(Some(chrome.clone().into()), &OsString::new())
                .unwrap()
                .path,
            chrome
        );
        let wrong = find_browser_in(Some("/no/such/chrome".into()), &path_var).unwrap_err();
        assert!(wrong.message.contains("RSASIM_BROWSER=/no/such/chrome"));
    }
}
