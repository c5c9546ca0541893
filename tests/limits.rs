//! Resource limits: what a scenario costs is known and capped before anything runs, `validate`
//! says what a run will write, `expand` streams, and echoed user text is bounded.

use crate::common;

use common::rsasim;

/// A small valid scenario (one bead, one 64 × 64 detector, two runs).
const BASE: &str = r#"name = "limits"
seed = 1

[protocol]
noise_levels = [0.0, 0.5]
runs_per_level = 1

[output]
formats = ["tiff", "exr"]

[[sources]]
id = "tube1"
position_mm = [0.0, 0.0, 1000.0]

[[detectors]]
id = "det1"
source = "tube1"
pixels = [64, 64]
size_mm = [200.0, 200.0]
bpp = 12
position_mm = [0.0, 0.0, -300.0]

[[phantoms]]
id = "beads"
randomize.position_mm = [5.0, 5.0, 5.0]

[[phantoms.beads]]
id = "B1"
position_mm = [10.0, 0.0, 0.0]

[[exposures]]
id = "calibration"
phantoms = ["beads"]
"#;

/// Runs rsasim with `args` where `SCENARIO` is replaced by the path of `text` written to a
/// temporary folder; returns exit code, stdout and stderr.
fn with_scenario(text: &str, args: &[&str]) -> (Option<i32>, String, String) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("s.toml");
    std::fs::write(&file, text).unwrap();
    let out = dir.path().join("out");
    let args: Vec<String> = args
        .iter()
        .map(|a| {
            a.replace("SCENARIO", file.to_str().unwrap())
                .replace("OUT", out.to_str().unwrap())
        })
        .collect();
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = rsasim(&args, &[]);
    assert!(!out.exists(), "something was written");
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn validate_says_what_a_run_will_write_and_use() {
    let (code, _, stderr) = with_scenario(BASE, &["validate", "SCENARIO"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("valid: 2 runs, 2 images per format, at most ")
            && stderr.contains("on disk (tiff ")
            && stderr.contains("of memory with "),
        "{stderr}"
    );
}

#[test]
fn a_runs_typo_is_refused_at_once_with_the_override_named() {
    let text = BASE.replace("runs_per_level = 1", "runs_per_level = 1000000000");
    for args in [
        vec!["validate", "SCENARIO"],
        vec!["expand", "SCENARIO"],
        vec!["SCENARIO", "--out", "OUT"],
    ] {
        let start = std::time::Instant::now();
        let (code, stdout, stderr) = with_scenario(&text, &args);
        assert_eq!(code, Some(2), "{args:?}: {stderr}");
        assert!(stdout.is_empty(), "{args:?}");
        assert!(
            stderr.contains("the protocol has 2000000000 runs")
                && stderr.contains("s.toml:6:18")
                && stderr.contains("--allow-large"),
            "{args:?}: {stderr}"
        );
        assert!(start.elapsed().as_secs() < 20, "{args:?} took too long");
    }
}

#[test]
fn the_schemas_largest_detector_is_refused_before_it_runs() {
    let huge = BASE.replace("pixels = [64, 64]", "pixels = [65535, 65535]");
    // As TIFF it cannot be written at all, --allow-large or not.
    for args in [
        vec!["validate", "SCENARIO"],
        vec!["validate", "SCENARIO", "--allow-large"],
        vec!["SCENARIO", "--out", "OUT", "--allow-large"],
    ] {
        let (code, _, stderr) = with_scenario(&huge, &args);
        assert_eq!(code, Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("more than the 4 GiB a classic TIFF file can hold"),
            "{stderr}"
        );
    }
    // As EXR: beyond the pixel cap, and (where the machine's memory is known) beyond it.
    let exr = huge.replace("formats = [\"tiff\", \"exr\"]", "formats = [\"exr\"]");
    let (code, _, stderr) = with_scenario(&exr, &["validate", "SCENARIO"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("4295 megapixels per image, more than the cap of 100 megapixels")
            && stderr.contains("pass --allow-large"),
        "{stderr}"
    );
    if rsasim::cost::available_memory_bytes().is_some_and(|m| m < 100_000_000_000) {
        assert!(
            stderr.contains("the simulation needs about ") && stderr.contains("available"),
            "{stderr}"
        );
    }
}

#[test]
fn an_uncompressed_tiff_over_4_gib_is_refused_before_the_encoder_fails() {
    let text = BASE
        .replace("pixels = [64, 64]", "pixels = [46341, 46341]")
        .replace("[output]\n", "[output]\ntiff_compression = \"none\"\n");
    let (code, _, stderr) = with_scenario(&text, &["SCENARIO", "--out", "OUT", "--allow-large"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("4 GiB"), "{stderr}");
}

#[test]
fn expand_streams_the_same_json_as_the_whole_array() {
    let path = common::root().join("scenarios/golden/small_biplanar.toml");
    let o = rsasim(&["expand", path.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let plan = rsasim::simulate::prepare(&path).unwrap();
    let whole = serde_json::to_string_pretty(&plan.runs).unwrap() + "\n";
    assert_eq!(String::from_utf8_lossy(&o.stdout), whole);
}

#[test]
fn many_runs_validate_run_by_run() {
    // 40,000 runs: checked one at a time, never held together.
    let text = BASE.replace("runs_per_level = 1", "runs_per_level = 20000");
    let (code, _, stderr) = with_scenario(&text, &["validate", "SCENARIO"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("valid: 40000 runs, 40000 images"),
        "{stderr}"
    );
}

#[test]
fn a_600_kb_line_is_not_echoed_whole() {
    let long = "x".repeat(600_000);
    let text = BASE.replace("name = \"limits\"", &format!("name = \"{long}\""));
    let (code, _, stderr) = with_scenario(&text, &["validate", "SCENARIO"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.len() < 3_000, "{} bytes of errors", stderr.len());
    assert!(
        stderr.contains("more bytes)") && stderr.contains("is 600000 bytes long"),
        "{stderr}"
    );
    // A parse error on a long line: the excerpt is cut too.
    let text = BASE.replace(
        "seed = 1",
        &format!("seed = [{}\"x\"", "1, ".repeat(200_000)),
    );
    let (code, _, stderr) = with_scenario(&text, &["validate", "SCENARIO"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.len() < 3_000, "{} bytes of errors", stderr.len());
}

/// Runs rsasim with `args` (and `RAYON_NUM_THREADS=2`) and returns its exit status and its peak
/// resident set, bytes: the kernel's high-water mark of the run's own address space (`VmHWM` in
/// `/proc/<pid>/status`), read every millisecond until the process ends. (`wait4`'s
/// `ru_maxrss` would not do: it keeps the resident set the child inherited from this test
/// process before its exec, which is large when many tests run at once.) The last reading is a
/// lower bound of the peak, missing at most the last millisecond.
#[cfg(target_os = "linux")]
fn peak_rss_bytes(args: &[&str]) -> (i32, u64) {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_rsasim"))
        .args(args)
        .current_dir(common::root())
        .env("RAYON_NUM_THREADS", "2")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let status_file = format!("/proc/{}/status", child.id());
    let mut peak_kib = 0u64;
    loop {
        if let Ok(text) = std::fs::read_to_string(&status_file)
            && let Some(kib) = text
                .lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        {
            peak_kib = peak_kib.max(kib);
        }
        if let Some(status) = child.try_wait().unwrap() {
            return (status.code().unwrap_or(-1), peak_kib * 1024);
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

/// `validate`'s "about N MB of memory" as bytes (its units are powers of 1000, as it prints).
fn estimated_memory_bytes(validate_said: &str) -> u64 {
    let (_, rest) = validate_said.split_once("about ").unwrap();
    let mut words = rest.split_whitespace();
    let number: f64 = words.next().unwrap().parse().unwrap();
    let unit = match words.next().unwrap() {
        "kB" | "KB" => 1e3,
        "MB" => 1e6,
        "GB" => 1e9,
        u => panic!("unit {u}"),
    };
    (number * unit) as u64
}

/// The memory `validate` announces bounds what a run takes: the kernel's high-water mark of the
/// run's resident set, on two threads, for a golden scenario and for one large image.
#[cfg(target_os = "linux")]
#[test]
fn the_memory_estimate_bounds_the_measured_peak() {
    let tmp = tempfile::tempdir().unwrap();
    let large = tmp.path().join("large.toml");
    std::fs::write(
        &large,
        BASE.replace("pixels = [64, 64]", "pixels = [2000, 2000]")
            .replace("noise_levels = [0.0, 0.5]", "noise_levels = [0.5]"),
    )
    .unwrap();
    let golden = common::root().join("scenarios/golden/small_biplanar.toml");
    for scenario in [golden, large] {
        let scenario = scenario.to_str().unwrap();
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_rsasim"))
            .args(["validate", scenario])
            .current_dir(common::root())
            .env("RAYON_NUM_THREADS", "2")
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // validate reports on standard error.
        let said = String::from_utf8_lossy(&o.stderr);
        assert!(said.contains("with 2 threads"), "{said}");
        let estimate = estimated_memory_bytes(&said);
        let out = tmp.path().join("out");
        let (code, peak) = peak_rss_bytes(&[scenario, "--out", out.to_str().unwrap()]);
        assert_eq!(code, 0, "{scenario}");
        std::fs::remove_dir_all(&out).unwrap();
        eprintln!("{scenario}: peak {peak} B, estimated {estimate} B");
        assert!(peak > 1_000_000, "a run takes more than 1 MB: {peak}");
        assert!(
            peak <= estimate,
            "{scenario}: peak {peak} B above the estimate {estimate} B"
        );
    }
}
