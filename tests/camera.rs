//! `rsasim camera`: a camera computed by hand from a source and four corners (intrinsics,
//! extrinsics, DLT-11 and the pixels of hand-chosen points); a scenario's detectors fed back
//! through the corner path give the same cameras; a run's cameras put every bead on its truth
//! pixel; bad input is refused with exit code 2, the option named and nothing written.

use std::path::Path;

use std::process::Output;

use crate::common::{
    ALLOW_MODELS, MayaCam, beads, read_mayacam as mayacam, rsasim, rsasim_ok, run_scenario, truths,
};

/// The blocks `rsasim camera` prints: (label line, text) in order.
fn blocks(stdout: &[u8]) -> Vec<(String, String)> {
    let text = String::from_utf8(stdout.to_vec()).unwrap();
    let mut out: Vec<(String, String)> = Vec::new();
    for line in text.lines() {
        if let Some(label) = line.strip_prefix("# ") {
            out.push((label.to_string(), String::new()));
        } else if let Some((_, body)) = out.last_mut() {
            body.push_str(line);
            body.push('\n');
        }
    }
    out.iter_mut()
        .for_each(|(_, b)| *b = b.trim_end().to_string() + "\n");
    out
}

/// The block whose label starts with `label`.
fn block<'a>(blocks: &'a [(String, String)], label: &str) -> &'a str {
    &blocks
        .iter()
        .find(|(l, _)| l.starts_with(label))
        .unwrap_or_else(|| panic!("no block {label}"))
        .1
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

fn assert_mayacam_close(a: &MayaCam, b: &MayaCam, what: &str) {
    let flat = |m: &MayaCam| {
        let mut v = m.0.to_vec();
        v.extend(m.1.iter().flatten());
        v.extend(m.2.iter().flatten());
        v.extend(m.3);
        v
    };
    for (x, y) in flat(a).into_iter().zip(flat(b)) {
        assert!(close(x, y, 1e-9), "{what}: {x} vs {y}\n{a:?}\n{b:?}");
    }
}

/// OpenCV projection x ∝ K·(R·X + t), written out here from the file's numbers.
fn project(k: &[[f64; 3]; 3], r: &[[f64; 3]; 3], t: &[f64; 3], p: [f64; 3]) -> [f64; 2] {
    let c: Vec<f64> = (0..3)
        .map(|i| (0..3).map(|j| r[i][j] * p[j]).sum::<f64>() + t[i])
        .collect();
    let h: Vec<f64> = (0..3)
        .map(|i| (0..3).map(|j| k[i][j] * c[j]).sum())
        .collect();
    [h[0] / h[2], h[1] / h[2]]
}

/// DLT-11 reprojection as DLTdv and XMALab define it (L12 = 1).
fn dlt(l: &[f64], p: [f64; 3]) -> [f64; 2] {
    let den = l[8] * p[0] + l[9] * p[1] + l[10] * p[2] + 1.0;
    [
        (l[0] * p[0] + l[1] * p[1] + l[2] * p[2] + l[3]) / den,
        (l[4] * p[0] + l[5] * p[1] + l[6] * p[2] + l[7]) / den,
    ]
}

fn matrix(v: &serde_json::Value) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| v[i][j].as_f64().unwrap()))
}

/// The hand example: source 1000 mm above a 1000 × 800 detector of 0.2 mm pixels lying in
/// z = 0, centred on the origin. Seen from the source (looking down −z), row 0 is the top row
/// at y = +80 mm and columns run towards +x.
const CORNERS: &str = "-100,80,0;100,80,0;100,-80,0;-100,-80,0";

/// `rsasim camera` of a source, corners and pixel counts, with `extra` arguments.
fn camera_of(source: &str, corners: &str, pixels: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "camera",
        "--source-mm",
        source,
        "--corners-mm",
        corners,
        "--pixels",
        pixels,
    ];
    args.extend(extra);
    rsasim(&args, &[])
}

/// [`camera_of`] that must succeed.
fn camera_ok(source: &str, corners: &str, pixels: &str, extra: &[&str]) -> Output {
    let o = camera_of(source, corners, pixels, extra);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

#[test]
fn a_camera_computed_by_hand() {
    let o = camera_ok("0,0,1000", CORNERS, "1000,800", &[]);
    let b = blocks(&o.stdout);
    let (size, k, r, t) = mayacam(block(&b, "det1: MayaCam"));
    // By hand: f = distance / pitch = 1000 / 0.2 = 5000 px. The source's foot (the origin) is
    // the image centre; 0-based pixel centres put the image's outer edges at −0.5 and W − 0.5,
    // so cx = (1000 − 1) / 2 = 499.5 and cy = (800 − 1) / 2 = 399.5.
    assert_eq!(size, [1000.0, 800.0]);
    let want_k = [[5000.0, 0.0, 499.5], [0.0, 5000.0, 399.5], [0.0, 0.0, 1.0]];
    // Camera axes (rows of R, world → camera): x from corner 1 to corner 2 = +x; y from corner
    // 1 to corner 4 = −y; the viewing direction x × y = −z. t = −R·source = (0, 0, 1000).
    let want_r = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    let want_t = [0.0, 0.0, 1000.0];
    assert_mayacam_close(
        &(size, k, r, t),
        &([1000.0, 800.0], want_k, want_r, want_t),
        "MayaCam",
    );
    let json: serde_json::Value = serde_json::from_str(block(&b, "det1: OpenCV")).unwrap();
    assert_eq!(json["image_size_px"], serde_json::json!([1000, 800]));
    let (jk, jr) = (matrix(&json["K"]), matrix(&json["R"]));
    let jt = [0, 1, 2].map(|i| json["t_mm"][i].as_f64().unwrap());
    assert_mayacam_close(&(size, jk, jr, jt), &(size, want_k, want_r, want_t), "JSON");
    // DLT by hand: X = x + 1 and Y = H − y (1-based, origin bottom-left). For a point (X, Y, Z)
    // the camera depth is 1000 − Z, x = 5000·X/(1000 − Z) + 499.5, y = −5000·Y/(1000 − Z) +
    // 399.5; dividing by 1000: X_dlt = (5X − 0.5005Z + 500.5)/(1 − 0.001Z),
    // Y_dlt = (5Y − 0.4005Z + 400.5)/(1 − 0.001Z).
    let l: Vec<f64> = block(&b, "det1: DLT-11")
        .lines()
        .map(|v| v.parse().unwrap())
        .collect();
    let want_l = [
        5.0, 0.0, -0.5005, 500.5, 0.0, 5.0, -0.4005, 400.5, 0.0, 0.0, -0.001,
    ];
    assert_eq!(l.len(), 11);
    for (a, w) in l.iter().zip(want_l) {
        assert!(close(*a, w, 1e-12), "DLT {l:?}");
    }
    // Hand-chosen points and their pixels (OpenCV: 0-based, y down).
    for (p, px) in [
        ([0.0, 0.0, 0.0], [499.5, 399.5]),     // the principal point
        ([10.0, 0.0, 0.0], [549.5, 399.5]),    // 10·5000/1000 = 50 px right
        ([0.0, 10.0, 0.0], [499.5, 349.5]),    // +y is up in the image: 50 px higher
        ([10.0, 0.0, 500.0], [599.5, 399.5]),  // halfway to the source: twice the shift
        ([-100.0, 80.0, 0.0], [-0.5, -0.5]),   // corner 1: the first pixel's outer corner
        ([100.0, -80.0, 0.0], [999.5, 799.5]), // corner 3
    ] {
        for (what, got) in [
            ("MayaCam", project(&k, &r, &t, p)),
            ("JSON", project(&jk, &jr, &jt, p)),
        ] {
            assert!(
                close(got[0], px[0], 1e-12) && close(got[1], px[1], 1e-12),
                "{what} {p:?}: {got:?}, by hand {px:?}"
            );
        }
        let d = dlt(&l, p);
        assert!(
            close(d[0], px[0] + 1.0, 1e-12) && close(d[1], 800.0 - px[1], 1e-12),
            "DLT {p:?}: {d:?}"
        );
    }
    // The same three forms as files.
    let tmp = tempfile::tempdir().unwrap();
    let dest = tmp.path().join("cams");
    let dest_s = dest.to_str().unwrap();
    camera_ok(
        "0,0,1000",
        CORNERS,
        "1000,800",
        &["--detector", "c-arm", "--dir", dest_s],
    );
    let read = |name: &str| std::fs::read_to_string(dest.join(name)).unwrap();
    assert_eq!(read("c-arm_MayaCam.txt"), block(&b, "det1: MayaCam"));
    assert_eq!(read("dlt11.csv"), block(&b, "det1: DLT-11"));
    let file: serde_json::Value = serde_json::from_str(&read("c-arm_opencv.json")).unwrap();
    assert_eq!(file["K"], json["K"]);
    assert_eq!(file["detector"], "c-arm");
    let mut names: Vec<String> = std::fs::read_dir(&dest)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["c-arm_MayaCam.txt", "c-arm_opencv.json", "dlt11.csv"]
    );
}

/// Every detector of a scenario, given back as its source and corners, is the same camera.
#[test]
fn a_scenarios_detectors_through_their_corners_give_the_same_cameras() {
    let scenario = "scenarios/golden/small_biplanar.toml";
    let o = rsasim_ok(&["camera", scenario, ALLOW_MODELS[0], ALLOW_MODELS[1]]);
    let b = blocks(&o.stdout);
    for det in ["det1", "det2"] {
        let json: serde_json::Value =
            serde_json::from_str(block(&b, &format!("{det}: OpenCV"))).unwrap();
        let triple = |v: &serde_json::Value| {
            (0..3)
                .map(|i| v[i].as_f64().unwrap().to_string())
                .collect::<Vec<_>>()
                .join(",")
        };
        let corners: Vec<String> = (0..4).map(|i| triple(&json["corners_mm"][i])).collect();
        if det == "det1" {
            // By hand from the scenario: det1 430 mm square at z = −500, r = +x, c = +y; the
            // corners (u, v) = (0, H), (W, H), (W, 0), (0, 0) of rsasim's frame.
            assert_eq!(
                corners,
                [
                    "-215,215,-500",
                    "215,215,-500",
                    "215,-215,-500",
                    "-215,-215,-500"
                ]
            );
        }
        let size = &json["image_size_px"];
        let o = camera_ok(
            &triple(&json["source_mm"]),
            &corners.join(";"),
            &format!("{},{}", size[0], size[1]),
            &[],
        );
        let back = blocks(&o.stdout);
        let want = block(&b, &format!("{det}: MayaCam"));
        let got = block(&back, "det1: MayaCam");
        assert_eq!(got.lines().count(), want.lines().count());
        assert_mayacam_close(&mayacam(got), &mayacam(want), det);
    }
}

/// The cameras of a run put every bead centre on the pixel the simulator wrote into truth.json
/// (rsasim's (u, v) → OpenCV (u − 0.5, H − v − 0.5) of the flipped image).
#[test]
fn a_runs_cameras_put_every_bead_on_its_truth_pixel() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("eval");
    run_scenario("tests/scenarios/evaluate.toml", &out, &[]);
    let (_, truth) = truths(&out).remove(3);
    let o = rsasim_ok(&["camera", out.to_str().unwrap(), "--run", &truth.run.id]);
    let b = blocks(&o.stdout);
    let mut checked = 0;
    for (detector, bead_mm, pixel) in beads(&truth) {
        let json: serde_json::Value =
            serde_json::from_str(block(&b, &format!("{detector}: OpenCV"))).unwrap();
        let (k, r) = (matrix(&json["K"]), matrix(&json["R"]));
        let t = [0, 1, 2].map(|i| json["t_mm"][i].as_f64().unwrap());
        let h = json["image_size_px"][1].as_f64().unwrap();
        let got = project(&k, &r, &t, bead_mm);
        let want = [pixel[0] - 0.5, h - pixel[1] - 0.5];
        assert!(
            (got[0] - want[0]).abs() < 1e-6 && (got[1] - want[1]).abs() < 1e-6,
            "{detector} {bead_mm:?}: {got:?} vs {want:?}"
        );
        checked += 1;
    }
    assert!(checked > 4, "{checked} beads");
    // An output folder needs --run; a run it does not have, or a changed truth, is refused.
    let refused = |args: &[&str], needle: &str| {
        let o = rsasim(args, &[]);
        let e = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(o.stdout.is_empty() && e.contains(needle), "{e}");
    };
    let out_s = out.to_str().unwrap();
    refused(&["camera", out_s], "--run");
    refused(&["camera", out_s, "--run", "n9-r99"], "no run `n9-r99`");
    let file = out.join("runs").join(&truth.run.id).join("truth.json");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, format!("{text}\n")).unwrap();
    refused(&["camera", out_s, "--run", &truth.run.id], "truth.json");
}

/// Runs `rsasim camera` with corner arguments that must be refused; returns stderr.
fn refused(source: &str, corners: &str, pixels: &str, dest: &Path) -> String {
    let o = camera_of(source, corners, pixels, &["--dir", dest.to_str().unwrap()]);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(o.stdout.is_empty(), "{e}");
    assert!(!dest.exists(), "nothing is written: {e}");
    e
}

#[test]
fn bad_corners_and_sources_are_refused_naming_the_option() {
    let tmp = tempfile::tempdir().unwrap();
    let dest = tmp.path().join("cams");
    let bad = |source: &str, corners: &str, pixels: &str, needles: &[&str]| {
        let e = refused(source, corners, pixels, &dest);
        for n in needles {
            assert!(e.contains(n), "{n:?} not in: {e}");
        }
    };
    // Not a rectangle: corner 3 moved by 1 mm; a parallelogram (corner 2 and 3 sheared).
    bad(
        "0,0,1000",
        "-100,80,0;100,80,0;100,-80,0;-100,-81,0",
        "1000,800",
        &["--corners-mm", "corner 3 lies"],
    );
    bad(
        "0,0,1000",
        "-100,80,0;100,80,0;110,-80,0;-90,-80,0",
        "1000,800",
        &["--corners-mm", "angle at corner 1"],
    );
    // The source behind the image as the corners order it (its mirror image).
    bad(
        "0,0,-1000",
        CORNERS,
        "1000,800",
        &["--source-mm", "-1000.000 mm in front", "4, 3, 2, 1"],
    );
    bad(
        "0,0,0",
        CORNERS,
        "1000,800",
        &["--source-mm", "0.000 mm in front"],
    );
    // Wrong counts.
    bad("0,1000", CORNERS, "1000,800", &["--source-mm", "not 3"]);
    bad(
        "0,0,1000",
        "-100,80,0;100,80,0;100,-80,0",
        "1000,800",
        &["--corners-mm", "3 corner(s) given, not 4"],
    );
    bad(
        "0,0,1000",
        "-100,80,0;100,80;100,-80,0;-100,-80,0",
        "1000,800",
        &["--corners-mm", "corner 2"],
    );
    bad("0,0,1000", CORNERS, "1000", &["--pixels"]);
    bad("0,0,1000", CORNERS, "1000,800,1", &["--pixels", "not 2"]);
    // Not numbers.
    bad(
        "0,zero,1000",
        CORNERS,
        "1000,800",
        &["--source-mm", "`zero`"],
    );
    bad("0,0,inf", CORNERS, "1000,800", &["--source-mm", "`inf`"]);
    bad(
        "0,0,1000",
        "-100,80,0;100,80,0;100,-80,0;-100,-80,NaN",
        "1000,800",
        &["--corners-mm", "corner 4", "`NaN`"],
    );
    bad("0,0,1000", CORNERS, "1000,-800", &["--pixels"]);
    bad("0,0,1000", CORNERS, "1000,8e2", &["--pixels"]);
    // Corners that coincide.
    bad(
        "0,0,1000",
        "0,0,0;0,0,0;0,0,0;0,0,0",
        "1000,800",
        &["--corners-mm", "no extent"],
    );
    // An existing folder is never written into.
    std::fs::create_dir(&dest).unwrap();
    let o = camera_of(
        "0,0,1000",
        CORNERS,
        "1000,800",
        &["--dir", dest.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("already exists"));
    assert_eq!(std::fs::read_dir(&dest).unwrap().count(), 0);
}
