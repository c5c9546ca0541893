//! `rsasim export` and XMALab's exports read by `rsasim evaluate`, end to end: the exported
//! DLT-11 and MayaCam cameras reproject every bead onto its truth pixel; the images are the run's,
//! flipped and scaled; hand-made XMALab CSVs in the exact layout give the residuals put into them;
//! bad files and folders are refused with exit code 2.

use crate::common;

use std::path::{Path, PathBuf};

use common::{beads, numbers, read_tiff, rsasim, run_scenario, truths};
use rsasim::evaluate::stats::Confidence;
use rsasim::evaluate::table::{Report, Table};
use rsasim::evaluate::{MeasuredSource, Options, evaluate};
use rsasim::output::Truth;

/// The golden small biplanar scenario (240² px, 4 runs) and its export for `to`.
fn exported(to: &str) -> (tempfile::TempDir, PathBuf, PathBuf) {
    common::exported("scenarios/golden/small_biplanar.toml", to, &[])
}

/// Reads a MayaCam 2.0 file ([`common::read_mayacam`]): (W, H, K, R, t).
fn mayacam(file: &Path) -> common::MayaCam {
    common::read_mayacam(&std::fs::read_to_string(file).unwrap())
}

#[test]
fn exported_dlt_and_mayacam_reproject_every_bead_onto_its_truth_pixel() {
    let (_tmp, out, dest) = exported("xmalab");
    let mut checked = 0;
    let mut worst_dlt: f64 = 0.0;
    let mut worst_cam: f64 = 0.0;
    for (_, truth) in truths(&out) {
        let run = dest.join(&truth.run.id);
        let dlt_text = std::fs::read_to_string(run.join("calibration/dlt11.csv")).unwrap();
        let rows: Vec<Vec<f64>> = dlt_text.lines().map(numbers).collect();
        assert_eq!(rows.len(), 11);
        for (d, det) in truth.run.detectors.iter().enumerate() {
            let l: Vec<f64> = rows.iter().map(|r| r[d]).collect();
            let (size, k, r, t) = mayacam(&run.join(format!("calibration/{}_MayaCam.txt", det.id)));
            assert_eq!(size, [det.pixels[0] as f64, det.pixels[1] as f64]);
            let h = det.pixels[1] as f64;
            for (on, x, uv) in beads(&truth).into_iter().filter(|b| b.0 == det.id) {
                assert_eq!(on, det.id);
                // DLT-11: 1-based, origin bottom-left: (u + 0.5, v + 0.5) in rsasim's pixels.
                let den = l[8] * x[0] + l[9] * x[1] + l[10] * x[2] + 1.0;
                let dx = (l[0] * x[0] + l[1] * x[1] + l[2] * x[2] + l[3]) / den;
                let dy = (l[4] * x[0] + l[5] * x[1] + l[6] * x[2] + l[7]) / den;
                let e = (dx - (uv[0] + 0.5)).hypot(dy - (uv[1] + 0.5));
                worst_dlt = worst_dlt.max(e);
                // MayaCam: K·(R·x + t), 0-based, origin top-left of the flipped image.
                let c: Vec<f64> = (0..3)
                    .map(|i| (0..3).map(|j| r[i][j] * x[j]).sum::<f64>() + t[i])
                    .collect();
                let px = (0..3).map(|i| (0..3).map(|j| k[i][j] * c[j]).sum::<f64>());
                let p: Vec<f64> = px.collect();
                let (cx, cy) = (p[0] / p[2], p[1] / p[2]);
                let e = (cx - (uv[0] - 0.5)).hypot(cy - (h - uv[1] - 0.5));
                worst_cam = worst_cam.max(e);
                checked += 1;
            }
        }
    }
    eprintln!(
        "{checked} bead images: worst DLT error {worst_dlt:e} px, worst MayaCam error {worst_cam:e} px"
    );
    assert!(checked > 100, "only {checked} beads checked");
    assert!(worst_dlt <= 1e-6, "DLT reprojection error {worst_dlt} px");
    assert!(
        worst_cam <= 1e-6,
        "MayaCam reprojection error {worst_cam} px"
    );
}

#[test]
fn exported_images_are_the_runs_flipped_and_scaled() {
    let (_tmp, out, dest) = exported("xmalab");
    // Binary mode shows beads bright; the export makes dense matter dark by default:
    // I_max − value, then scaled.
    // The last run has background noise (level 0.45): many grey levels, not only 0 and I_max.
    let (dir, truth) = truths(&out).pop().unwrap();
    let image = &truth.images[0];
    let stem = format!("{}-{}", image.exposure, image.detector);
    let (w, h, original) = read_tiff(&dir.join(format!("{stem}.tiff")));
    let (w2, h2, exported) = read_tiff(
        &dest
            .join(&truth.run.id)
            .join(format!("images/{stem}/{stem}.0001.tif")),
    );
    assert_eq!((w, h), (w2, h2));
    let det = truth
        .run
        .detectors
        .iter()
        .find(|d| d.id == image.detector)
        .unwrap();
    let i_max = f64::from(det.i_max());
    let mut levels = std::collections::BTreeSet::new();
    for j in 0..h as usize {
        for i in 0..w as usize {
            let v = i_max - f64::from(original[(h as usize - 1 - j) * w as usize + i]);
            let want = (v * 65535.0 / i_max).round();
            assert_eq!(
                f64::from(exported[j * w as usize + i]),
                want,
                "pixel ({i}, {j})"
            );
            levels.insert(exported[j * w as usize + i]);
        }
    }
    assert!(levels.contains(&0) && levels.len() > 2, "{levels:?}");
}

#[test]
fn autoscoper_export_has_a_trial_per_exposure_with_a_model_whose_files_exist() {
    let (_tmp, out, dest) = exported("autoscoper");
    let (_, truth) = truths(&out).remove(0);
    let run = dest.join(&truth.run.id);
    for exposure in &truth.run.exposures {
        let cfg_path = run.join(format!("{}.cfg", exposure.id));
        // The box alone (the calibration exposure) has nothing to track: no trial.
        if !exposure.phantoms.iter().any(|p| p == "femur") {
            assert!(!cfg_path.exists());
            continue;
        }
        let cfg = std::fs::read_to_string(cfg_path).unwrap();
        let mut cameras = 0;
        for line in cfg.lines().filter(|l| !l.starts_with('#')) {
            let Some((key, value)) = line.split_once(' ') else {
                continue;
            };
            match key {
                "mayaCam_csv" | "MeshFile" | "VolumeFile" => {
                    assert!(run.join(value).is_file(), "{value}");
                    cameras += usize::from(key == "mayaCam_csv");
                }
                "CameraRootDir" => {
                    assert!(!value.starts_with('/') && value.ends_with('/'), "{value}");
                    let tifs = std::fs::read_dir(run.join(value)).unwrap().count();
                    assert_eq!(tifs, 1, "{value}");
                }
                _ => {}
            }
        }
        assert_eq!(cameras, truth.run.detectors.len());
    }
    assert!(run.join("models/femur.stl").is_file());
    // The same cameras as the XMALab export would hold: no DLT or calibration object here.
    assert!(!run.join("calibration/dlt11.csv").exists());
}

fn table<'a>(r: &'a Report, id: &str) -> &'a Table {
    r.tables.iter().find(|t| t.id == id).unwrap()
}

fn trueness(t: &Table, level: usize, group: &str, column: &str) -> f64 {
    let mut k = 0;
    for g in &t.groups {
        for c in &g.columns {
            if g.label.starts_with(group) && c.label == column {
                return t.rows[level].cells[k].clone().unwrap().trueness;
            }
            k += 1;
        }
    }
    panic!("no column {group}/{column}")
}

/// Shortest round-trip text of a number, as XMALab's CSVs hold plain decimals.
fn num(x: f64) -> String {
    format!("{x}")
}

/// The known offset of every hand-made XMALab result, mm (box frame).
const OFFSET: [f64; 3] = [0.1, -0.2, 0.05];

/// A rigid-body transformation export of XMALab, exact layout, for body `femur` at the truth
/// pose moved by [`OFFSET`]: `Frame` column, 16 columns, the 3×3 block = world → body rotation.
fn rigid_body_csv(truth: &Truth) -> String {
    format!(
        "Frame,{}\n1,{}\n",
        rigid_body_header(),
        rigid_body_values(truth, OFFSET)
    )
}

/// The 16 column names of body `femur` in XMALab's rigid-body export.
fn rigid_body_header() -> String {
    let names = [
        "R11", "R12", "R13", "01", "R21", "R22", "R23", "02", "R31", "R32", "R33", "03", "TX",
        "TY", "TZ", "1",
    ];
    let header: Vec<String> = names.iter().map(|n| format!("femur_{n}")).collect();
    header.join(",")
}

/// The 16 values of body `femur` at its truth pose moved by `offset` (mm, box frame).
fn rigid_body_values(truth: &Truth, offset: [f64; 3]) -> String {
    let p = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
    // World → body rows are the body axes, i.e. the columns of rsasim's rotation.
    let axes = [p.rotation.x_axis, p.rotation.y_axis, p.rotation.z_axis];
    let pos = p.position_mm.to_array();
    let mut v = Vec::new();
    for a in axes {
        v.extend([num(a.x), num(a.y), num(a.z), "0".into()]);
    }
    v.extend((0..3).map(|i| num(pos[i] + offset[i])));
    v.push("1".into());
    v.join(",")
}

/// A 3-D point export of XMALab for every bead of `femur`, moved by [`OFFSET`].
fn points_csv(truth: &Truth) -> String {
    format!(
        "{}\n{}\n",
        points_header(truth),
        points_values(truth, OFFSET)
    )
}

/// The column names of every bead of `femur` in XMALab's 3-D point export.
fn points_header(truth: &Truth) -> String {
    let p = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
    let header: Vec<String> = p
        .markers
        .iter()
        .map(|m| format!("{0}_X,{0}_Y,{0}_Z", m.id))
        .collect();
    header.join(",")
}

/// Every bead of `femur` at its truth position moved by `offset` (mm, box frame).
fn points_values(truth: &Truth, offset: [f64; 3]) -> String {
    let p = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
    let values: Vec<String> = p
        .markers
        .iter()
        .map(|m| {
            let x = m.position_mm.to_array();
            (0..3)
                .map(|i| num(x[i] + offset[i]))
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect();
    values.join(",")
}

/// The evaluate test scenario (16² px, 2 levels × 20 runs, a femur with 6 beads) and a folder
/// of per-run result folders, as an export gives.
fn simulated_with_results_folder() -> (tempfile::TempDir, PathBuf, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("eval");
    run_scenario("tests/scenarios/evaluate.toml", &out, &[]);
    let dest = tmp.path().join("xma");
    for (_, truth) in truths(&out) {
        std::fs::create_dir_all(dest.join(&truth.run.id)).unwrap();
    }
    (tmp, out, dest)
}

/// A 2-D point export of XMALab (0-based pixels, y down, of the exported flipped images) for
/// every bead of `femur` moved by [`OFFSET`], projected by rsasim's own detector frames.
fn points2d_csv(truth: &Truth) -> String {
    points2d_csv_as(truth, &Export2d::default())
}

/// The options of XMALab's 2-D point export dialog.
#[derive(Default)]
struct Export2d {
    /// "y axis up (Matlab)".
    y_up: bool,
    /// "start coordinates at 1 (Matlab)".
    start_at_one: bool,
    /// "cam offset columns": `Some(separator)` between the header's offset names and before
    /// the first marker's column (XMALab writes none: `Some("")`).
    offset_columns: Option<&'static str>,
}

/// [`points2d_csv`] as XMALab writes it with `options`, by the rules of its
/// `Trial::save2dPoints` (src/core/Trial.cpp, XMALab 2.2.7): y up writes `H − y − 1`, then
/// start at 1 adds 1 to x and y; offset columns write `cam<j>_offset` (j from 0) with no comma
/// between them nor before the first marker, and `0,` per camera at the start of every row.
fn points2d_csv_as(truth: &Truth, options: &Export2d) -> String {
    let p = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
    let mut header = Vec::new();
    let mut values = Vec::new();
    for m in &p.markers {
        for (j, det) in truth.run.detectors.iter().enumerate() {
            header.push(format!("{0}_cam{1}_X,{0}_cam{1}_Y", m.id, j + 1));
            let moved = m.position_mm + glam::DVec3::from_array(OFFSET);
            let uv = det
                .frame()
                .project(truth.run.source_of(det), moved)
                .unwrap();
            let h = f64::from(det.pixels[1]);
            let (mut x, mut y) = (uv.x - 0.5, h - uv.y - 0.5);
            if options.y_up {
                y = h - y - 1.0;
            }
            if options.start_at_one {
                x += 1.0;
                y += 1.0;
            }
            values.push(format!("{},{}", num(x), num(y)));
        }
    }
    let (mut head, mut row) = (String::new(), String::new());
    if let Some(separator) = options.offset_columns {
        for j in 0..truth.run.detectors.len() {
            head += &format!("cam{j}_offset{separator}");
            row += "0,";
        }
    }
    format!("{head}{}\n{row}{}\n", header.join(","), values.join(","))
}

/// Asserts the femur's trueness is [`OFFSET`] at both levels, with no rotation.
fn assert_offset_residuals(report: &Report, name: &str) {
    assert_eq!(report.runs_scored, 40, "{name}");
    let femur = table(report, "phantom-femur");
    for level in 0..2 {
        for (i, axis) in ["x", "y", "z"].iter().enumerate() {
            let t = trueness(femur, level, "position", axis);
            assert!((t - OFFSET[i]).abs() < 1e-7, "{name} {axis}: {t}");
        }
        for angle in ["α", "β", "γ"] {
            let t = trueness(femur, level, "orientation", angle);
            assert!(t.abs() < 1e-7, "{name} {angle}: {t}");
        }
    }
}

/// Scores the XMALab file `name` of every run in `dest` with the 2-D options `xmalab_2d`.
fn evaluate_xmalab(
    out: &Path,
    dest: &Path,
    name: &str,
    xmalab_2d: rsasim::interop::xmalab_points2d::PixelOptions,
) -> Report {
    evaluate(
        out,
        &Options {
            measured: MeasuredSource::PerRunIn {
                name: name.into(),
                dir: dest.to_path_buf(),
            },
            confidence: Confidence::default(),
            mtpm_threshold_mm: rsasim::evaluate::DEFAULT_MTPM_THRESHOLD_MM,
            study: Default::default(),
            xmalab_2d,
            source_truth: Default::default(),
        },
    )
    .unwrap_or_else(|e| panic!("{name}: {e:?}"))
}

#[test]
fn hand_made_xmalab_exports_give_the_residuals_put_into_them() {
    let (_tmp, out, dest) = simulated_with_results_folder();
    for (name, make) in [
        (
            "xmalab-rigid-bodies.csv",
            rigid_body_csv as fn(&Truth) -> String,
        ),
        ("xmalab-points.csv", points_csv),
        ("xmalab-points2d.csv", points2d_csv),
    ] {
        for (_, truth) in truths(&out) {
            std::fs::write(dest.join(&truth.run.id).join(name), make(&truth)).unwrap();
        }
        let report = evaluate_xmalab(&out, &dest, name, Default::default());
        assert_offset_residuals(&report, name);
    }
    // The command line: the same file names found under --results-in.
    let o = evaluate_cli(&out, &dest, "xmalab-points.csv", &["--format", "csv"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("report-xmalab-points/report.csv").is_file());
}

/// Every option of XMALab's 2-D point export, alone and combined, with the y axis and first
/// pixel stated on the command line (the file does not say them), gives the same residuals.
#[test]
fn every_variant_of_xmalab_2d_points_gives_the_residuals_put_into_them() {
    use rsasim::interop::xmalab_points2d::{FirstPixel, PixelOptions, YAxis};
    let (_tmp, out, dest) = simulated_with_results_folder();
    let variant = |y_up, start_at_one, offset_columns| Export2d {
        y_up,
        start_at_one,
        offset_columns,
    };
    let variants = [
        ("offsets", variant(false, false, Some(""))),
        ("offsets-with-commas", variant(false, false, Some(","))),
        ("y-up", variant(true, false, None)),
        ("start-at-1", variant(false, true, None)),
        ("y-up-start-at-1", variant(true, true, None)),
        ("all", variant(true, true, Some(""))),
    ];
    for (label, export) in &variants {
        let name = format!("xmalab-2d-{label}.csv");
        for (_, truth) in truths(&out) {
            let text = points2d_csv_as(&truth, export);
            std::fs::write(dest.join(&truth.run.id).join(&name), text).unwrap();
        }
        let pixels = PixelOptions {
            y_axis: if export.y_up { YAxis::Up } else { YAxis::Down },
            first_pixel: if export.start_at_one {
                FirstPixel::One
            } else {
                FirstPixel::Zero
            },
        };
        assert_offset_residuals(&evaluate_xmalab(&out, &dest, &name, pixels), &name);
    }
    // The header and row XMALab writes with offset columns, two cameras: no comma after
    // `cam0_offset` nor after `cam1_offset`, the header two cells shorter than the row.
    let (_, truth) = truths(&out).remove(0);
    let text = points2d_csv_as(&truth, &variants[5].1);
    let (head, row) = (text.lines().next().unwrap(), text.lines().nth(1).unwrap());
    assert!(
        head.starts_with("cam0_offsetcam1_offsetK1_cam1_X,K1_cam1_Y,K1_cam2_X,K1_cam2_Y,K2_"),
        "{head}"
    );
    assert!(row.starts_with("0,0,"), "{row}");
    assert_eq!(head.split(',').count() + 2, row.split(',').count());
    // The command line.
    let flags = ["--xmalab-2d-y-axis", "up", "--xmalab-2d-start-at", "1"];
    let o = evaluate_cli(
        &out,
        &dest,
        "xmalab-2d-all.csv",
        &[&flags[..], &["--format", "csv"]].concat(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("report-xmalab-2d-all/report.csv").is_file());
    // The options of 2-D points given for a rigid-body export are refused.
    std::fs::write(
        dest.join(&truth.run.id).join("rigid.csv"),
        rigid_body_csv(&truth),
    )
    .unwrap();
    let e = evaluate_refused(&out, &dest, "rigid.csv", &flags[..2]);
    assert!(
        e.contains(":1:7") && e.contains("--xmalab-2d-y-axis up"),
        "{e}"
    );
}

/// `rsasim evaluate OUT --measured NAME --results-in DEST` and `extra` arguments.
fn evaluate_cli(out: &Path, dest: &Path, name: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "evaluate",
        out.to_str().unwrap(),
        "--measured",
        name,
        "--results-in",
        dest.to_str().unwrap(),
    ];
    args.extend(extra);
    rsasim(&args, &[])
}

/// [`evaluate_cli`] that must be refused with exit code 2; returns its stderr.
fn evaluate_refused(out: &Path, dest: &Path, name: &str, extra: &[&str]) -> String {
    let o = evaluate_cli(out, dest, name, extra);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{e}");
    e
}

/// Runs `evaluate` on one bad XMALab file in the first run folder and returns its stderr.
fn evaluate_bad(out: &Path, dest: &Path, first_run: &str, text: &str) -> String {
    std::fs::write(dest.join(first_run).join("bad.csv"), text).unwrap();
    evaluate_refused(out, dest, "bad.csv", &[])
}

#[test]
fn bad_xmalab_files_are_refused_with_file_line_and_column() {
    let (_tmp, out, dest) = simulated_with_results_folder();
    let (_, truth) = truths(&out).remove(0);
    let id = truth.run.id.clone();
    let good = rigid_body_csv(&truth);
    let file = format!("{id}/bad.csv");
    // A value that is not a number: line 2, at its column.
    let bad = good.replacen(",0,", ",zero,", 1);
    let col = bad.lines().nth(1).unwrap().find("zero").unwrap() + 1;
    let e = evaluate_bad(&out, &dest, &id, &bad);
    assert!(
        e.contains(&format!("{file}:2:{col}")) && e.contains("`zero` is not a number"),
        "{e}"
    );
    // A body that is not a phantom: line 1, column 7 (after `Frame,`).
    let e = evaluate_bad(&out, &dest, &id, &good.replace("femur_", "tibia_"));
    assert!(
        e.contains(&format!("{file}:1:7"))
            && e.contains("rigid body `tibia`")
            && e.contains("femur"),
        "{e}"
    );
    // Two frames in one run's file.
    let two = format!("{good}{}\n", good.lines().nth(1).unwrap());
    let e = evaluate_bad(&out, &dest, &id, &two);
    assert!(
        e.contains(&format!("{file}:3:1")) && e.contains("2 frame(s)"),
        "{e}"
    );
    // Neither layout.
    let e = evaluate_bad(&out, &dest, &id, "a,b,c\n1,2,3\n");
    assert!(
        e.contains(&format!("{file}:1:1")) && e.contains("none of XMALab's"),
        "{e}"
    );
    // 2-D points for one camera of two.
    let e = evaluate_bad(&out, &dest, &id, "K1_cam1_X,K1_cam1_Y\n1,2\n");
    assert!(
        e.contains(&format!("{file}:1:11")) && e.contains("not a multiple of 4"),
        "{e}"
    );
    // Offset columns in a form XMALab does not write: numbered from 1; a camera skipped; one
    // for two cameras; an offset value that is not a number.
    let good2d = points2d_csv_as(
        &truth,
        &Export2d {
            offset_columns: Some(""),
            ..Default::default()
        },
    );
    for (from, to, at, needle) in [
        (
            "cam0_offsetcam1",
            "cam1_offsetcam2",
            "1:1",
            "`cam1_offsetcam2_offsetK1_cam1_X` is no offset column XMALab writes",
        ),
        (
            "cam1_offset",
            "cam2_offset",
            "1:12",
            "cam0_offsetcam1_offset",
        ),
        (
            "cam1_offset",
            "",
            "1:1",
            "1 offset column(s) for the run's 2 camera(s)",
        ),
        (
            "\n0,",
            "\nzero,",
            "2:1",
            "offset column `zero` is not a number",
        ),
    ] {
        let e = evaluate_bad(&out, &dest, &id, &good2d.replacen(from, to, 1));
        assert!(
            e.contains(&format!("{file}:{at}")) && e.contains(needle),
            "{e}"
        );
    }
    // A marker that is no bead.
    let e = evaluate_bad(&out, &dest, &id, "Q9_X,Q9_Y,Q9_Z\n1,2,3\n");
    assert!(
        e.contains(&format!("{file}:1:1")) && e.contains("`Q9` is not a bead"),
        "{e}"
    );
}

#[test]
fn export_refuses_existing_folders_the_output_itself_and_unknown_runs() {
    let (tmp, out, dest) = exported("xmalab");
    let before = common::hashes(&dest);
    let args = |d: &Path, extra: &[&str]| {
        let mut a = vec![
            "export".to_string(),
            out.to_str().unwrap().to_string(),
            "--to".into(),
            "xmalab".into(),
            "--dir".into(),
            d.to_str().unwrap().to_string(),
        ];
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let run = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        rsasim(&a, &[])
    };
    // An existing folder (the earlier export) is never written into.
    let o = run(args(&dest, &[]));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("already exists"));
    assert_eq!(common::hashes(&dest), before);
    // Inside the output folder.
    let inside = out.join("xma");
    let o = run(args(&inside, &[]));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("inside the output folder"));
    assert!(!inside.exists());
    // An unknown run: nothing written.
    let fresh = tmp.path().join("fresh");
    let o = run(args(&fresh, &["--run", "n9-r99"]));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no run `n9-r99`"));
    assert!(!fresh.exists());
    // One run only.
    let o = run(args(&fresh, &["--run", "n1-r01"]));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let runs: Vec<String> = std::fs::read_dir(&fresh)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "README.md")
        .collect();
    assert_eq!(runs, ["n1-r01"]);
}

#[test]
fn a_measured_calibration_is_exported_instead_of_the_truth() {
    let (tmp, out, _) = exported("xmalab");
    let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
    assert!(
        o.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let (dir, truth) = truths(&out).remove(0);
    let name = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .find(|n| n.starts_with("measured-rsasim-"))
        .unwrap_or_else(|| {
            panic!(
                "reconstruct wrote nothing: {}",
                String::from_utf8_lossy(&o.stderr)
            )
        });
    let name = name.as_str();
    let dest = tmp.path().join("measured-cal");
    let o = rsasim(
        &[
            "export",
            out.to_str().unwrap(),
            "--to",
            "autoscoper",
            "--dir",
            dest.to_str().unwrap(),
            "--run",
            &truth.run.id,
            "--calibration-from",
            name,
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m: rsasim::output::Measured =
        serde_json::from_slice(&std::fs::read(dir.join(name)).unwrap()).unwrap();
    // The camera centre −Rᵀ·t is the measured source, not the true one.
    let det = &truth.run.detectors[0];
    let (_, _, r, t) = mayacam(
        &dest
            .join(&truth.run.id)
            .join(format!("calibration/{}_MayaCam.txt", det.id)),
    );
    let centre: Vec<f64> = (0..3)
        .map(|j| -(0..3).map(|i| r[i][j] * t[i]).sum::<f64>())
        .collect();
    let measured = m
        .sources
        .iter()
        .find(|s| s.id == det.source)
        .unwrap()
        .position_mm;
    for j in 0..3 {
        assert!(
            (centre[j] - measured[j]).abs() < 1e-9,
            "{centre:?} {measured:?}"
        );
    }
    assert!(
        (0..3).any(|j| (centre[j] - truth.run.source_of(det)[j]).abs() > 1e-6),
        "the measured source equals the true one"
    );
}

/// The values of a `.tra` line (comma- or space-separated).
fn tra_values(text: &str) -> Vec<f64> {
    text.split([',', ' '])
        .filter(|t| !t.trim().is_empty())
        .map(|t| t.trim().parse().unwrap())
        .collect()
}

/// `x, y, z, yaw, pitch, roll` of a row-order world ← volume matrix, by hand: R = Rz(yaw)·
/// Ry(pitch)·Rx(roll) has R20 = −sin(pitch), R21 = cos(pitch)·sin(roll), R22 = cos(pitch)·cos(roll),
/// R10 = sin(yaw)·cos(pitch), R00 = cos(yaw)·cos(pitch).
fn xyzypr(m: &[f64]) -> [f64; 6] {
    [
        m[3],
        m[7],
        m[11],
        m[4].atan2(m[0]).to_degrees(),
        (-m[8]).asin().to_degrees(),
        m[9].atan2(m[10]).to_degrees(),
    ]
}

#[test]
fn autoscoper_tracking_results_give_the_residuals_put_into_them() {
    // The exported truth .tra is what a perfect tracking saves; moved by OFFSET in the world it is
    // a tracking whose every pose is off by OFFSET.
    let (_tmp, out, dest) = common::exported("tests/scenarios/evaluate.toml", "autoscoper", &[]);
    let moved = |run: &Path| -> Vec<f64> {
        let mut m =
            tra_values(&std::fs::read_to_string(run.join("truth/model_femur.tra")).unwrap());
        for (k, o) in OFFSET.iter().enumerate() {
            m[4 * k + 3] += o;
        }
        m
    };
    let join = |v: &[f64], sep: &str| v.iter().map(|x| num(*x)).collect::<Vec<_>>().join(sep);
    let variants: [(&str, &dyn Fn(&[f64]) -> String); 4] = [
        ("model_femur.tra", &|m| join(m, ",") + "\n"),
        // Column order, space-separated.
        ("model_femur.tra", &|m| {
            let col: Vec<f64> = (0..16).map(|k| m[(k % 4) * 4 + k / 4]).collect();
            join(&col, " ") + "\n"
        }),
        ("model_femur.tra", &|m| join(&xyzypr(m), ",") + "\n"),
        // All volumes of trial `model` (only femur), named after the trial.
        ("model.tra", &|m| join(m, ",") + "\n"),
    ];
    for (i, (name, make)) in variants.iter().enumerate() {
        for (_, truth) in truths(&out) {
            let run = dest.join(&truth.run.id);
            std::fs::write(run.join(name), make(&moved(&run))).unwrap();
        }
        let report = evaluate_xmalab(&out, &dest, name, Default::default());
        assert_offset_residuals(&report, &format!("variant {i}: {name}"));
    }
    // Bad files: the run folder, line and what would be valid.
    let first = truths(&out).remove(0).1.run.id;
    let bad = |name: &str, text: &str| {
        std::fs::write(dest.join(&first).join(name), text).unwrap();
        evaluate_refused(&out, &dest, name, &[])
    };
    let e = bad("femur.tra", "1,2,3,0,0,0\n");
    assert!(
        e.contains("names no trial") && e.contains("model_femur.tra"),
        "{e}"
    );
    let e = bad("model_femur.tra", "1,2,3,0,0\n");
    assert!(e.contains("5 values for 1 volume(s)"), "{e}");
    let e = bad("model_femur.tra", "1,2,3,0,0,0\n1,2,3,0,0,0\n");
    assert!(e.contains("2 frame(s)") && e.contains(":2"), "{e}");
    let e = bad("model_femur.tra", "NaN,2,3,0,0,0\n");
    assert!(e.contains("NaN in some values"), "{e}");
    let e = bad("model_femur.tra", "1,2,3,0,0,x\n");
    assert!(e.contains("`x` is not a finite number"), "{e}");
    // Untracked (NaN everywhere, as C++ prints it): the run is excluded, not an error.
    std::fs::write(
        dest.join(&first).join("model_femur.tra"),
        "-nan -nan -nan nan nan nan\n",
    )
    .unwrap();
    for (_, truth) in truths(&out).into_iter().skip(1) {
        let run = dest.join(&truth.run.id);
        std::fs::write(run.join("model_femur.tra"), join(&moved(&run), ",") + "\n").unwrap();
    }
    let o = evaluate_cli(&out, &dest, "model_femur.tra", &["--format", "csv"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// tests/scenarios/sequence.toml (one sequence of 5 frames, the femur flexing) and its export
/// for `to`, with the truths of its frames in frame order.
fn sequence_exported(to: &str) -> (tempfile::TempDir, PathBuf, PathBuf, Vec<Truth>) {
    let (tmp, out, dest) = common::exported("tests/scenarios/sequence.toml", to, &[]);
    let frames: Vec<Truth> = truths(&out).into_iter().map(|t| t.1).collect();
    let indices: Vec<u32> = frames
        .iter()
        .map(|t| t.run.frame.as_ref().unwrap().index)
        .collect();
    assert_eq!(indices, [0, 1, 2, 3, 4]);
    (tmp, out, dest, frames)
}

/// The offset put into frame k of a hand-made result of a sequence, mm: (k + 1) · 0.1 along x,
/// so that a line or row read as another frame's shows.
fn frame_offset(k: usize) -> [f64; 3] {
    [0.1 * (k + 1) as f64, 0.0, 0.0]
}

/// Reads the results `name` of the sequence from `dest/n0-r00/` as `evaluate --results-in dest`
/// does, and asserts that in frame k the femur is at its truth pose moved by `offset(k)`.
fn assert_frame_offsets(
    out: &Path,
    dest: &Path,
    name: &str,
    frames: &[Truth],
    offset: &dyn Fn(usize) -> [f64; 3],
) {
    let runs = rsasim::evaluate::input::load_truths(out).unwrap();
    let measured =
        rsasim::evaluate::input::load_per_run(name, Some(dest), &runs, out, Default::default())
            .unwrap_or_else(|e| panic!("{name}: {e:?}"));
    assert_eq!(measured.len(), frames.len(), "{name}");
    for (k, truth) in frames.iter().enumerate() {
        let (position, rotation) = measured[&truth.run.id].phantoms["femur"];
        let p = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
        let moved = p.position_mm + glam::DVec3::from_array(offset(k));
        assert!(
            (position - moved).length() < 1e-9,
            "{name}, frame {k}: {position} instead of {moved}"
        );
        let turn = (rotation.unwrap() - p.rotation).to_cols_array();
        assert!(turn.iter().all(|x| x.abs() < 1e-9), "{name}, frame {k}");
    }
}

/// Asserts the femur's trueness is zero in every position and angle over the sequence's 5
/// frames.
fn assert_zero_trueness(report: &Report, name: &str) {
    assert_eq!(report.runs_scored, 5, "{name}");
    let femur = table(report, "phantom-femur");
    for (group, columns) in [
        ("position", ["x", "y", "z"]),
        ("orientation", ["α", "β", "γ"]),
    ] {
        for column in columns {
            let t = trueness(femur, 0, group, column);
            assert!(t.abs() < 1e-9, "{name} {column}: {t}");
        }
    }
}

/// Autoscoper's tracking of a sequence's trial, one line a frame (the exported truth saved as
/// Autoscoper names the tracking of trial `model.cfg`): zero error in every frame; line k is
/// frame k's pose; a line too few or too many is refused naming the file, the line and the
/// sequence's frames, and nothing is written.
#[test]
fn a_sequences_tracking_is_read_line_by_line_frame_by_frame() {
    let (_tmp, out, dest, frames) = sequence_exported("autoscoper");
    let trial = dest.join("n0-r00");
    let truth_tra = std::fs::read_to_string(trial.join("truth/model_femur.tra")).unwrap();
    assert_eq!(truth_tra.lines().count(), 5);
    std::fs::write(trial.join("model_femur.tra"), &truth_tra).unwrap();
    assert_frame_offsets(&out, &dest, "model_femur.tra", &frames, &|_| [0.0; 3]);
    let report = evaluate_xmalab(&out, &dest, "model_femur.tra", Default::default());
    assert_zero_trueness(&report, "model_femur.tra");
    // Line k moved by frame k's offset in the world: read as frame k's pose.
    let lines: Vec<Vec<f64>> = truth_tra.lines().map(tra_values).collect();
    let moved: Vec<String> = lines
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let mut m = m.clone();
            for (i, o) in frame_offset(k).iter().enumerate() {
                m[4 * i + 3] += o;
            }
            m.iter().map(|x| num(*x)).collect::<Vec<_>>().join(",") + "\n"
        })
        .collect();
    std::fs::write(trial.join("model.tra"), moved.concat()).unwrap();
    assert_frame_offsets(&out, &dest, "model.tra", &frames, &frame_offset);
    // A line too few, a line too many.
    for (kept, line) in [(4, 5), (6, 6)] {
        let text: String = moved.iter().cycle().take(kept).cloned().collect();
        std::fs::write(trial.join("model_femur.tra"), text).unwrap();
        let e = evaluate_refused(&out, &dest, "model_femur.tra", &[]);
        assert!(
            e.contains(&format!("n0-r00/model_femur.tra:{line}:1"))
                && e.contains(&format!(
                    "the file holds {kept} line(s), but sequence n0-r00 has 5 frame(s)"
                )),
            "{e}"
        );
    }
    assert!(
        !std::fs::read_dir(&out).unwrap().any(|e| e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .starts_with("report-")),
        "a refused evaluation writes no report"
    );
}

/// XMALab's exports of a sequence's trial: rigid-body transformations with the `Frame` column
/// (rows given last frame first, each read as the frame it names) and 3-D points without it
/// (row k is frame k); the truth scores zero in every frame; a range of frames with the `Frame`
/// column leaves the others untracked; a row too few without it, a row too many, a `Frame`
/// beyond the trial and a frame twice are refused naming the file, the line and the column.
#[test]
fn a_sequences_xmalab_exports_are_read_row_by_row_honouring_the_frame_column() {
    let (_tmp, out, dest, frames) = sequence_exported("xmalab");
    let trial = dest.join("n0-r00");
    let rigid = |offset: &dyn Fn(usize) -> [f64; 3], order: &[usize]| {
        let rows: Vec<String> = order
            .iter()
            .map(|&k| format!("{},{}\n", k + 1, rigid_body_values(&frames[k], offset(k))))
            .collect();
        format!("Frame,{}\n{}", rigid_body_header(), rows.concat())
    };
    std::fs::write(
        trial.join("xmalab-femur.csv"),
        rigid(&|_| [0.0; 3], &[0, 1, 2, 3, 4]),
    )
    .unwrap();
    let report = evaluate_xmalab(&out, &dest, "xmalab-femur.csv", Default::default());
    assert_zero_trueness(&report, "xmalab-femur.csv");
    std::fs::write(
        trial.join("xmalab-femur.csv"),
        rigid(&frame_offset, &[4, 3, 2, 1, 0]),
    )
    .unwrap();
    assert_frame_offsets(&out, &dest, "xmalab-femur.csv", &frames, &frame_offset);
    let points: Vec<String> = (0..5)
        .map(|k| points_values(&frames[k], frame_offset(k)) + "\n")
        .collect();
    std::fs::write(
        trial.join("xmalab-points.csv"),
        format!("{}\n{}", points_header(&frames[0]), points.concat()),
    )
    .unwrap();
    assert_frame_offsets(&out, &dest, "xmalab-points.csv", &frames, &frame_offset);
    // XMALab's export of frames 2 to 4 (it writes a range only with the Frame column): those
    // three read as their frames, frames 1 and 5 untracked.
    std::fs::write(
        trial.join("xmalab-range.csv"),
        rigid(&frame_offset, &[1, 2, 3]),
    )
    .unwrap();
    let runs = rsasim::evaluate::input::load_truths(&out).unwrap();
    let measured = rsasim::evaluate::input::load_per_run(
        "xmalab-range.csv",
        Some(&dest),
        &runs,
        &out,
        Default::default(),
    )
    .unwrap_or_else(|e| panic!("{e:?}"));
    for (k, truth) in frames.iter().enumerate() {
        let femur = measured[&truth.run.id].phantoms.get("femur");
        if k == 0 || k == 4 {
            assert!(femur.is_none(), "frame {k} is outside the range: {femur:?}");
        } else {
            let p = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
            let moved = p.position_mm + glam::DVec3::from_array(frame_offset(k));
            assert!((femur.unwrap().0 - moved).length() < 1e-9, "frame {k}");
        }
    }
    // Without the Frame column a row too few is refused: which frame is missing is unknown.
    std::fs::write(
        trial.join("bad.csv"),
        format!("{}\n{}", points_header(&frames[0]), points[..4].concat()),
    )
    .unwrap();
    let e = evaluate_refused(&out, &dest, "bad.csv", &[]);
    assert!(
        e.contains(
            "n0-r00/bad.csv:6:1: the file holds 4 data row(s), but sequence n0-r00 has 5 frame(s)"
        ),
        "{e}"
    );
    // Refused: a row too many (the first beyond the trial's frames), a frame beyond the trial
    // (line 3: the second row), a frame twice.
    let file = "n0-r00/bad.csv";
    for (order, text) in [
        (
            vec![0, 1, 2, 3, 4, 4],
            format!("{file}:7:1: the file holds 6 data row(s), but sequence n0-r00 has 5 frame(s)"),
        ),
        (
            vec![0, 5, 1, 2, 3],
            format!("{file}:3:1: `Frame` is `6`, not a frame of the trial (1 to 5)"),
        ),
        (
            vec![0, 1, 1, 2, 3],
            format!("{file}:4:1: frame 2 appears twice"),
        ),
    ] {
        // Frame 6 has no truth: its values are frame 0's.
        let rows: Vec<String> = order
            .iter()
            .map(|&k| {
                format!(
                    "{},{}\n",
                    k + 1,
                    rigid_body_values(&frames[k.min(4)], [0.0; 3])
                )
            })
            .collect();
        std::fs::write(
            trial.join("bad.csv"),
            format!("Frame,{}\n{}", rigid_body_header(), rows.concat()),
        )
        .unwrap();
        let e = evaluate_refused(&out, &dest, "bad.csv", &[]);
        assert!(e.contains(&text), "{e}");
    }
}

/// `export --run` takes a sequence's id and refuses a frame's; a frame whose cameras (or whose
/// place in its sequence) were edited is refused naming its truth.json, with nothing written.
#[test]
fn export_takes_sequence_ids_and_refuses_frames_that_break_the_sequence() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    run_scenario("tests/scenarios/sequence.toml", &out, &[]);
    let export = |dest: &Path, run: &str| common::export(&out, "xmalab", dest, &["--run", run]);
    let dest = tmp.path().join("x");
    let refused = |run: &str| {
        let o = export(&dest, run);
        let e = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(!dest.exists(), "nothing written: {e}");
        e
    };
    let e = refused("n0-r00-f0001");
    assert!(
        e.contains("n0-r00-f0001/truth.json")
            && e.contains("frame 1 of sequence n0-r00")
            && e.contains("--run n0-r00"),
        "{e}"
    );
    let e = refused("n0-r01");
    assert!(
        e.contains("no run `n0-r01`") && e.contains("sequence"),
        "{e}"
    );
    let o = export(&dest, "n0-r00");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read_dir(dest.join("n0-r00/images/model-det1"))
            .unwrap()
            .count(),
        5
    );
    std::fs::remove_dir_all(&dest).unwrap();
    // Frame 3 with detector det1 moved by 1 mm, its manifest entry resealed.
    let rel = "runs/n0-r00-f0003/truth.json";
    let edit = |change: &dyn Fn(&mut serde_json::Value)| {
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(rel)).unwrap()).unwrap();
        change(&mut v);
        std::fs::write(out.join(rel), serde_json::to_vec_pretty(&v).unwrap()).unwrap();
        common::rehash(&out, &[rel]);
    };
    edit(&|v| {
        let x = &mut v["detectors"][0]["position_mm"][0];
        *x = serde_json::json!(x.as_f64().unwrap() + 1.0);
    });
    let e = refused("n0-r00");
    assert!(
        e.contains(rel)
            && e.contains("frame n0-r00-f0003 of sequence n0-r00: the camera of detector `det1` differs from frame n0-r00-f0000's"),
        "{e}"
    );
    edit(&|v| {
        let x = &mut v["detectors"][0]["position_mm"][0];
        *x = serde_json::json!(x.as_f64().unwrap() - 1.0);
        v["frame"]["index"] = serde_json::json!(2);
    });
    let e = refused("n0-r00");
    assert!(
        e.contains(rel)
            && e.contains("frame 2 of sequence \"n0-r00\" (5 frames) is run \"n0-r00-f0002\""),
        "{e}"
    );
}

/// `export --calibration-from` on a sequence: the trial's one calibration is the measured one of
/// the sequence's first frame (the reference program calibrates every frame from the box), not
/// the truth, for every camera.
#[test]
fn a_sequences_trial_takes_the_first_frames_measured_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    common::run_scenario("tests/scenarios/sequence.toml", &out, &[]);
    common::rsasim_ok(&["reconstruct", out.to_str().unwrap()]);
    let name = "measured-rsasim-dlt-markers.json";
    let all = truths(&out);
    let (first_dir, first) = &all[0];
    assert_eq!(first.run.frame.as_ref().unwrap().index, 0);
    // Frame 0's measured sources moved by 1 mm along x, so that its calibration differs from
    // every other frame's (the box stands still, and its sharp binary images give every frame
    // the same bead centres whatever the noise).
    let mut m: rsasim::output::Measured =
        serde_json::from_slice(&std::fs::read(first_dir.join(name)).unwrap()).unwrap();
    for s in &mut m.sources {
        s.position_mm[0] += 1.0;
    }
    std::fs::write(first_dir.join(name), serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    let later: rsasim::output::Measured =
        serde_json::from_slice(&std::fs::read(all[2].0.join(name)).unwrap()).unwrap();
    let dest = tmp.path().join("xma");
    common::export_ok(&out, "xmalab", &dest, &["--calibration-from", name]);
    for det in &first.run.detectors {
        let (_, _, r, t) = mayacam(
            &dest
                .join("n0-r00")
                .join(format!("calibration/{}_MayaCam.txt", det.id)),
        );
        let centre: Vec<f64> = (0..3)
            .map(|j| -(0..3).map(|i| r[i][j] * t[i]).sum::<f64>())
            .collect();
        let source = |m: &rsasim::output::Measured| {
            m.sources
                .iter()
                .find(|s| s.id == det.source)
                .unwrap()
                .position_mm
        };
        for j in 0..3 {
            assert!(
                (centre[j] - source(&m)[j]).abs() < 1e-9,
                "{}: {centre:?} against frame 0's {:?}",
                det.id,
                source(&m)
            );
        }
        assert!(
            (0..3).any(|j| (centre[j] - first.run.source_of(det)[j]).abs() > 1e-6),
            "the measured source equals the true one"
        );
        assert!(
            (0..3).any(|j| (source(&m)[j] - source(&later)[j]).abs() > 1e-9),
            "frames 0 and 2 have the same sources: the test cannot tell which frame was used"
        );
    }
}
