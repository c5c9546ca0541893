//! `rsasim evaluate` end to end: measured files with known errors give exactly those truenesses
//! and precisions; bad results are clear errors with exit code 2.

use crate::common;

use std::path::PathBuf;

use common::{report_dir, rsasim, run_scenario, truths};
use rsasim::evaluate::stats::{Cell, Confidence, Significance};
use rsasim::evaluate::table::{Report, Table};
use rsasim::evaluate::{MeasuredSource, Options, evaluate};
use rsasim::geometry::{DMat3, rotation_from_rows, rotation_rows, rotation_xyz_deg};
use rsasim::output::Truth;
use rsasim::output::measured::{Measured, MeasuredPoint, MeasuredPose};

fn rows(m: DMat3) -> [[f64; 3]; 3] {
    rotation_rows(&m)
}

/// A simulated output folder (tiny images, 2 levels × 20 runs) in a temporary directory.
fn simulated() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("eval");
    run_scenario("tests/scenarios/evaluate.toml", &out, &[]);
    (tmp, out)
}

/// A deterministic standard normal sample per run (Box–Muller over a simple LCG): scatter of known SD.
fn normal(k: u64) -> f64 {
    let lcg = |x: u64| {
        x.wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407)
    };
    let (a, b) = (lcg(k + 1), lcg(lcg(k + 1)));
    let (u1, u2) = (
        ((a >> 11) as f64 + 1.0) / (1u64 << 53) as f64,
        (b >> 11) as f64 / (1u64 << 53) as f64,
    );
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// The truth, with: det1 moved +0.10 mm along its s axis; the femur turned +0.5° about z;
/// tube2 scattered along its beamline's r with SD 0.2 mm; everything else exact.
fn measured_with_known_errors(truth: &Truth, k: usize) -> Measured {
    let run = &truth.run;
    let det2 = run.detectors.iter().find(|d| d.id == "det2").unwrap();
    Measured {
        format: "rsasim-measured/1".into(),
        run: run.id.clone(),
        software: "known-errors 1.0".into(),
        methods: None,
        sources: run
            .sources
            .iter()
            .map(|s| {
                let p = if s.id == "tube2" {
                    s.position_mm + det2.rotation.x_axis * (0.2 * normal(k as u64))
                } else {
                    s.position_mm
                };
                MeasuredPoint {
                    id: s.id.clone(),
                    position_mm: p.to_array(),
                    quality: None,
                }
            })
            .collect(),
        detectors: run
            .detectors
            .iter()
            .map(|d| {
                let p = if d.id == "det1" {
                    d.position_mm + d.rotation.z_axis * 0.10
                } else {
                    d.position_mm
                };
                MeasuredPose {
                    id: d.id.clone(),
                    position_mm: p.to_array(),
                    rotation: Some(rows(d.rotation)),
                    markers: vec![],
                    quality: None,
                }
            })
            .collect(),
        phantoms: run
            .phantoms
            .iter()
            .filter(|p| p.kind != "calibration_box")
            .map(|p| MeasuredPose {
                id: p.id.clone(),
                position_mm: p.position_mm.to_array(),
                rotation: Some(rows(rotation_xyz_deg([0.0, 0.0, 0.5]) * p.rotation)),
                markers: vec![],
                quality: None,
            })
            .collect(),
    }
}

fn table<'a>(r: &'a Report, id: &str) -> &'a Table {
    r.tables
        .iter()
        .find(|t| t.id == id)
        .unwrap_or_else(|| panic!("no table {id}"))
}

fn cell(t: &Table, level: usize, group: &str, column: &str) -> Cell {
    let mut k = 0;
    for g in &t.groups {
        for c in &g.columns {
            if g.label.starts_with(group) && c.label == column {
                return t.rows[level].cells[k].clone().unwrap();
            }
            k += 1;
        }
    }
    panic!("no column {group}/{column} in {}", t.id)
}

/// `rsasim evaluate`'s defaults, reading `measured.json` in every run folder.
pub(crate) fn options() -> Options {
    Options {
        measured: MeasuredSource::PerRun("measured.json".into()),
        confidence: Confidence::default(),
        mtpm_threshold_mm: rsasim::evaluate::DEFAULT_MTPM_THRESHOLD_MM,
        study: Default::default(),
        xmalab_2d: Default::default(),
        source_truth: Default::default(),
    }
}

#[test]
fn tables_show_exactly_the_known_errors() {
    let (_tmp, out) = simulated();
    let mut scatter: Vec<Vec<f64>> = vec![vec![], vec![]];
    let mut mtpm_by_hand: Vec<Vec<f64>> = vec![vec![], vec![]];
    let turn = rotation_xyz_deg([0.0, 0.0, 0.5]);
    for (k, (dir, truth)) in truths(&out).iter().enumerate() {
        std::fs::write(
            dir.join("measured.json"),
            serde_json::to_vec_pretty(&measured_with_known_errors(truth, k)).unwrap(),
        )
        .unwrap();
        let level = truth.run.noise_level_index as usize;
        scatter[level].push(0.2 * normal(k as u64));
        // Each bead moves by (Rz(0.5°) − I)·(x − t): the largest such move is the run's MTPM.
        let femur = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
        let moves = femur.markers.iter().map(|m| {
            (turn * (m.position_mm - femur.position_mm) - (m.position_mm - femur.position_mm))
                .length()
        });
        mtpm_by_hand[level].push(moves.fold(0.0, f64::max));
    }
    let report = evaluate(&out, &options()).unwrap_or_else(|e| panic!("{e:?}"));
    assert_eq!(report.runs_scored, 40);
    assert!(report.excluded.is_empty(), "{:?}", report.excluded);
    for level in 0..2 {
        // Detector 1: +0.10 mm along s, exactly, and nothing else.
        let det1 = table(&report, "detector-det1");
        let s = cell(det1, level, "position", "s");
        assert_eq!(s.n, 20);
        assert!(
            (s.trueness - 0.10).abs() < 1e-9 && s.precision < 1e-9,
            "{s:?}"
        );
        assert_eq!(s.significance, Significance::Positive);
        for c in ["r", "c"] {
            assert!(cell(det1, level, "position", c).trueness.abs() < 1e-9);
        }
        // The femur: +0.5° about z (γ), nothing else.
        let femur = table(&report, "phantom-femur");
        let g = cell(femur, level, "orientation", "γ");
        assert!(
            (g.trueness - 0.5).abs() < 1e-9 && g.precision < 1e-9,
            "{g:?}"
        );
        assert!(cell(femur, level, "orientation", "α").trueness.abs() < 1e-9);
        assert!(cell(femur, level, "position", "x").trueness.abs() < 1e-9);
        // Tube 2: the scatter's own mean and τ·s/√N, by hand.
        let v = &scatter[level];
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let r = cell(table(&report, "sources"), level, "tube2", "r");
        assert!((r.trueness - mean).abs() < 1e-9, "{} vs {mean}", r.trueness);
        assert!(
            (r.precision - 1.729133 * sd / n.sqrt()).abs() < 1e-6,
            "{} vs {}",
            r.precision,
            1.729133 * sd / n.sqrt()
        );
        assert!((0.1..0.3).contains(&sd), "scatter SD {sd}");
        assert!(
            cell(table(&report, "sources"), level, "tube2", "s")
                .trueness
                .abs()
                < 1e-9
        );
        // MTPM over the femur's beads, by hand.
        let mtpm = cell(report.mtpm.as_ref().unwrap(), level, "femur", "MTPM");
        let want = mtpm_by_hand[level].iter().sum::<f64>() / 20.0;
        assert!(
            (mtpm.trueness - want).abs() < 1e-9 && want > 0.1,
            "{mtpm:?} vs {want}"
        );
    }
    // The group analysis of det1 s: every group identical → no between-level variance.
    let a = report
        .group_analyses
        .iter()
        .find(|g| g.table == "detector-det1" && g.parameter == "position: s")
        .unwrap();
    assert!(a.analysis.s_l.abs() < 1e-9);
    // Two sources have r, c, s columns: each parameter is named by its group.
    assert!(
        report
            .group_analyses
            .iter()
            .any(|g| g.parameter == "tube2 (beamline det2): r")
    );
}

#[test]
fn missing_runs_are_excluded_and_n_follows() {
    let (_tmp, out) = simulated();
    for (k, (dir, truth)) in truths(&out).iter().enumerate() {
        // Level 1 loses 5 runs; one run of level 0 omits detector det2.
        if truth.run.noise_level_index == 1 && truth.run.run_index < 5 {
            continue;
        }
        let mut m = measured_with_known_errors(truth, k);
        if truth.run.id == "n0-r03" {
            m.detectors.retain(|d| d.id != "det2");
        }
        std::fs::write(
            dir.join("measured.json"),
            serde_json::to_vec_pretty(&m).unwrap(),
        )
        .unwrap();
    }
    let report = evaluate(&out, &options()).unwrap();
    assert_eq!(report.runs_scored, 35);
    assert_eq!(
        report
            .excluded
            .iter()
            .filter(|e| e.reason.contains("no measurement"))
            .count(),
        5
    );
    assert!(
        report
            .excluded
            .iter()
            .any(|e| e.run == "n0-r03" && e.reason.contains("detector det2"))
    );
    let s = cell(table(&report, "detector-det1"), 1, "position", "s");
    assert_eq!(s.n, 15);
    assert!(
        (s.tau - 1.761310).abs() < 1e-5,
        "τ for N = 15 is t(0.95; 14) = 1.7613, got {}",
        s.tau
    );
    assert_eq!(
        cell(table(&report, "detector-det2"), 0, "position", "s").n,
        19
    );
}

#[test]
fn a_csv_long_table_gives_the_same_report_as_json_files() {
    let (tmp, out) = simulated();
    let mut csv = String::from("run,kind,id,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    for (k, (dir, truth)) in truths(&out).iter().enumerate() {
        let m = measured_with_known_errors(truth, k);
        std::fs::write(
            dir.join("measured.json"),
            serde_json::to_vec_pretty(&m).unwrap(),
        )
        .unwrap();
        for s in &m.sources {
            let p = s.position_mm;
            csv += &format!("{},source,{},{},{},{},,,,\n", m.run, s.id, p[0], p[1], p[2]);
        }
        for (kind, list) in [("detector", &m.detectors), ("phantom", &m.phantoms)] {
            for e in list {
                let r = e.rotation.unwrap();
                let mat = rotation_from_rows(r);
                let q = glam::DQuat::from_mat3(&mat);
                let p = e.position_mm;
                csv += &format!(
                    "{},{kind},{},{},{},{},{},{},{},{}\n",
                    m.run, e.id, p[0], p[1], p[2], q.w, q.x, q.y, q.z
                );
            }
        }
    }
    let file = tmp.path().join("results.csv");
    std::fs::write(&file, csv).unwrap();
    let from_json = evaluate(&out, &options()).unwrap();
    let from_csv = evaluate(
        &out,
        &Options {
            measured: MeasuredSource::Csv(file),
            ..options()
        },
    )
    .unwrap();
    for (a, b) in from_json.tables.iter().zip(&from_csv.tables) {
        for (ra, rb) in a.rows.iter().zip(&b.rows) {
            for (ca, cb) in ra.cells.iter().zip(&rb.cells) {
                let (ca, cb) = (ca.as_ref().unwrap(), cb.as_ref().unwrap());
                assert!(
                    (ca.trueness - cb.trueness).abs() < 1e-9
                        && (ca.precision - cb.precision).abs() < 1e-9,
                    "{}",
                    a.id
                );
            }
        }
    }
}

/// Writes `m` as `dir/measured.json`.
fn write_measured(dir: &std::path::Path, m: &Measured) {
    std::fs::write(
        dir.join("measured.json"),
        serde_json::to_vec_pretty(m).unwrap(),
    )
    .unwrap()
}

/// (what is broken, how, expected message part, expected field or line marker)
#[test]
fn bad_results_are_named_by_file_line_and_field() {
    let (tmp, out) = simulated();
    let all = truths(&out);
    let (dir, truth) = &all[0];
    let good = measured_with_known_errors(truth, 0);
    let write = |m: &Measured| write_measured(dir, m);
    let run_json = |expect: &[&str]| {
        let o = rsasim(&["evaluate", out.to_str().unwrap()], &[]);
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{stderr}");
        for e in expect {
            assert!(stderr.contains(e), "expected `{e}` in:\n{stderr}");
        }
    };
    // A rotation that is not orthonormal: the deviation is named.
    let mut m = good.clone();
    m.detectors[1].rotation.as_mut().unwrap()[0][0] += 0.01;
    write(&m);
    run_json(&[
        "measured.json:50:",
        "`detectors[1].rotation`",
        "not orthonormal: max |RᵀR − I| = 9.999e-3",
    ]);
    // An unknown entity id.
    let mut m = good.clone();
    m.detectors[0].id = "det9".into();
    write(&m);
    run_json(&[
        "`detectors[0].id`",
        "no detector has the id `det9`",
        "valid detector ids: det1, det2",
    ]);
    // A run id that does not match its folder.
    let mut m = good.clone();
    m.run = "n9-r99".into();
    write(&m);
    run_json(&["`run`", "n9-r99"]);
    // Malformed JSON: line and column.
    std::fs::write(
        dir.join("measured.json"),
        b"{\n  \"format\": \"rsasim-measured/1\",\n  \"run\": 3\n}",
    )
    .unwrap();
    run_json(&["measured.json:3:", "invalid JSON"]);
    std::fs::remove_file(dir.join("measured.json")).unwrap();

    // CSV: a NaN, an unknown run, a bad row, a missing file.
    let csv = |body: &str, expect: &[&str]| {
        let file = tmp.path().join("r.csv");
        std::fs::write(&file, format!("run,kind,id,x_mm,y_mm,z_mm\n{body}")).unwrap();
        let o = rsasim(
            &[
                "evaluate",
                out.to_str().unwrap(),
                "--csv",
                file.to_str().unwrap(),
            ],
            &[],
        );
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{stderr}");
        for e in expect {
            assert!(stderr.contains(e), "expected `{e}` in:\n{stderr}");
        }
    };
    csv(
        "n0-r00,source,tube1,1,2,NaN\n",
        &["r.csv:2:", "`z_mm`", "not a finite number"],
    );
    csv(
        "n0-r00,source,tube1,1,2,3\nn7-r00,source,tube1,1,2,3\n",
        &["r.csv:3:", "`run`", "no run `n7-r00`"],
    );
    csv("n0-r00,source,tube1,1,2\n", &["r.csv:2:", "malformed row"]);
    csv(
        "n0-r00,camera,tube1,1,2,3\n",
        &["r.csv:2:", "`kind`", "unknown kind `camera`"],
    );
    let o = rsasim(
        &[
            "evaluate",
            out.to_str().unwrap(),
            "--csv",
            "/nonexistent/r.csv",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("/nonexistent/r.csv"));
}

#[test]
fn the_command_writes_every_report_format() {
    let (tmp, out) = simulated();
    for (k, (dir, truth)) in truths(&out).iter().enumerate() {
        std::fs::write(
            dir.join("measured.json"),
            serde_json::to_vec_pretty(&measured_with_known_errors(truth, k)).unwrap(),
        )
        .unwrap();
    }
    let report = tmp.path().join("rep");
    let o = rsasim(
        &[
            "evaluate",
            out.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "report.md",
        "report.csv",
        "report.tex",
        "report.html",
        "iso5725.csv",
    ] {
        assert!(report.join(f).is_file(), "{f} missing");
    }
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    // det1's +0.10 mm along s is a significant positive cell: "0.10 ± 0" marked ▲.
    assert!(md.contains("**0.10 ± 0** ▲"), "{md}");
    let tex = std::fs::read_to_string(report.join("report.tex")).unwrap();
    assert!(tex.contains(r"\cellcolor{red!25}"));
    // Default folder, chosen formats, two-sided τ.
    let o = rsasim(
        &[
            "evaluate",
            out.to_str().unwrap(),
            "--format",
            "md,html",
            "--sided",
            "two",
        ],
        &[],
    );
    assert!(o.status.success());
    // The default folder is named after the results file, so two softwares' reports never mix.
    let folder = out.join("report-measured");
    assert!(folder.join("report.html").is_file() && !folder.join("report.tex").exists());
    let md = std::fs::read_to_string(folder.join("report.md")).unwrap();
    assert!(
        md.contains("**Software under test:** known-errors 1.0"),
        "{md}"
    );
    assert!(md.contains("**Results file:** measured.json"), "{md}");
    let o = rsasim(
        &["evaluate", out.to_str().unwrap(), "--format", "docx"],
        &[],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("valid formats"));
    // PDF without a browser: exit 2 before anything is written, saying what to install.
    let pdf_dir = tmp.path().join("pdf");
    let (code, stderr) = evaluate_cli_env(
        &out,
        &[
            "--format",
            "html,pdf",
            "--report",
            pdf_dir.to_str().unwrap(),
        ],
        &[("RSASIM_BROWSER", "/no/such/chromium")],
    );
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("RSASIM_BROWSER=/no/such/chromium")
            && stderr.contains("apt-get install chromium"),
        "{stderr}"
    );
    assert!(!pdf_dir.exists());
}

/// Words of the HTML tables (not the facts table, whose hash wraps anywhere): tags become
/// spaces, entities are decoded.
fn table_words(html: &str) -> Vec<String> {
    let mut words = Vec::new();
    for table in html.split("<table").skip(1) {
        if table.starts_with(" class=\"facts\"") {
            continue;
        }
        let body = &table[..table.find("</table>").unwrap()];
        let body = &body[body.find('>').unwrap() + 1..];
        let mut text = String::new();
        let mut in_tag = false;
        for ch in body.chars() {
            match ch {
                '<' => in_tag = true,
                '>' => {
                    in_tag = false;
                    text.push(' ');
                }
                _ if !in_tag => text.push(ch),
                _ => {}
            }
        }
        let text = text
            .replace("&gt;", ">")
            .replace("&lt;", "<")
            .replace("&quot;", "\"")
            .replace("&#39;", "'")
            .replace("&amp;", "&");
        words.extend(text.split_whitespace().map(str::to_string));
    }
    words
}

/// Every word of the PDF with its page width: `(word, xMin, xMax, page width)` from
/// `pdftotext -bbox`.
fn pdf_words(pdftotext: &std::path::Path, pdf: &std::path::Path) -> Vec<(String, f64, f64, f64)> {
    let o = std::process::Command::new(pdftotext)
        .args(["-bbox", pdf.to_str().unwrap(), "-"])
        .output()
        .unwrap();
    assert!(o.status.success());
    let text = String::from_utf8(o.stdout).unwrap();
    let attr = |tag: &str, name: &str| -> f64 {
        let at = tag.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        tag[at..at + tag[at..].find('"').unwrap()].parse().unwrap()
    };
    let mut width = 0.0;
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with("<page ") {
            width = attr(line, "width");
        } else if let Some(rest) = line.strip_prefix("<word ") {
            let close = rest.find('>').unwrap();
            let word = rest[close + 1..rest.rfind("</word>").unwrap()]
                .replace("&gt;", ">")
                .replace("&lt;", "<")
                .replace("&quot;", "\"")
                .replace("&amp;", "&");
            out.push((word, attr(rest, "xMin"), attr(rest, "xMax"), width));
        }
    }
    out
}

#[test]
fn the_report_prints_to_pdf_with_every_column_on_the_page() {
    let test = "the_report_prints_to_pdf_with_every_column_on_the_page";
    let Some(browser) = common::browser::chromium_or_skip(test) else {
        return;
    };
    let Some(pdftotext) = common::browser::tool_or_skip(test, &["pdftotext"], "poppler-utils")
    else {
        return;
    };
    let (tmp, out) = simulated();
    write_all(&out, "measured.json", &|m| m);
    let report = tmp.path().join("rep");
    let (code, stderr) = evaluate_cli_env(
        &out,
        &["--format", "html,pdf", "--report", report.to_str().unwrap()],
        &[("RSASIM_BROWSER", browser.to_str().unwrap())],
    );
    assert_eq!(code, Some(0), "{stderr}");
    let pdf = report.join("report.pdf");
    assert!(std::fs::read(&pdf).unwrap().starts_with(b"%PDF-"));
    // Every word lies on its page (a column cut off at the right edge would not), and every
    // word of every table (headings, cells: all columns) is in the PDF.
    let words = pdf_words(&pdftotext, &pdf);
    assert!(words.len() > 500, "{}", words.len());
    for (w, x0, x1, width) in &words {
        assert!(
            *x0 >= 0.0 && *x1 <= *width,
            "{w} at {x0}..{x1} of {width} pt"
        );
    }
    let html = std::fs::read_to_string(report.join("report.html")).unwrap();
    let printed: std::collections::BTreeSet<&str> = words.iter().map(|w| w.0.as_str()).collect();
    let expected = table_words(&html);
    assert!(expected.len() > 500, "{}", expected.len());
    for heading in ["max", "Mandel", "k", "Grubbs", "verdict", "(within)"] {
        assert!(expected.iter().any(|w| w == heading), "{heading}");
    }
    let missing: Vec<&String> = expected
        .iter()
        .filter(|w| !printed.contains(w.as_str()))
        .collect();
    assert!(missing.is_empty(), "not in the PDF: {missing:?}");
    // The page loads in the browser without a console message (one more launch).
    let console = common::browser::run_headless(
        &browser,
        &report.join("report.html"),
        &["--dump-dom".to_string()],
    );
    assert!(console.is_empty(), "{console:?}");
}

#[test]
fn a_folder_that_is_not_an_output_folder_is_named_as_such() {
    let tmp = tempfile::tempdir().unwrap();
    for cmd in ["evaluate", "reconstruct"] {
        let o = rsasim(&[cmd, tmp.path().to_str().unwrap()], &[]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {stderr}");
        assert!(
            stderr.contains(
                "not an rsasim output folder: scenario.toml, manifest.json, runs missing"
            ),
            "{cmd}: {stderr}"
        );
        assert!(stderr.contains("--out DIR"), "{cmd}: {stderr}");
    }
}

/// Writes every run's known-error results as `name`, with `edit` applied to each file's text.
fn write_all(out: &std::path::Path, name: &str, edit: &dyn Fn(Measured) -> Measured) {
    for (k, (dir, truth)) in truths(out).iter().enumerate() {
        let m = edit(measured_with_known_errors(truth, k));
        std::fs::write(dir.join(name), serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    }
}

/// Runs `rsasim evaluate OUT args…` and returns (exit code, stderr).
fn evaluate_cli(out: &std::path::Path, args: &[&str]) -> (Option<i32>, String) {
    evaluate_cli_env(out, args, &[])
}

/// [`evaluate_cli`] with extra environment.
fn evaluate_cli_env(
    out: &std::path::Path,
    args: &[&str],
    env: &[(&str, &str)],
) -> (Option<i32>, String) {
    let mut all = vec!["evaluate", out.to_str().unwrap()];
    all.extend(args);
    let o = rsasim(&all, env);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn round6(rows: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    rows.map(|r| r.map(|x| (x * 1e6).round() / 1e6))
}

#[test]
fn rotations_rounded_to_six_decimals_are_repaired_and_counted() {
    let (_tmp, out) = simulated();
    let expected = std::cell::Cell::new(0);
    write_all(&out, "measured.json", &|mut m| {
        for e in m.detectors.iter_mut().chain(m.phantoms.iter_mut()) {
            let r = e.rotation.unwrap();
            if round6(r) != r {
                expected.set(expected.get() + 1);
            }
            e.rotation = Some(round6(r));
        }
        m
    });
    assert!(expected.get() > 40, "{}", expected.get());
    let exact = evaluate(&out, &options());
    let report = exact.unwrap_or_else(|e| panic!("rounded rotations rejected: {e:?}"));
    assert_eq!(report.repaired_rotations, expected.get());
    // The command says so on stderr and in the report.
    let (code, stderr) = evaluate_cli(&out, &["--format", "md"]);
    assert_eq!(code, Some(0), "{stderr}");
    let said = format!(
        "note: {} rotation(s) were re-orthonormalised",
        expected.get()
    );
    assert!(stderr.contains(&said), "{stderr}");
    let md = std::fs::read_to_string(out.join("report-measured/report.md")).unwrap();
    assert!(
        md.contains(&format!(
            "**Rotations re-orthonormalised:** {}",
            expected.get()
        )),
        "{md}"
    );
    // Quaternions rounded to 6 decimals in a CSV are repaired too.
    let mut csv = String::from("run,kind,id,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    for (k, (_, truth)) in truths(&out).iter().enumerate() {
        let m = measured_with_known_errors(truth, k);
        for e in &m.phantoms {
            let q = glam::DQuat::from_mat3(&rotation_from_rows(e.rotation.unwrap()));
            let p = e.position_mm;
            csv += &format!(
                "{},phantom,{},{},{},{},{:.6},{:.6},{:.6},{:.6}\n",
                m.run, e.id, p[0], p[1], p[2], q.w, q.x, q.y, q.z
            );
        }
    }
    let file = out.join("q.csv");
    std::fs::write(&file, csv).unwrap();
    let (code, stderr) = evaluate_cli(&out, &["--csv", file.to_str().unwrap(), "--format", "md"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("rotation(s) were re-orthonormalised"),
        "{stderr}"
    );
}

#[test]
fn duplicates_implausible_values_and_long_values_are_errors_naming_the_place() {
    let (tmp, out) = simulated();
    let all = truths(&out);
    let (dir, truth) = &all[0];
    let good = measured_with_known_errors(truth, 0);
    let write = |m: &Measured| write_measured(dir, m);
    let expect = |args: &[&str], parts: &[&str]| {
        let (code, stderr) = evaluate_cli(&out, args);
        assert_eq!(code, Some(2), "{stderr}");
        for p in parts {
            assert!(stderr.contains(p), "expected `{p}` in:\n{stderr}");
        }
        assert!(!out.join("report-measured").exists() && !out.join("report-r").exists());
        stderr
    };
    // The same phantom twice in one measured.json: both lines named.
    let mut m = good.clone();
    let mut second = m.phantoms[0].clone();
    second.position_mm[0] += 1.0;
    m.phantoms.push(second);
    write(&m);
    let text = std::fs::read_to_string(dir.join("measured.json")).unwrap();
    let id_lines: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.contains(&format!("\"id\": \"{}\"", m.phantoms[0].id)))
        .map(|(i, _)| i + 1)
        .collect();
    assert_eq!(id_lines.len(), 2, "{text}");
    expect(
        &[],
        &[
            "repeats the id `femur`",
            &format!("line {} and line {}", id_lines[0], id_lines[1]),
        ],
    );
    // A position of 1e308 mm: refused, naming the field (it made inf cells and NaN rows).
    let mut m = good.clone();
    m.phantoms[0].position_mm[2] = 1e308;
    write(&m);
    expect(&[], &["`phantoms[0].position_mm`", "implausible", "1e308"]);
    // A UTF-8 byte-order mark (PowerShell, .NET) is accepted.
    let mut bytes = vec![0xef, 0xbb, 0xbf];
    bytes.extend(serde_json::to_vec_pretty(&good).unwrap());
    std::fs::write(dir.join("measured.json"), bytes).unwrap();
    let (code, stderr) = evaluate_cli(&out, &["--format", "md"]);
    assert_eq!(code, Some(0), "a BOM was refused: {stderr}");
    std::fs::remove_file(dir.join("measured.json")).unwrap();
    std::fs::remove_dir_all(out.join("report-measured")).unwrap();

    let csv = |body: &[u8], parts: &[&str]| -> String {
        let file = tmp.path().join("r.csv");
        let mut text = b"run,kind,id,x_mm,y_mm,z_mm\n".to_vec();
        text.extend(body);
        std::fs::write(&file, text).unwrap();
        expect(&["--csv", file.to_str().unwrap()], parts)
    };
    // Two rows for one run and entity: both lines named, instead of the last silently winning.
    csv(
        b"n0-r00,source,tube1,1,2,3\nn0-r01,source,tube1,1,2,3\nn0-r00,source,tube1,1,2,4\n",
        &[
            "r.csv:4:",
            "line 4 repeats run n0-r00, source `tube1` of line 2",
        ],
    );
    csv(
        b"n0-r00,source,tube1,1,2,1e308\n",
        &["r.csv:2:", "`z_mm`", "implausible"],
    );
    // A 1 MB field is echoed cut, not whole.
    let long = "x".repeat(1 << 20);
    let stderr = csv(
        format!("n0-r00,source,{long},1,2,3\n").as_bytes(),
        &[
            "r.csv:2:",
            "no source has the id `xxxx",
            "… (1048376 more bytes)",
        ],
    );
    assert!(stderr.len() < 2000, "{} bytes of stderr", stderr.len());
    let stderr = csv(
        format!("n0-r00,source,tube1,1,2,{long}\n").as_bytes(),
        &["`z_mm`"],
    );
    assert!(stderr.len() < 2000, "{} bytes of stderr", stderr.len());
    // A BOM before the CSV header is accepted.
    let file = tmp.path().join("bom.csv");
    std::fs::write(
        &file,
        b"\xef\xbb\xbfrun,kind,id,x_mm,y_mm,z_mm\nn0-r00,source,tube1,1,2,3\n",
    )
    .unwrap();
    let (code, stderr) = evaluate_cli(&out, &["--csv", file.to_str().unwrap(), "--format", "md"]);
    assert_eq!(code, Some(0), "{stderr}");
}

#[test]
fn the_default_results_file_is_chosen_or_asked_for() {
    let (_tmp, out) = simulated();
    // Only one kind of measured*.json: used, and said so.
    write_all(&out, "measured-vendor.json", &|m| m);
    let (code, stderr) = evaluate_cli(&out, &["--format", "md"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains("results: measured-vendor.json"), "{stderr}");
    let md = std::fs::read_to_string(out.join("report-measured-vendor/report.md")).unwrap();
    assert!(
        md.contains("**Results file:** measured-vendor.json"),
        "{md}"
    );
    // Two kinds: an error listing both and the flag to pass.
    write_all(&out, "measured-other.json", &|m| m);
    let (code, stderr) = evaluate_cli(&out, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("measured-other.json, measured-vendor.json")
            && stderr.contains("--measured measured-other.json"),
        "{stderr}"
    );
    // measured.json, when present, is the default.
    write_all(&out, "measured.json", &|m| m);
    let (code, stderr) = evaluate_cli(&out, &["--format", "md"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(out.join("report-measured/report.md").is_file());
}

#[test]
fn a_folder_mixing_runs_of_different_scenarios_is_an_error_naming_the_run() {
    let (_tmp, out) = simulated();
    write_all(&out, "measured.json", &|m| m);
    let all = truths(&out);
    let (dir, truth) = &all[3];
    let mut other = truth.clone();
    other.run.phantoms.retain(|p| p.id != "femur");
    let bytes = serde_json::to_vec_pretty(&other).unwrap();
    std::fs::write(dir.join("truth.json"), &bytes).unwrap();
    // A manifest that lists the mixed folder as it is (as if two outputs were merged and indexed
    // again), so that the truth verifies and the mix itself must be found.
    let manifest_file = out.join("manifest.json");
    let mut manifest: rsasim::output::Manifest =
        serde_json::from_slice(&std::fs::read(&manifest_file).unwrap()).unwrap();
    let rel = format!("runs/{}/truth.json", truth.run.id);
    let entry = manifest.files.iter_mut().find(|f| f.path == rel).unwrap();
    entry.sha256 = sha256_hex(&bytes);
    entry.bytes = bytes.len() as u64;
    std::fs::write(&manifest_file, manifest.to_bytes()).unwrap();
    let mut m = measured_with_known_errors(truth, 3);
    m.phantoms.retain(|p| p.id != "femur");
    std::fs::write(
        dir.join("measured.json"),
        serde_json::to_vec_pretty(&m).unwrap(),
    )
    .unwrap();
    let (code, stderr) = evaluate_cli(&out, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!("run `{}` has phantoms", truth.run.id))
            && stderr.contains("mixes runs of different scenarios"),
        "{stderr}"
    );
}

#[test]
fn a_missing_mtpm_column_is_explained_in_the_report_and_on_stderr() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("mb");
    run_scenario("tests/scenarios/model_based.toml", &out, &[]);
    write_all(&out, "measured.json", &|m| m);
    // The bead-less femur's MTPM uses its mesh's corners; with an unreadable mesh the column
    // used to disappear without a word.
    std::fs::write(out.join("phantoms/femur.glb"), b"not a mesh").unwrap();
    let (code, stderr) = evaluate_cli(&out, &["--format", "md"]);
    assert_eq!(code, Some(0), "{stderr}");
    let said = "no MTPM column for model femur: it has no beads and its mesh could not be built";
    assert!(stderr.contains(&format!("note: {said}")), "{stderr}");
    let md = std::fs::read_to_string(out.join("report-measured/report.md")).unwrap();
    assert!(md.contains("## Notes") && md.contains(said), "{md}");
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Attenuation mode: the report's rows are exposure levels (`×1`, `×0.25`), not noise levels.
#[test]
fn attenuation_reports_label_their_rows_by_exposure() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("att");
    run_scenario("scenarios/golden/small_attenuation.toml", &out, &[]);
    for (k, (dir, truth)) in truths(&out).iter().enumerate() {
        write_measured(dir, &measured_with_known_errors(truth, k));
    }
    let o = rsasim(&["evaluate", out.to_str().unwrap(), "--format", "md"], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(report_dir(&out).join("report.md")).unwrap();
    assert!(md.contains("| Exposure | N |"), "{md}");
    assert!(md.contains("| ×1 |") && md.contains("| ×0.25 |"), "{md}");
    assert!(md.contains("2 exposure level(s) (×1, ×0.25)"), "{md}");
    assert!(!md.contains("| Noise |"));
}

/// `--source-truth`: with a focal spot whose emission falls 60 % towards +r (uniform 1.2 mm,
/// 3×3: its intensity-weighted centre lies 0.16/2.1 mm towards −r, by hand from the weights
/// 0.5, 0.7, 0.9), sources measured exactly at the spot's centre score 0 against the geometric
/// truth and +0.16/2.1 mm along r against the effective one; the report says which.
#[test]
fn sources_are_scored_against_the_geometric_or_the_effective_source() {
    let text = std::fs::read_to_string(common::root().join("tests/scenarios/evaluate.toml"))
        .unwrap()
        .replacen(
            "[output]",
            "[imaging.focal_spot]\nsize_mm = 1.2\nsamples = 3\nintensity_fall_percent = 60.0\nanode_direction = \"+r\"\n\n[output]",
            1,
        )
        .replace(
            "\"../../scenarios/models/",
            &format!("\"{}/scenarios/models/", common::root().display()),
        );
    let tmp = tempfile::tempdir().unwrap();
    let out = common::run_scenario_text(tmp.path(), "spot", &text);
    for (dir, truth) in truths(&out) {
        let mut m = measured_with_known_errors(&truth, 0);
        for s in &mut m.sources {
            s.position_mm = truth
                .run
                .sources
                .iter()
                .find(|t| t.id == s.id)
                .unwrap()
                .position_mm
                .to_array();
        }
        write_measured(&dir, &m);
    }
    let score = |source_truth| {
        let report = evaluate(
            &out,
            &Options {
                source_truth,
                ..options()
            },
        )
        .unwrap();
        let r = cell(table(&report, "sources"), 0, "tube1", "r").trueness;
        (r, report.notes.join("\n"))
    };
    let (geometric, note) = score(rsasim::evaluate::SourceTruth::Geometric);
    assert!(geometric.abs() < 1e-9, "{geometric}");
    assert!(note.contains("geometric centre (position_mm)"), "{note}");
    let (effective, note) = score(rsasim::evaluate::SourceTruth::Effective);
    assert!((effective - 0.16 / 2.1).abs() < 1e-9, "{effective}");
    assert!(
        note.contains("intensity-weighted centre (effective_position_mm)"),
        "{note}"
    );
}
