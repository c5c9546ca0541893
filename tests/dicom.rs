//! DICOM output and the metadata other readers see, checked with independent tools:
//! `dciodvfy` (Debian `dicom3tools`) validates every DICOM file against the DX IOD, pydicom
//! (Debian `python3-pydicom`) reads spacing, identity and pixels back, `tiffinfo` (Debian
//! `libtiff-tools`) reads the TIFF resolution in pixels per centimetre, and `rsasim verify`
//! covers the new files.
//!
//! A tool that is missing fails the test when `CI` is set; otherwise the test prints a loud
//! `SKIPPED` line and returns.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{read_tiff, rsasim, run_scenario, truths};

/// Whether `tool --probe` runs; if not, fail under CI or print SKIPPED.
fn have(tool: &str, probe: &[&str], package: &str) -> bool {
    let ok = Command::new(tool)
        .args(probe)
        .output()
        .is_ok_and(|o| o.status.success() || !o.stdout.is_empty() || !o.stderr.is_empty());
    if !ok {
        common::skip(&format!("(needs {tool}: apt-get install {package})"));
    }
    ok
}

/// A Python with pydicom: `python3`, else Debian's `/usr/bin/python3`.
fn pydicom_python() -> Option<&'static str> {
    let found = ["python3", "/usr/bin/python3"].into_iter().find(|py| {
        Command::new(py)
            .args(["-c", "import pydicom"])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    if found.is_none() {
        common::skip("(needs pydicom: apt-get install python3-pydicom)");
    }
    found
}

fn dcm_files(out: &Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for (dir, _) in truths(out) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "dcm") {
                v.push(p);
            }
        }
    }
    v.sort();
    v
}

/// Both modes' outputs, simulated once: binary (`tests/scenarios/dicom_binary.toml`) and
/// attenuation (the golden `small_attenuation`, which writes DICOM too).
fn outputs() -> &'static [(PathBuf, tempfile::TempDir)] {
    static OUT: std::sync::OnceLock<Vec<(PathBuf, tempfile::TempDir)>> = std::sync::OnceLock::new();
    OUT.get_or_init(|| {
        [
            "tests/scenarios/dicom_binary.toml",
            "scenarios/golden/small_attenuation.toml",
        ]
        .into_iter()
        .map(|scenario| {
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().join("out");
            run_scenario(scenario, &out, &[]);
            (out, dir)
        })
        .collect()
    })
}

#[test]
fn every_dicom_file_passes_dciodvfy_without_errors() {
    if !have("dciodvfy", &["-help"], "dicom3tools") {
        return;
    }
    let mut checked = 0;
    for (out, _) in outputs() {
        for file in dcm_files(out) {
            let o = Command::new("dciodvfy").arg(&file).output().unwrap();
            let report = format!(
                "{}{}",
                String::from_utf8_lossy(&o.stdout),
                String::from_utf8_lossy(&o.stderr)
            );
            let name = file.file_name().unwrap().to_string_lossy().into_owned();
            let iod = if name.ends_with("-processing.dcm") {
                "DXImageForProcessing"
            } else {
                "DXImageForPresentation"
            };
            assert!(report.contains(iod), "{name}: not a {iod}:\n{report}");
            assert!(
                !report.contains("Error"),
                "{}: dciodvfy reports errors:\n{report}",
                file.display()
            );
            assert!(
                !report.contains("Warning"),
                "{}: dciodvfy warns:\n{report}",
                file.display()
            );
            checked += 1;
        }
    }
    // Binary: 2 runs × 2 exposures × 2 detectors × 2 intents; attenuation: 4 × 2 × 2 × 2.
    assert_eq!(checked, 16 + 32);
}

/// What pydicom reads from one file, as `key=value` lines.
const PYDICOM_SCRIPT: &str = r#"
import hashlib, sys, pydicom
for path in sys.argv[1:]:
    d = pydicom.dcmread(path)
    print("file=" + path)
    print("sop_class=" + d.SOPClassUID.name)
    print("intent=" + d.PresentationIntentType)
    print("imager_pixel_spacing=" + ",".join(repr(float(v)) for v in d.ImagerPixelSpacing))
    print("pixel_spacing=" + ",".join(repr(float(v)) for v in d.PixelSpacing))
    print("size=%d,%d" % (d.Columns, d.Rows))
    print("bits_stored=%d" % d.BitsStored)
    print("photometric=" + d.PhotometricInterpretation)
    print("sid=" + repr(float(d.DistanceSourceToDetector)))
    print("patient=" + str(d.PatientName) + "|" + d.PatientComments)
    print("date=" + d.StudyDate + "," + d.ContentDate)
    print("uids=" + d.StudyInstanceUID + "," + d.SeriesInstanceUID + "," + d.SOPInstanceUID)
    print("kvp=" + (repr(float(d.KVP)) if "KVP" in d else "none"))
    print("uas=" + (str(int(d.ExposureInuAs)) if "ExposureInuAs" in d else "none"))
    print("pixels_sha256=" + hashlib.sha256(d.PixelData).hexdigest())
"#;

fn sha256_le(pixels: &[u16]) -> String {
    use sha2::{Digest, Sha256};
    let bytes: Vec<u8> = pixels.iter().flat_map(|p| p.to_le_bytes()).collect();
    Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn pydicom_reads_spacing_identity_and_the_tiff_pixels() {
    let Some(python) = pydicom_python() else {
        return;
    };
    for (out, _) in outputs() {
        let files = dcm_files(out);
        let o = Command::new(python)
            .arg("-c")
            .arg(PYDICOM_SCRIPT)
            .args(&files)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "pydicom failed:\n{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let text = String::from_utf8(o.stdout).unwrap();
        let records: Vec<std::collections::HashMap<&str, &str>> = text
            .split("file=")
            .skip(1)
            .map(|block| {
                block
                    .lines()
                    .skip(1)
                    .filter_map(|l| l.split_once('='))
                    .collect()
            })
            .collect();
        assert_eq!(records.len(), files.len());
        let attenuation = out
            .join("scenario.toml")
            .exists()
            .then(|| std::fs::read_to_string(out.join("scenario.toml")).unwrap())
            .is_some_and(|t| t.contains("attenuation"));
        let mut study_of_run = std::collections::HashMap::new();
        let mut instances = std::collections::HashSet::new();
        for (file, r) in files.iter().zip(&records) {
            let dir = file.parent().unwrap();
            let name = file.file_name().unwrap().to_str().unwrap();
            let processing = name.ends_with("-processing.dcm");
            let stem = name
                .trim_end_matches("-processing.dcm")
                .trim_end_matches(".dcm");
            let truth = &truths(out).into_iter().find(|(d, _)| d == dir).unwrap().1;
            let det_id = stem.rsplit('-').next().unwrap();
            let det = truth.run.detectors.iter().find(|d| d.id == det_id).unwrap();
            let [px, py] = det.pixel_pitch_mm;
            // Row spacing (the y pitch) first, to the 16 characters DS allows.
            for key in ["imager_pixel_spacing", "pixel_spacing"] {
                let v: Vec<f64> = r[key].split(',').map(|x| x.parse().unwrap()).collect();
                assert!(
                    (v[0] - py).abs() < 1e-12 * py && (v[1] - px).abs() < 1e-12 * px,
                    "{name}: {key} {v:?}, pitch [{px}, {py}]"
                );
            }
            assert_eq!(r["size"], format!("{},{}", det.pixels[0], det.pixels[1]));
            assert_eq!(r["bits_stored"], det.bpp.to_string());
            let (w, h, tiff) = read_tiff(&dir.join(format!("{stem}.tiff")));
            assert_eq!((w, h), (det.pixels[0], det.pixels[1]));
            assert_eq!(
                r["pixels_sha256"],
                sha256_le(&tiff),
                "{name}: pixels differ from the TIFF's"
            );
            let (class, intent) = if processing {
                (
                    "Digital X-Ray Image Storage - For Processing",
                    "FOR PROCESSING",
                )
            } else {
                (
                    "Digital X-Ray Image Storage - For Presentation",
                    "FOR PRESENTATION",
                )
            };
            assert_eq!((r["sop_class"], r["intent"]), (class, intent), "{name}");
            assert!(r["patient"].starts_with("SYNTHETIC^PHANTOM|"));
            assert!(r["patient"].contains("no real person"));
            let sid: f64 = r["sid"].parse().unwrap();
            assert!(sid > 1700.0 && sid < 1900.0, "{name}: SID {sid}");
            if attenuation {
                assert_eq!(r["date"], "20000101,20000101", "the documented default");
                assert_eq!(r["kvp"], "80.0");
                // 10 mAs times the run's exposure level (1.0 or 0.25).
                let f = truth.run.exposure_factor.unwrap();
                assert_eq!(r["uas"], format!("{}", (10_000.0 * f) as u64));
                assert_eq!(r["photometric"], "MONOCHROME1", "raw polarity");
            } else {
                assert_eq!(r["date"], "20240229,20240229", "the scenario's date");
                assert_eq!((r["kvp"], r["uas"]), ("none", "none"));
                assert_eq!(r["photometric"], "MONOCHROME2");
            }
            // One study per run; a stereo pair shares its series; every instance is unique.
            let uids: Vec<&str> = r["uids"].split(',').collect();
            let study = study_of_run
                .entry(truth.run.id.clone())
                .or_insert(uids[0].to_string());
            assert_eq!(study, uids[0], "{name}: one study per run");
            assert!(instances.insert(uids[2].to_string()), "{name}: UID repeats");
            let partner = records.iter().zip(&files).find(|(_, f)| {
                f.parent() == Some(dir)
                    && f.as_path() != file.as_path()
                    && f.file_name()
                        .unwrap()
                        .to_str()
                        .unwrap()
                        .starts_with(stem.rsplit_once('-').unwrap().0)
                    && f.to_str().unwrap().ends_with("-processing.dcm") == processing
            });
            let (partner, _) = partner.expect("the other detector's image");
            assert_eq!(
                partner["uids"].split(',').nth(1),
                Some(uids[1]),
                "{name}: a stereo pair shares its series"
            );
        }
    }
}

#[test]
fn tiffinfo_shows_the_pitch_in_pixels_per_centimetre_and_i_max() {
    if !have("tiffinfo", &[], "libtiff-tools") {
        return;
    }
    let (out, _) = &outputs()[0];
    let file = out.join("runs/n0-r00/calibration-det1.tiff");
    let o = Command::new("tiffinfo").arg(&file).output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    // Pitch 3.0 × 4.5 mm: 10/3 and 10/4.5 pixels per centimetre; 12 bits: I_max 4095.
    assert!(
        text.contains("Resolution: 3.33333, 2.22222 pixels/cm"),
        "{text}"
    );
    assert!(text.contains("Max Sample Value: 4095"), "{text}");
}

#[test]
fn verify_covers_the_dicom_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    run_scenario("tests/scenarios/dicom_binary.toml", &out, &[]);
    let manifest = std::fs::read_to_string(out.join("manifest.json")).unwrap();
    assert!(manifest.contains("runs/n0-r00/model-det2-processing.dcm"));
    assert!(manifest.contains("runs/n0-r00/model-det2.dcm"));
    let o = rsasim(&["verify", out.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    let file = out.join("runs/n0-r00/model-det2.dcm");
    let mut bytes = std::fs::read(&file).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&file, bytes).unwrap();
    let o = rsasim(&["verify", out.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stdout).contains("runs/n0-r00/model-det2.dcm"));
}

/// A dynamic exam's DICOM files as a viewer groups them, read by pydicom (Debian
/// `python3-pydicom`) and validated by dciodvfy: the golden `small_sequence` (2 sequences of 3
/// frames, 2 detectors, 2 exposures) written as DICOM. Each sequence is one study (its id as
/// Study ID); each camera of each exposure one series, whose instances are the frames in order
/// (Instance Number = frame + 1) at the frame's time (Acquisition and Content Time, 20 ms apart
/// at 50 frames per second); no two series share a number within a study.
#[test]
fn a_sequence_is_one_study_with_a_series_per_camera_and_its_frames_in_time_order() {
    let Some(python) = pydicom_python() else {
        return;
    };
    let models = common::root().join("scenarios/golden/models");
    let text = std::fs::read_to_string(common::root().join("scenarios/golden/small_sequence.toml"))
        .unwrap()
        .replace(
            "formats = [\"tiff\", \"exr\"]",
            "formats = [\"tiff\", \"dicom\"]",
        )
        .replace("\"models/", &format!("\"{}/", models.display()));
    assert!(text.contains("\"dicom\"]"));
    let tmp = tempfile::tempdir().unwrap();
    let out = common::run_scenario_text(tmp.path(), "seq", &text);
    let files = dcm_files(&out);
    // 2 sequences × 3 frames × 2 exposures × 2 detectors × the intents (presentation by default).
    assert_eq!(files.len() % 24, 0, "{}", files.len());
    const SCRIPT: &str = r#"
import sys, pydicom
for path in sys.argv[1:]:
    d = pydicom.dcmread(path)
    print("|".join([path, d.StudyInstanceUID, d.StudyID, d.SeriesInstanceUID, str(d.SeriesNumber),
                    str(d.InstanceNumber), d.AcquisitionTime, d.ContentTime, d.PresentationIntentType]))
"#;
    let o = Command::new(python)
        .arg("-c")
        .arg(SCRIPT)
        .args(&files)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    use std::collections::{BTreeMap, BTreeSet};
    let mut studies: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut series: BTreeMap<String, Vec<(u32, String, String)>> = BTreeMap::new();
    let mut numbers: BTreeMap<(String, String), BTreeSet<String>> = BTreeMap::new();
    for line in String::from_utf8_lossy(&o.stdout).lines() {
        let f: Vec<&str> = line.split('|').collect();
        let [
            path,
            study,
            study_id,
            series_uid,
            series_no,
            instance,
            acq,
            content,
            _,
        ] = f[..]
        else {
            panic!("{line}")
        };
        // The run folder is `<sequence>-f<frame>`.
        let run = Path::new(path)
            .parent()
            .unwrap()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let (sequence, frame) = run.rsplit_once("-f").unwrap();
        assert_eq!(study_id, sequence, "{line}");
        studies
            .entry(study.to_string())
            .or_default()
            .insert(run.clone());
        let frame: u32 = frame.parse().unwrap();
        assert_eq!(instance.parse::<u32>().unwrap(), frame + 1, "{line}");
        assert_eq!(acq, content, "{line}");
        series
            .entry(series_uid.to_string())
            .or_default()
            .push((frame, acq.to_string(), run));
        numbers
            .entry((study.to_string(), series_no.to_string()))
            .or_default()
            .insert(series_uid.to_string());
    }
    assert_eq!(studies.len(), 2, "one study per sequence: {studies:?}");
    for runs in studies.values() {
        assert_eq!(runs.len(), 3, "{runs:?}");
    }
    for (uid, mut frames) in series {
        frames.sort();
        assert_eq!(frames.len(), 3, "{uid}: one instance per frame: {frames:?}");
        let times: Vec<&str> = frames.iter().map(|f| f.1.as_str()).collect();
        assert_eq!(
            times,
            ["000000.000000", "000000.020000", "000000.040000"],
            "{uid}"
        );
    }
    for ((study, number), uids) in numbers {
        assert_eq!(
            uids.len(),
            1,
            "study {study}: series number {number} given to {uids:?}"
        );
    }
    if have("dciodvfy", &["-help"], "dicom3tools") {
        for file in &files {
            let o = Command::new("dciodvfy").arg(file).output().unwrap();
            let report = format!(
                "{}{}",
                String::from_utf8_lossy(&o.stdout),
                String::from_utf8_lossy(&o.stderr)
            );
            assert!(
                !report.contains("Error") && !report.contains("Warning"),
                "{}: {report}",
                file.display()
            );
        }
    }
}
