//! A headless Chromium for the whole-program tests (the HTML report printed to PDF, the scene
//! page). Without the browser (or `pdftotext`) a test prints a loud SKIPPED line and returns;
//! under CI (`CI` set) it fails instead: `.ci/run` installs them.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The first executable named `name` on PATH.
pub fn on_path(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// `tool` (a Debian package `package` provides) or, without it, `None` after a SKIPPED line;
/// panics when `CI` is set.
pub fn tool_or_skip(test: &str, tools: &[&str], package: &str) -> Option<PathBuf> {
    if let Some(found) = tools.iter().find_map(|t| on_path(t)) {
        return Some(found);
    }
    super::skip(&format!(
        "{test} (needs {}: apt-get install {package})",
        tools.join(" or ")
    ));
    None
}

/// The browser and `pdftotext`, or `None` (skipped).
pub fn chromium_or_skip(test: &str) -> Option<PathBuf> {
    tool_or_skip(
        test,
        &["chromium", "chromium-browser", "google-chrome"],
        "chromium",
    )
}

/// Runs the browser headless once on the local file `page` with `args` (e.g.
/// `--screenshot=…`), console messages logged: returns the lines of the page's console
/// (messages, uncaught errors), which a clean page leaves empty. Panics when the browser fails.
pub fn run_headless(browser: &Path, page: &Path, args: &[String]) -> Vec<String> {
    let profile = tempfile::tempdir().unwrap();
    let url = format!("file://{}", std::path::absolute(page).unwrap().display());
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .args(args)
        .arg(&url)
        .output()
        .expect("the browser starts");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "{} failed:\n{stderr}",
        browser.display()
    );
    stderr
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(str::to_string)
        .collect()
}

/// A screenshot decoded: width, height and RGB of every pixel.
pub struct Screenshot {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    rgb: Vec<[u8; 3]>,
}

impl Screenshot {
    /// The colour of pixel (x, y).
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        self.rgb[y * self.width as usize + x]
    }
}

/// Runs the browser headless on `page` in a `width` × `height` window (no scroll bars) and
/// returns the page's console lines ([`run_headless`]) and the screenshot, decoded.
pub fn screenshot(
    browser: &Path,
    page: &Path,
    width: u32,
    height: u32,
) -> (Vec<String>, Screenshot) {
    let tmp = tempfile::tempdir().unwrap();
    let shot = tmp.path().join("shot.png");
    let console = run_headless(
        browser,
        page,
        &[
            format!("--window-size={width},{height}"),
            "--hide-scrollbars".to_string(),
            format!("--screenshot={}", shot.display()),
        ],
    );
    let mut reader =
        png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()))
            .read_info()
            .unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.line_size / info.width as usize;
    let rgb = (0..info.height as usize)
        .flat_map(|y| (0..info.width as usize).map(move |x| (x, y)))
        .map(|(x, y)| {
            let at = y * info.line_size + x * channels;
            [buf[at], buf[at + 1], buf[at + 2]]
        })
        .collect();
    (
        console,
        Screenshot {
            width: info.width,
            height: info.height,
            rgb,
        },
    )
}
