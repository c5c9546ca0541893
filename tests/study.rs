//! Clinical studies (`[study]`): the relative-motion truth of `study.json` checked against an
//! independent computation from the absolute poses in every run's `truth.json`, the sign
//! conventions on the shipped `tka_migration.toml`, double examinations, prefix-stable patients,
//! loose and missing markers, and the located errors of a bad design.

use crate::common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use common::{hashes, root, rsasim, run_scenario};
use glam::{DMat3, DVec3};
use serde_json::Value;

const SCENARIO: &str = "tests/scenarios/study.toml";

/// A rigid transform `x ↦ r·x + t`, built and inverted here from first principles.
#[derive(Clone, Copy, Debug)]
struct Rigid {
    r: DMat3,
    t: DVec3,
}

impl Rigid {
    fn apply(&self, x: DVec3) -> DVec3 {
        self.r * x + self.t
    }
    fn then(&self, inner: &Rigid) -> Rigid {
        // (self ∘ inner)(x) = self.r·(inner.r·x + inner.t) + self.t
        Rigid {
            r: self.r * inner.r,
            t: self.r * inner.t + self.t,
        }
    }
    fn inverse(&self) -> Rigid {
        let rt = self.r.transpose();
        Rigid {
            r: rt,
            t: -(rt * self.t),
        }
    }
}

fn vec3(v: &Value) -> DVec3 {
    DVec3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

/// A pose as JSON (`position_mm` and `rotation` as three rows).
fn rigid(v: &Value) -> Rigid {
    let rows: Vec<DVec3> = (0..3).map(|i| vec3(&v["rotation"][i])).collect();
    Rigid {
        r: DMat3::from_cols(rows[0], rows[1], rows[2]).transpose(),
        t: vec3(&v["position_mm"]),
    }
}

/// Angles `[α, β, γ]` (degrees) of `r = Rx(α)·Ry(β)·Rz(γ)`: multiplying out, row 0 of `r` is
/// `(cβ·cγ, −cβ·sγ, sβ)` and column 2 is `(sβ, −sα·cβ, cα·cβ)`.
fn xyz_angles_deg(r: &DMat3) -> [f64; 3] {
    let m = |row: usize, col: usize| r.col(col)[row];
    let beta = m(0, 2).asin();
    let alpha = (-m(1, 2)).atan2(m(2, 2));
    let gamma = (-m(0, 1)).atan2(m(0, 0));
    [alpha, beta, gamma].map(f64::to_degrees)
}

fn read_json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap())
        .unwrap_or_else(|e| panic!("{path:?}: {e}"))
}

fn phantom<'a>(truth: &'a Value, id: &str) -> &'a Value {
    truth["phantoms"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["id"] == id)
        .unwrap_or_else(|| panic!("no phantom {id}"))
}

/// The implant's pose in the anatomical frame of one run: `P = (B·A)⁻¹·I`.
fn implant_in_anatomical(truth: &Value, study: &Value, reference: &str, implant: &str) -> Rigid {
    let b = rigid(phantom(truth, reference));
    let a = rigid(&study["anatomical_frame"]);
    let i = rigid(phantom(truth, implant));
    b.then(&a).inverse().then(&i)
}

fn segment_id<'a>(study: &'a Value, role: &str) -> &'a str {
    study["segments"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["role"] == role)
        .unwrap()["id"]
        .as_str()
        .unwrap()
}

/// Per patient and exam, the migration computed from the runs' truth files:
/// `(translation of the centre, X-Y-Z angles, MTPM)`.
fn independent_migration(out: &Path, study: &Value) -> BTreeMap<(String, String), [f64; 7]> {
    let reference = segment_id(study, "reference");
    let implant = segment_id(study, "implant");
    let segment = study["segments"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["id"] == implant)
        .unwrap();
    let local_points: Vec<DVec3> = segment["mtpm_points_mm"]
        .as_array()
        .unwrap()
        .iter()
        .map(vec3)
        .collect();
    let reference_exam = study["exams"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["reference"] == true)
        .unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let mut out_map = BTreeMap::new();
    for patient in study["patients"].as_array().unwrap() {
        let runs = patient["runs"].as_object().unwrap();
        let truth_of = |exam: &str| {
            read_json(
                &out.join("runs")
                    .join(runs[exam].as_str().unwrap())
                    .join("truth.json"),
            )
        };
        let p_ref = implant_in_anatomical(&truth_of(&reference_exam), study, reference, implant);
        let points: Vec<DVec3> = local_points.iter().map(|&p| p_ref.apply(p)).collect();
        let centre = points.iter().copied().sum::<DVec3>() / points.len() as f64;
        for exam in runs.keys() {
            let p_e = implant_in_anatomical(&truth_of(exam), study, reference, implant);
            let m = p_e.then(&p_ref.inverse());
            let t = m.apply(centre) - centre;
            let angles = xyz_angles_deg(&m.r);
            let mtpm = points
                .iter()
                .map(|&p| (m.apply(p) - p).length())
                .fold(0.0, f64::max);
            out_map.insert(
                (patient["id"].as_str().unwrap().to_string(), exam.clone()),
                [t.x, t.y, t.z, angles[0], angles[1], angles[2], mtpm],
            );
        }
    }
    out_map
}

/// The test study simulated with `patients` patients into `tmp/out<patients>`.
fn simulate_patients(tmp: &Path, patients: u32) -> PathBuf {
    let models = root().join("scenarios/models");
    let text = std::fs::read_to_string(root().join(SCENARIO))
        .unwrap()
        .replace("../../scenarios/models/", &format!("{}/", models.display()));
    let path = tmp.join(format!("study{patients}.toml"));
    std::fs::write(
        &path,
        text.replace("patients = 3", &format!("patients = {patients}")),
    )
    .unwrap();
    let out = tmp.join(format!("out{patients}"));
    let o = rsasim(
        &[
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--allow-dir",
            models.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

fn simulate(tmp: &Path) -> PathBuf {
    let out = tmp.join("study");
    run_scenario(SCENARIO, &out, &[]);
    out
}

#[test]
fn migration_truth_matches_an_independent_computation_from_the_absolute_poses() {
    let tmp = tempfile::tempdir().unwrap();
    let out = simulate(tmp.path());
    let study = read_json(&out.join("study.json"));
    // study.json is listed and hashed in the manifest like every file.
    let manifest = read_json(&out.join("manifest.json"));
    assert!(
        manifest["files"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f["path"] == "study.json")
    );
    let independent = independent_migration(&out, &study);
    let patients = study["patients"].as_array().unwrap();
    assert_eq!(patients.len(), 3);
    let mut checked = 0;
    for patient in patients {
        let id = patient["id"].as_str().unwrap();
        let migration = patient["migration"].as_array().unwrap();
        // Every exam but the reference, for the one implant.
        assert_eq!(migration.len(), 4, "{id}");
        for m in migration {
            let exam = m["exam"].as_str().unwrap();
            let mine = independent[&(id.to_string(), exam.to_string())];
            let theirs: Vec<f64> = (0..3)
                .map(|k| m["translation_mm"][k].as_f64().unwrap())
                .chain((0..3).map(|k| m["rotation_deg"][k].as_f64().unwrap()))
                .chain([m["mtpm_mm"].as_f64().unwrap()])
                .collect();
            for k in 0..7 {
                assert!(
                    (mine[k] - theirs[k]).abs() < 1e-9,
                    "{id} {exam}: component {k}: from truth.json {mine:?}, study.json {theirs:?}"
                );
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 12);

    // The prescription: each patient's migration is the exam's prescribed translation and angles
    // times one factor 1 + u, |u| ≤ migration_spread = 0.3, the same for every exam.
    let prescribed: [(&str, [f64; 6]); 2] = [
        ("6m", [0.1, -0.2, 0.05, 0.2, -0.1, 0.3]),
        ("1y", [0.15, -0.4, 0.1, 0.5, -0.2, 0.6]),
    ];
    let mut factors = Vec::new();
    for patient in patients {
        let id = patient["id"].as_str().unwrap().to_string();
        let factor = independent[&(id.clone(), "6m".to_string())][1] / -0.2;
        assert!((factor - 1.0).abs() <= 0.3, "{id}: factor {factor}");
        for (exam, values) in &prescribed {
            let got = independent[&(id.clone(), exam.to_string())];
            for k in 0..6 {
                assert!(
                    (got[k] - factor * values[k]).abs() < 1e-9,
                    "{id} {exam}: {got:?} vs {factor} × {values:?}"
                );
            }
        }
        factors.push(factor);
    }
    assert!(factors[0] != factors[1] && factors[1] != factors[2]);

    // Double examinations: zero migration relative to the exam they repeat, yet the patient
    // was repositioned (the limb's pose differs).
    for patient in patients {
        let id = patient["id"].as_str().unwrap().to_string();
        let double = independent[&(id.clone(), "double".to_string())];
        assert!(double.iter().all(|x| x.abs() < 1e-9), "{id}: {double:?}");
        let (one, repeat) = (
            independent[&(id.clone(), "1y".to_string())],
            independent[&(id.clone(), "1y-double".to_string())],
        );
        for k in 0..7 {
            assert!(
                (one[k] - repeat[k]).abs() < 1e-9,
                "{id}: {one:?} vs {repeat:?}"
            );
        }
        let runs = patient["runs"].as_object().unwrap();
        let bone = |exam: &str| {
            let truth = read_json(
                &out.join("runs")
                    .join(runs[exam].as_str().unwrap())
                    .join("truth.json"),
            );
            vec3(&phantom(&truth, "bone")["position_mm"])
        };
        assert!((bone("postop") - bone("double")).length() > 0.1, "{id}");
    }
}

#[test]
fn loose_and_missing_markers_are_in_the_truth_and_in_study_json() {
    let tmp = tempfile::tempdir().unwrap();
    let out = simulate(tmp.path());
    let study = read_json(&out.join("study.json"));
    let planned_k2 = DVec3::new(0.0, 36.0, 2.0);
    let displacement = DVec3::new(0.0, 0.6, -0.3);
    let mut occlusion = [0usize; 2];
    for patient in study["patients"].as_array().unwrap() {
        let id = patient["id"].as_str().unwrap();
        let runs = patient["runs"].as_object().unwrap();
        let loose: Vec<&str> = patient["loose_markers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| {
                assert_eq!(l["segment"], "bone");
                assert_eq!(l["bead"], "K2");
                assert!((vec3(&l["displacement_mm"]) - displacement).length() < 1e-12);
                l["exam"].as_str().unwrap()
            })
            .collect();
        if id == "p02" {
            assert_eq!(loose, ["6m", "1y", "1y-double"]);
        } else {
            assert!(loose.is_empty(), "{id}: {loose:?}");
        }
        for (exam, run) in runs {
            let truth = read_json(
                &out.join("runs")
                    .join(run.as_str().unwrap())
                    .join("truth.json"),
            );
            let bone = phantom(&truth, "bone");
            let pose = rigid(bone);
            let markers = bone["markers"].as_array().unwrap();
            let ids: Vec<&str> = markers.iter().map(|m| m["id"].as_str().unwrap()).collect();
            if id == "p03" {
                assert_eq!(ids, ["K1", "K2", "K3", "K5"], "{exam}");
            } else {
                assert_eq!(ids, ["K1", "K2", "K3", "K4", "K5"], "{exam}");
            }
            // Every image's projected markers list the same beads, each with its binary-mode
            // occlusion (the disc over the component's shadow).
            for image in truth["images"].as_array().unwrap() {
                for m in image["markers"].as_array().unwrap() {
                    occlusion[usize::from(m["occluded"].as_bool().unwrap())] += 1;
                }
                let projected = image["markers"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|m| m["phantom"] == "bone")
                    .count();
                assert_eq!(projected, ids.len());
            }
            let k2 = markers.iter().find(|m| m["id"] == "K2").unwrap();
            let local = pose.inverse().apply(vec3(&k2["position_mm"]));
            let expected = if loose.contains(&exam.as_str()) {
                planned_k2 + displacement
            } else {
                planned_k2
            };
            assert!((local - expected).length() < 1e-9, "{id} {exam}: {local}");
        }
    }
    // Most beads are clear of the component; the cage beads behind it are not.
    assert!(
        occlusion[0] > occlusion[1] && occlusion[1] > 0,
        "{occlusion:?}"
    );
}

/// The shipped study, expanded in memory: the sign conventions docs/src/guide/clinical-study.md states.
#[test]
fn on_the_shipped_study_subsidence_is_proximal_and_the_tilt_turns_proximal_forward() {
    let loaded = rsasim::scenario::load(&root().join("scenarios/tka_migration.toml")).unwrap();
    let models = rsasim::phantom::build(&loaded).unwrap();
    let runs = rsasim::expand::expand(&loaded.scenario, &models);
    assert_eq!(runs.len(), 100);
    assert_eq!(runs[0].id, "p01-e0-postop");
    assert_eq!(runs[99].id, "p20-e4-2y");
    let mut ids: Vec<&str> = runs[..5].iter().map(|r| r.id.as_str()).collect();
    ids.sort();
    assert_eq!(
        ids,
        [
            "p01-e0-postop",
            "p01-e1-double",
            "p01-e2-3m",
            "p01-e3-1y",
            "p01-e4-2y"
        ]
    );
    let pose = |run: &rsasim::expand::Run, id: &str| {
        let p = run.phantoms.iter().find(|p| p.id == id).unwrap();
        Rigid {
            r: p.rotation,
            t: p.position_mm,
        }
    };
    // Anatomical frame = the bone's frame; the component's frame coincides with it nominally.
    for patient in 0..20 {
        let exams = &runs[patient * 5..patient * 5 + 5];
        let p = |k: usize| {
            pose(&exams[k], "femur")
                .inverse()
                .then(&pose(&exams[k], "component"))
        };
        let p_ref = p(0);
        for (k, subsidence_mm, tilt_deg) in [(2, 0.1, 0.1), (3, 0.2, 0.2), (4, 0.3, 0.3)] {
            let m = p(k).then(&p_ref.inverse());
            // The centre of the five MTPM points (component frame = anatomical frame here).
            let centre = DVec3::new(0.0, -7.4, -8.6);
            let moved = m.apply(p_ref.apply(centre)) - p_ref.apply(centre);
            assert!(
                (moved - DVec3::new(0.0, subsidence_mm, 0.0)).length() < 1e-9,
                "patient {patient} exam {k}: {moved}"
            );
            let angles = xyz_angles_deg(&m.r);
            assert!((angles[0] - tilt_deg).abs() < 1e-9 && angles[1].abs() < 1e-9);
            // A positive tilt about x turns +y towards +z: the anterior flange's top (proximal)
            // moves anterior.
            let flange = p_ref.apply(DVec3::new(0.0, 27.0, 25.0));
            assert!((m.apply(flange) - flange).z > 0.0);
        }
    }
}

/// Patient k's runs are the same whether the study has k or k + 3 patients: expanded runs and
/// every file of their run folders.
#[test]
fn patients_are_prefix_stable() {
    let tmp = tempfile::tempdir().unwrap();
    let write = |patients: u32| simulate_patients(tmp.path(), patients);
    let (few, many) = (write(1), write(4));
    let runs_of = |out: &Path| -> Vec<(String, String)> {
        hashes(out)
            .into_iter()
            .filter(|(p, _)| p.starts_with("runs/p01-"))
            .collect()
    };
    let (a, b) = (runs_of(&few), runs_of(&many));
    assert_eq!(a.len(), 15, "{a:?}");
    assert_eq!(a, b);
    let study = |out: &Path| read_json(&out.join("study.json"));
    assert_eq!(study(&few)["patients"][0], study(&many)["patients"][0]);
    assert_eq!(study(&many)["patients"].as_array().unwrap().len(), 4);
    assert!(
        hashes(&many)
            .iter()
            .any(|(p, _)| p.starts_with("runs/p04-e4-1y-double/"))
    );
}

/// Each bad design gives exit code 2 and an error naming the file, line and key.
#[test]
fn bad_designs_are_located_errors() {
    let base = std::fs::read_to_string(root().join(SCENARIO)).unwrap();
    let cases: [(&str, String, &str); 8] = [
        (
            "protocol",
            base.replace("[study]\n", "[protocol]\nruns_per_level = 2\n\n[study]\n"),
            "`protocol`: a scenario with [study] has no [protocol]",
        ),
        (
            "two references",
            base.replace("role = \"implant\"", "role = \"reference\""),
            "a second reference segment",
        ),
        (
            "implant fixed_to",
            base.replace(
                "id = \"component\"\n",
                "id = \"component\"\nfixed_to = \"bone\"\n",
            ),
            "implant segment `component` is fixed_to another phantom",
        ),
        (
            "double of a later exam",
            base.replace("double_of = \"1y\"", "double_of = \"2y\""),
            "`study.exams[4].double_of`: no exam listed before `1y-double` has the id `2y`",
        ),
        (
            "migration on the reference",
            base.replace(
                "reference = true\n",
                "reference = true\ntranslation_mm = [0.0, 1.0, 0.0]\n",
            ),
            "`study.exams[0].translation_mm`: the reference exam has no migration",
        ),
        (
            "unknown loose bead",
            base.replace("bead = \"K2\"", "bead = \"K9\""),
            "`study.loose_markers[0].bead`: phantom `bone` has no bead `K9`",
        ),
        (
            "model-only implant without MTPM points",
            base.replace(
                "mtpm_points_mm = [[-24.0, -27.0, -5.0], [24.0, -27.0, -5.0], [0.0, 27.0, 25.0]]\n",
                "",
            ),
            "implant segment `component` has no markers, so its MTPM has no points",
        ),
        (
            "exams out of order",
            base.replace("days = 182", "days = 900"),
            "`study.exams[3].days`: exam `1y` is on day 365, before the exam listed above it",
        ),
    ];
    let tmp = tempfile::tempdir().unwrap();
    for (case, text, expected) in cases {
        assert_ne!(text, base, "{case}: the replacement did nothing");
        let path = tmp.path().join("bad.toml");
        std::fs::write(&path, &text).unwrap();
        let out = tmp.path().join("out");
        let o = rsasim(
            &[path.to_str().unwrap(), "--out", out.to_str().unwrap()],
            &[],
        );
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{case}: {stderr}");
        assert!(stderr.contains(expected), "{case}: {stderr}");
        assert!(
            stderr.contains("bad.toml:"),
            "{case}: no file:line in {stderr}"
        );
        assert!(!out.exists(), "{case}: something was written");
    }
}

#[test]
fn in_attenuation_mode_the_migration_truth_matches_the_absolute_poses_too() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("study_attenuation");
    run_scenario("tests/scenarios/study_attenuation.toml", &out, &[]);
    let study = read_json(&out.join("study.json"));
    let independent = independent_migration(&out, &study);
    let mut checked = 0;
    for patient in study["patients"].as_array().unwrap() {
        let id = patient["id"].as_str().unwrap();
        for m in patient["migration"].as_array().unwrap() {
            let mine = independent[&(id.to_string(), m["exam"].as_str().unwrap().to_string())];
            for k in 0..3 {
                assert!((mine[k] - m["translation_mm"][k].as_f64().unwrap()).abs() < 1e-9);
                assert!((mine[3 + k] - m["rotation_deg"][k].as_f64().unwrap()).abs() < 1e-9);
            }
            assert!((mine[6] - m["mtpm_mm"].as_f64().unwrap()).abs() < 1e-9);
            checked += 1;
        }
    }
    assert_eq!(checked, 12);
    // Attenuation mode records, per bead and image, whether it is seen over the metal.
    let truth = read_json(&out.join("runs/p01-e0-postop/truth.json"));
    assert!(
        truth["images"][0]["markers"]
            .as_array()
            .unwrap()
            .iter()
            .all(|m| m["occluded"].is_boolean())
    );
}

/// `study.json` pairs runs with patients and exams, so `reconstruct` and `evaluate` use it only
/// when it is the file the folder's manifest lists: an edited one, or a valid one from another
/// study (here the same design simulated with one patient, whose runs all exist in the folder),
/// is refused with exit code 2 and an error naming it, before anything is written.
#[test]
fn a_study_json_the_manifest_does_not_list_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = simulate(tmp.path());
    let file = out.join("study.json");
    let original = std::fs::read(&file).unwrap();
    let other = simulate_patients(tmp.path(), 1);
    let foreign = std::fs::read(other.join("study.json")).unwrap();
    assert_ne!(foreign, original);
    // Swapping two exams' runs keeps valid JSON of the right shape.
    let mut edited: Value = serde_json::from_slice(&original).unwrap();
    let runs = &mut edited["patients"][0]["runs"];
    let (six, year) = (runs["6m"].clone(), runs["1y"].clone());
    assert_eq!(
        (six.as_str(), year.as_str()),
        (Some("p01-e2-6m"), Some("p01-e3-1y"))
    );
    runs["6m"] = year;
    runs["1y"] = six;
    let tampered = serde_json::to_string_pretty(&edited).unwrap() + "\n";
    let report = tmp.path().join("report");
    for (what, bytes) in [("foreign", foreign), ("tampered", tampered.into_bytes())] {
        std::fs::write(&file, &bytes).unwrap();
        for args in [
            vec!["reconstruct", out.to_str().unwrap()],
            vec![
                "evaluate",
                out.to_str().unwrap(),
                "--report",
                report.to_str().unwrap(),
            ],
        ] {
            let o = rsasim(&args, &[]);
            let stderr = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{what} {args:?}: {stderr}");
            assert!(
                stderr.contains("study.json")
                    && stderr.contains("differs from the study.json")
                    && stderr.contains("manifest.json"),
                "{what} {args:?}: {stderr}"
            );
        }
        assert!(!report.exists(), "{what}: a report was written");
        assert!(
            !out.join("runs/p01-e0-postop").read_dir().unwrap().any(|e| e
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with("measured")),
            "{what}: reconstruct wrote results"
        );
    }
    // The original file passes the check (this test study's one box plate cannot calibrate a
    // view, so the runs themselves then fail, and are reported as such).
    std::fs::write(&file, &original).unwrap();
    let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("study.json"), "{stderr}");
    assert!(stderr.contains("calibration failed"), "{stderr}");
}
