//! The knee at full extension (`tests/scenarios/knee_joint.toml`): `rsasim validate` accepts it,
//! it places the tibia where the library's full-extension pose and markers say, and a
//! binary-mode run of it (one run, 240 × 240 px detectors) images the tibial side where the
//! truth projects its markers.

use crate::common;

use common::{ALLOW_MODELS, read_tiff, rsasim, run_scenario, truths};
use rsasim::phantom::tibia::{MARKER_DIAMETER_MM, TIBIAL_MARKERS_MM};
use rsasim::phantom::tibial::full_extension_position_mm;

const SCENARIO: &str = "tests/scenarios/knee_joint.toml";

#[test]
fn validate_accepts_the_knee_joint_scenario() {
    let o = rsasim(
        &["validate", SCENARIO, ALLOW_MODELS[0], ALLOW_MODELS[1]],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn the_scenario_puts_the_tibia_at_full_extension_with_the_library_s_markers() {
    let text = std::fs::read_to_string(common::root().join(SCENARIO)).unwrap();
    let scenario: toml::Table = toml::from_str(&text).unwrap();
    let phantoms = scenario["phantoms"].as_array().unwrap();
    let tibia = phantoms
        .iter()
        .find(|p| p["id"].as_str() == Some("tibia"))
        .expect("a phantom `tibia`");
    let numbers = |v: &toml::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_float().unwrap())
            .collect()
    };
    assert_eq!(tibia["fixed_to"].as_str(), Some("femur"));
    assert_eq!(
        numbers(&tibia["position_mm"]),
        full_extension_position_mm().to_vec()
    );
    assert_eq!(numbers(&tibia["rotation_deg"]), vec![0.0; 3]);
    let beads = tibia["mesh"]["beads"].as_array().unwrap();
    assert_eq!(beads.len(), TIBIAL_MARKERS_MM.len());
    for (bead, (id, position)) in beads.iter().zip(TIBIAL_MARKERS_MM) {
        assert_eq!(bead["id"].as_str(), Some(id));
        assert_eq!(numbers(&bead["position_mm"]), position.to_vec());
        assert_eq!(bead["diameter_mm"].as_float(), Some(MARKER_DIAMETER_MM));
    }
    // The tibial parts all move with the tibia.
    for id in ["tibia_cancellous", "tray", "insert"] {
        let p = phantoms
            .iter()
            .find(|p| p["id"].as_str() == Some(id))
            .unwrap();
        assert_eq!(p["fixed_to"].as_str(), Some("tibia"), "{id}");
    }
}

/// The scenario in binary mode without the soft tissue, shrunk to one run on 240 × 240 px
/// detectors, its model files named by absolute path (in `scenarios/models`, which [`run_scenario`] allows).
fn binary_variant(models: &std::path::Path) -> String {
    let text = std::fs::read_to_string(common::root().join(SCENARIO)).unwrap();
    let (head, rest) = text.split_at(text.find("[imaging]").unwrap());
    let rest = &rest[rest.find("# --- Beamline 1").unwrap()..];
    // Without the soft tissue, which binary mode would render as solid as the bones.
    let (knee, exposures) = rest.split_at(rest.find("# The leg around the knee").unwrap());
    let exposures = &exposures[exposures.find("[[exposures]]").unwrap()..];
    let text = format!("{head}{knee}{exposures}")
        .replace(", \"leg\"]", "]")
        .replace("exposure_levels = [1.0]", "noise_levels = [0.0]")
        .replace("runs_per_level = 2", "runs_per_level = 1")
        .replace("pixels = [1440, 1440]", "pixels = [240, 240]")
        .replace("../../scenarios/models", models.to_str().unwrap());
    // Materials and nesting are attenuation-mode keys: binary mode would only warn about them.
    text.lines()
        .filter(|l| {
            !["material = ", "inside = ", "thickness_mm = "]
                .iter()
                .any(|k| l.starts_with(k))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn a_binary_mode_run_images_the_tibia_where_the_truth_projects_its_markers() {
    let tmp = tempfile::tempdir().unwrap();
    let models = common::root().join("scenarios/models");
    let scenario = tmp.path().join("knee_binary.toml");
    std::fs::write(&scenario, binary_variant(&models)).unwrap();
    let out = tmp.path().join("out");
    run_scenario(scenario.to_str().unwrap(), &out, &[]);
    let runs = truths(&out);
    assert_eq!(runs.len(), 1);
    let (dir, truth) = &runs[0];
    let mut seen = 0;
    for image in truth.images.iter().filter(|i| i.exposure == "model") {
        let (w, h, pixels) = read_tiff(&dir.join(format!("model-{}.tiff", image.detector)));
        assert_eq!((w, h), (240, 240));
        // A binary image: the knee's shadow at I_max on a background of 0.
        assert!(
            pixels.iter().any(|&p| p == 0),
            "{}: no background",
            image.detector
        );
        let tibial: Vec<_> = image
            .markers
            .iter()
            .filter(|m| m.phantom == "tibia")
            .collect();
        assert_eq!(tibial.len(), 6, "{}: tibial markers", image.detector);
        for m in tibial {
            assert!(m.inside, "{} {} off the detector", image.detector, m.id);
            // The marker lies in the bone, so the pixel under it is in the tibia's shadow.
            let [u, v] = m.pixel.map(|c| c.floor() as usize);
            assert_eq!(
                pixels[v * w as usize + u],
                u16::MAX,
                "{} {}: pixel ({u}, {v}) is not in the shadow",
                image.detector,
                m.id
            );
            seen += 1;
        }
    }
    assert_eq!(seen, 12, "six tibial markers in each of the two views");
}
