//! `rsasim sweep`: expansion (grid and zip: counts, order, ids), standalone point scenarios
//! (run alone, a point gives the sweep's bytes), errors in the sweep file (exit 2 naming file,
//! line and key, nothing written), resuming, and a small sweep end to end whose summary CSV holds
//! exactly every point's evaluate table, with its page drawn by a headless browser.

use crate::common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::{hashes, report_dir, rsasim};

/// The small zipped sweep of the tests: 3 angles of beamline 2, 3 runs at one noise level.
const SMALL: &str = "tests/scenarios/sweeps/small_angle.toml";

/// Writes a sweep file into `dir` (base: the golden small biplanar scenario) and returns its path.
fn sweep_file(dir: &Path, body: &str) -> PathBuf {
    let base = common::root().join("scenarios/golden/small_biplanar.toml");
    let path = dir.join("sweep.toml");
    std::fs::write(&path, format!("scenario = \"{}\"\n{body}", base.display())).unwrap();
    path
}

fn sweep_cli(file: &Path, out: &Path, extra: &[&str]) -> (Option<i32>, String) {
    let mut args = vec![
        "sweep",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = rsasim(&args, &[]);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn index(out: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(out.join("sweep.json")).unwrap()).unwrap()
}

/// A grid of 2 seeds × 2 run counts: one noise level, runs of 1 or 2, two base seeds.
const GRID: &str = r#"
[[parameters]]
key = "seed"
values = [7, 8]

[[parameters]]
key = "protocol.runs_per_level"
values = [1, 2]

[[parameters]]
key = "protocol.noise_levels"
values = [[0.0]]
"#;

#[test]
fn a_grid_expands_to_every_combination_first_parameter_slowest() {
    let tmp = tempfile::tempdir().unwrap();
    let file = sweep_file(tmp.path(), GRID);
    let out = tmp.path().join("grid");
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(0), "{stderr}");
    let idx = index(&out);
    let points = idx["points"].as_array().unwrap();
    let got: Vec<(String, Vec<String>)> = points
        .iter()
        .map(|p| {
            (
                p["id"].as_str().unwrap().to_string(),
                p["values"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_str().unwrap().to_string())
                    .collect(),
            )
        })
        .collect();
    let want: Vec<(String, Vec<String>)> = [
        ("p00", "7", "1"),
        ("p01", "7", "2"),
        ("p02", "8", "1"),
        ("p03", "8", "2"),
    ]
    .iter()
    .map(|(id, seed, runs)| {
        (
            id.to_string(),
            vec![seed.to_string(), runs.to_string(), "[0.0]".to_string()],
        )
    })
    .collect();
    assert_eq!(got, want);
    // Each point's output is the point's scenario: its seed, its run count, one level.
    for (p, (id, values)) in points.iter().zip(&want) {
        let manifest: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(id).join("manifest.json")).unwrap())
                .unwrap();
        assert_eq!(manifest["seed"].to_string(), values[0]);
        assert_eq!(manifest["runs"].to_string(), values[1]);
        assert_eq!(manifest["scenario_sha256"], p["scenario_sha256"]);
        assert_eq!(
            manifest["scenario"],
            format!("small_biplanar-{id}").as_str()
        );
    }
}

#[test]
fn a_point_scenario_run_alone_writes_the_same_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let file = sweep_file(
        tmp.path(),
        r#"
combine = "zip"
[[parameters]]
key = "detectors.det2.pixels"
values = [[200, 200], [240, 160]]
[[parameters]]
key = "protocol.runs_per_level"
values = [1]
"#,
    );
    let out = tmp.path().join("s");
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(index(&out)["points"].as_array().unwrap().len(), 2);
    // The point scenario is copied elsewhere with its inputs, and run without --allow-dir.
    let copy = tmp.path().join("elsewhere");
    std::fs::create_dir_all(copy.join("inputs")).unwrap();
    for e in std::fs::read_dir(out.join("points/inputs")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), copy.join("inputs").join(e.file_name())).unwrap();
    }
    std::fs::copy(out.join("points/p01.toml"), copy.join("p01.toml")).unwrap();
    let alone = tmp.path().join("alone");
    let o = rsasim(
        &[
            copy.join("p01.toml").to_str().unwrap(),
            "--out",
            alone.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(hashes(&alone), hashes(&out.join("p01")));
    // The detector took the point's value.
    let truth = &common::truths(&alone)[0].1;
    let det2 = truth.run.detectors.iter().find(|d| d.id == "det2").unwrap();
    assert_eq!(det2.pixels, [240, 160]);
}

#[test]
fn a_bad_key_path_is_an_input_error_naming_the_sweep_file_line_and_key() {
    let tmp = tempfile::tempdir().unwrap();
    let file = sweep_file(
        tmp.path(),
        "\n[[parameters]]\nkey = \"sources.tube3.position_mm\"\nvalues = [[0.0, 0.0, 1300.0]]\n",
    );
    let out = tmp.path().join("never");
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    let line = format!("{}:4:7: `parameters[0].key`", file.display());
    assert!(stderr.contains(&line), "{stderr}");
    assert!(
        stderr.contains("`sources` has no table with id `tube3`; its ids are `tube1`, `tube2`"),
        "{stderr}"
    );
    assert!(stderr.contains("nothing was written"), "{stderr}");
    assert!(!out.exists());
}

/// A `scenario` path that reaches a file that is no scenario (here a plain text file outside the
/// sweep's folder, as `/etc/hosts` would be): the error is the file's, and it also names the
/// sweep file's line that chose it; exit 2, nothing written (campaign seeds 4817, 5219, 5364).
#[test]
fn a_base_scenario_that_is_no_scenario_is_traced_to_the_sweep_files_line() {
    let tmp = tempfile::tempdir().unwrap();
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let victim = elsewhere.join("notes.txt");
    std::fs::write(&victim, "root:x:0:0:root:/root:/bin/bash\n").unwrap();
    let dir = tmp.path().join("sweep");
    std::fs::create_dir(&dir).unwrap();
    let file = dir.join("sweep.toml");
    std::fs::write(
        &file,
        "name = \"s\"\nscenario = \"../elsewhere/notes.txt\"\n[[parameters]]\nkey = \"seed\"\nvalues = [1, 2]\n",
    )
    .unwrap();
    let out = tmp.path().join("never");
    for extra in [&[][..], &["--merge"][..]] {
        let (code, stderr) = sweep_cli(&file, &out, extra);
        assert_eq!(code, Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains("notes.txt:1:"), "{extra:?}: {stderr}");
        let origin = format!("named by `scenario` at {}:2:12", file.display());
        assert!(stderr.contains(&origin), "{extra:?}: {stderr}");
        assert!(!out.exists(), "{extra:?}");
    }
}

#[test]
fn a_bad_key_or_value_is_reported_at_the_value_that_made_the_point() {
    let tmp = tempfile::tempdir().unwrap();
    // An unknown key: the scenario's message lists the valid ones.
    let file = sweep_file(
        tmp.path(),
        "\n[[parameters]]\nkey = \"protocol.runs_per_levl\"\nvalues = [2]\n",
    );
    let out = tmp.path().join("never");
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{}:5:11: `parameters[0].values[0]`",
            file.display()
        )),
        "{stderr}"
    );
    assert!(
        stderr.contains("point p00 (protocol.runs_per_levl = 2)")
            && stderr.contains("unknown field `runs_per_levl`")
            && stderr.contains("runs_per_level"),
        "{stderr}"
    );
    // A value the scenario refuses, in the second point only.
    let file = sweep_file(
        tmp.path(),
        "\n[[parameters]]\nkey = \"detectors.det1.bpp\"\nvalues = [12, 40]\n",
    );
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{}:5:15: `parameters[0].values[1]`",
            file.display()
        )) && stderr.contains("point p01 (detectors.det1.bpp = 40)")
            && stderr.contains("detectors[0].bpp"),
        "{stderr}"
    );
    assert!(!stderr.contains("point p00"), "{stderr}");
    // Zipped lists of different lengths.
    let file = sweep_file(
        tmp.path(),
        "combine = \"zip\"\n[[parameters]]\nkey = \"seed\"\nvalues = [1, 2]\n[[parameters]]\nkey = \"protocol.runs_per_level\"\nvalues = [1, 2, 3]\n",
    );
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("`parameters[0].values`")
            && stderr.contains("needs equally many values: `seed` has 2, another parameter 3"),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn a_sweep_resumes_into_its_own_folder_and_refuses_another() {
    let tmp = tempfile::tempdir().unwrap();
    let file = sweep_file(
        tmp.path(),
        "[[parameters]]\nkey = \"seed\"\nvalues = [1, 2]\n[[parameters]]\nkey = \"protocol.runs_per_level\"\nvalues = [1]\n",
    );
    let out = tmp.path().join("s");
    // --no-run writes the points and runs none; the next sweep runs them.
    let (code, stderr) = sweep_cli(&file, &out, &["--no-run"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(out.join("points/p01.toml").is_file() && out.join("sweep.json").is_file());
    assert!(!out.join("p00").exists() && !out.join("p01").exists());
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(0), "{stderr}");
    // A stopped sweep: one point missing. The rerun keeps p00 as it is and writes p01 again.
    let p00 = hashes(&out.join("p00"));
    let p01 = hashes(&out.join("p01"));
    let manifest_time = std::fs::metadata(out.join("p00/manifest.json"))
        .unwrap()
        .modified()
        .unwrap();
    std::fs::remove_dir_all(out.join("p01")).unwrap();
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("point p00 (1/2) is complete from an earlier run, kept"),
        "{stderr}"
    );
    assert_eq!(hashes(&out.join("p00")), p00);
    assert_eq!(hashes(&out.join("p01")), p01);
    let again = std::fs::metadata(out.join("p00/manifest.json"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(again, manifest_time);
    // Another sweep into the same folder is refused, and a folder rsasim did not write too.
    std::fs::write(
        &file,
        std::fs::read_to_string(&file)
            .unwrap()
            .replace("[1, 2]", "[1, 3]"),
    )
    .unwrap();
    let (code, stderr) = sweep_cli(&file, &out, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("holds another sweep"), "{stderr}");
    let foreign = tmp.path().join("foreign");
    std::fs::create_dir_all(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
    let (code, stderr) = sweep_cli(&file, &foreign, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("not a sweep folder"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(foreign.join("notes.txt")).unwrap(),
        "mine"
    );
}

/// The small sweep run, reconstructed and evaluated in one command (once for the tests below).
fn evaluated() -> &'static Path {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, out) = DIR.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("small_angle");
        let (code, stderr) = sweep_cli(&common::root().join(SMALL), &out, &["--evaluate"]);
        assert_eq!(code, Some(0), "{stderr}");
        (tmp, out)
    });
    out
}

fn csv_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header = r.headers().unwrap().iter().map(String::from).collect();
    let rows = r
        .records()
        .map(|rec| rec.unwrap().iter().map(String::from).collect())
        .collect();
    (header, rows)
}

#[test]
fn the_summary_csv_holds_every_points_evaluate_table() {
    let out = evaluated();
    let (header, rows) = csv_rows(&out.join("sweep-report/sweep_summary.csv"));
    assert_eq!(
        header[..7],
        [
            "point",
            "tube angle (deg)",
            "detectors.det2.position_mm",
            "detectors.det2.rotation_deg",
            "protocol.noise_levels",
            "protocol.runs_per_level",
            "table"
        ]
    );
    let prefix = 6;
    let mut seen = 0;
    for (id, angle) in [("p00", "90"), ("p01", "75"), ("p02", "60")] {
        let (point_header, point_rows) = csv_rows(&report_dir(&out.join(id)).join("report.csv"));
        assert_eq!(header[prefix..], point_header[..]);
        let mine: Vec<&Vec<String>> = rows.iter().filter(|r| r[0] == id).collect();
        assert!(point_rows.len() > 20, "{}", point_rows.len());
        assert_eq!(mine.len(), point_rows.len(), "{id}");
        for (summary_row, point_row) in mine.iter().zip(&point_rows) {
            assert_eq!(summary_row[1], angle);
            assert_eq!(summary_row[5], "3");
            assert_eq!(summary_row[prefix..], point_row[..]);
        }
        seen += mine.len();
    }
    assert_eq!(seen, rows.len());
    // The points are scored from rsasim's reconstruction: 3 runs each, the box calibrated.
    let det2_s = rows
        .iter()
        .find(|r| r[0] == "p02" && r[6] == "detector-det2" && r[8] == "s")
        .unwrap();
    assert_eq!(det2_s[11], "3");
}

#[test]
fn the_summary_page_plots_every_cell_against_the_angle_and_renders() {
    let out = evaluated();
    let page = out.join("sweep-report/sweep_summary.html");
    let html = std::fs::read_to_string(&page).unwrap();
    let (_, rows) = csv_rows(&out.join("sweep-report/sweep_summary.csv"));
    // One plot per cell of a point's tables (one noise level), each with the three angles.
    let per_point = rows.iter().filter(|r| r[0] == "p00").count();
    assert_eq!(html.matches("<svg").count(), per_point);
    assert!(
        html.contains(">60</text>") && html.contains(">75</text>") && html.contains(">90</text>")
    );
    assert!(html.contains("angle (deg)</text>"));
    // Zipped parameters make no series of their own: one group of plots.
    assert_eq!(html.matches("<h3>Noise level 45.0%</h3>").count(), 1);
    let test = "the_summary_page_plots_every_cell_against_the_angle_and_renders";
    let Some(browser) = common::browser::chromium_or_skip(test) else {
        return;
    };
    let (console, shot) = common::browser::screenshot(&browser, &page, 1200, 1600);
    assert!(console.is_empty(), "{console:?}");
    // The plots are drawn: below the points table, many dark pixels (points, bars, tick labels).
    assert_eq!((shot.width, shot.height), (1200, 1600));
    let ink = (900..1600)
        .flat_map(|y| (0..1200).map(move |x| (x, y)))
        .filter(|&(x, y)| shot.pixel(x, y).iter().all(|&c| c < 0x80))
        .count();
    assert!(ink > 5_000, "only {ink} dark pixels where the plots are");
}
