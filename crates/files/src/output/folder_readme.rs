//! `README.md` of an output folder: what the folder is, for someone who receives only the folder.
//! Generated from the scenario's facts (formats, runs, exposures, detectors); it holds no clock
//! time or host name, since it is part of the byte-identical output.

use std::fmt::Write;

use super::Layout;
use crate::expand::Run;
use crate::scenario::Scenario;

/// The text of `README.md` for the output of `scenario` with `runs`. `layout` is `None` for an
/// ordinary output (images and truth together), `Some(Images)` for the blind folder handed to a
/// software under test (no seed, no truth named as present) and `Some(Truth)` for its truth
/// folder.
pub fn folder_readme(scenario: &Scenario, runs: &[Run], layout: Option<Layout>) -> String {
    if layout == Some(Layout::Truth) {
        return truth_readme(scenario, runs);
    }
    let blind = layout == Some(Layout::Images);
    let mut t = String::new();
    let s = scenario;
    let formats: Vec<&str> = s
        .output
        .formats
        .iter()
        .map(|f| match f {
            crate::scenario::ImageFormat::Dicom => "DICOM (dcm)",
            _ => f.extension(),
        })
        .collect();
    let files = s.output.image_files();
    let _ = writeln!(t, "# rsasim output: {}\n", s.name);
    if !s.description.is_empty() && !blind {
        let _ = writeln!(t, "> {}\n", s.description.trim().replace('\n', "\n> "));
    }
    if blind {
        let _ = writeln!(
            t,
            "This folder was written by {} (rsasim: a Radio Stereometric Analysis simulator). It \
             holds simulated RSA X-ray images for a **blind test** of RSA software: the images, \
             `phantoms/` and the nominal set-up only. The exact ground truth is kept in a separate \
             truth folder, bound to this one by the SHA-256 of this folder's `manifest.json`.\n",
            super::program()
        );
        let _ = writeln!(
            t,
            "Scenario `{}`: {} run(s) × {} exposure(s) × {} detector(s), images as {}.\n",
            s.name,
            runs.len(),
            s.exposures.len(),
            s.detectors.len(),
            formats.join(" and ")
        );
    } else {
        let _ = writeln!(
            t,
            "This folder was written by {} (rsasim: a Radio Stereometric Analysis simulator). It \
             holds simulated RSA X-ray images with their exact ground truth, to measure the \
             accuracy of RSA software: give the software the images and `phantoms/`, then compare \
             what it reconstructs with `truth.json`.\n",
            super::program()
        );
        let _ = writeln!(
            t,
            "Scenario `{}`, seed {}: {} run(s) × {} exposure(s) × {} detector(s), images as {}.\n",
            s.name,
            s.seed,
            runs.len(),
            s.exposures.len(),
            s.detectors.len(),
            formats.join(" and ")
        );
    }
    t += "## Layout\n\n";
    t += "```\n";
    t += "README.md        this file\n";
    if blind {
        t += "manifest.json    program and build, and every other file with its SHA-256\n";
        t += "scenario.toml    the nominal set-up (mesh paths into phantoms/)\n";
    } else {
        t += "manifest.json    program and build, scenario SHA-256, seed, and every other file with its SHA-256\n";
        t +=
            "scenario.toml    the scenario as run (defaults resolved, mesh paths into phantoms/)\n";
    }
    t += "phantoms/        what a real RSA user has: bead tables (CSV) and model meshes\n";
    if s.study.is_some() && !blind {
        t += "study.json       the clinical study: which run is which exam of which patient, and the true migration\n";
    }
    t += "runs/<run-id>/   one folder per run\n";
    if !blind {
        t += "  truth.json     exact poses of sources, detectors and phantoms; beads in 3D and in pixels\n";
    }
    for e in &s.exposures {
        for d in &s.detectors {
            for f in &files {
                let _ = writeln!(
                    t,
                    "  {}{}",
                    f.name(&format!("{}-{}", e.id, d.id)),
                    if e.phantoms.is_empty() {
                        String::new()
                    } else {
                        format!(
                            "   exposure {} ({}), detector {}",
                            e.id,
                            e.phantoms.join(", "),
                            d.id
                        )
                    }
                );
            }
        }
    }
    t += "```\n\n";
    if s.imaging.is_attenuation() {
        // Attenuation mode has no noise level: the noise follows from the photons.
        t += "Runs (exposure factor = the multiple of the scenario's exposure, `photons_per_pixel` \
              or `mas`, the run was imaged at; ";
        t += if s.imaging.detector.quantum_noise == Some(false) {
            "the images are expected images, without quantum noise: `quantum_noise = false`):\n\n"
        } else {
            "the images carry the quantum noise of their photons):\n\n"
        };
        t += "| run | exposure factor |\n| --- | --- |\n";
        for r in runs {
            let _ = writeln!(t, "| `{}` | {} |", r.id, r.exposure_factor.unwrap_or(1.0));
        }
    } else {
        t += "Runs (noise level = mean background noise as a fraction of I_max = 2^bpp − 1):\n\n";
        t += "| run | noise level |\n| --- | --- |\n";
        for r in runs {
            let _ = writeln!(t, "| `{}` | {} |", r.id, r.noise_level);
        }
    }
    t += "\nDetectors:\n\n| detector | source | pixels (W × H) | bits per pixel |\n| --- | --- | --- | --- |\n";
    for d in &s.detectors {
        let _ = writeln!(
            t,
            "| `{}` | `{}` | {} × {} | {} |",
            d.id, d.source, d.pixels[0], d.pixels[1], d.bpp
        );
    }
    if !blind {
        t += "\nThe exact pose, pixel pitch and source of every detector in every run are in that \
              run's `truth.json` (`detectors[]`, `sources[]`).\n";
    }
    t += "\n";
    t += "## Conventions\n\n";
    t += "- Every position and pose is in the **calibration box frame** (right-handed), the frame \
          RSA software reconstructs in. Lengths in millimetres (`_mm`), angles in degrees.\n";
    t += "- A pose is `position_mm` plus `rotation` (3 × 3, JSON as three rows). The columns of \
          `rotation` are the local axes in box coordinates: world = rotation · local + position.\n";
    t += "- Detector frame: origin at the centre of the active area; x = r along a row (increasing \
          column index), y = c along a column (increasing row index), z = s the normal towards \
          the source; r × c = s.\n";
    t += "- Pixel (i, j) is column i, row j; row 0 is the first row in the file. The centre of \
          pixel (i, j) is at continuous pixel coordinates (i + 0.5, j + 0.5).\n";
    t += "- Intensities are detector counts, I_max = 2^bpp − 1: 16-bit TIFF and 32-bit float EXR \
          hold the same values.\n";
    if s.output
        .formats
        .contains(&crate::scenario::ImageFormat::Dicom)
    {
        t += "- DICOM files are Digital X-Ray images of a **synthetic patient** (`SYNTHETIC^PHANTOM`: \
              no real person) with the same counts; Imager Pixel Spacing is the detector pitch \
              (row spacing first), and the source distances are the nominal set-up's, not a \
              run's exact geometry. `<exposure>-<detector>.dcm` is for presentation, \
              `…-processing.dcm` for processing.\n";
    }
    let im = &s.imaging;
    if im.samples_per_side() > 1 {
        let n = im.samples_per_side();
        let _ = writeln!(
            t,
            "- Each pixel averages {n} × {n} rays over its area (area sampling), so pixels that \
             a shadow's edge crosses take partial values."
        );
    }
    if let Some(f) = &im.focal_spot {
        let _ = writeln!(
            t,
            "- The X-ray sources have a {} mm focal spot ({}, sampled by {} × {} sub-sources). \
             The source position in `truth.json` is the focal spot's **centre**, and a bead's \
             projected centre is the central projection of its centre from there.",
            f.size_mm,
            match f.profile {
                crate::scenario::SpotProfile::Uniform => "uniform square",
                crate::scenario::SpotProfile::Gaussian => "Gaussian, size = FWHM",
            },
            f.samples,
            f.samples
        );
    }
    t += "- Bead tables in `phantoms/` are in each phantom's own frame (the box's is the box frame): \
          `id,plate,role,x_mm,y_mm,z_mm,diameter_mm`.\n\n";
    t += "## Verifying this folder\n\n";
    t += "Every file but `manifest.json` is listed in it with its SHA-256 (and the manifest \
          carries its own, `manifest_sha256`, over its bytes with that value empty). To check by \
          hand:\n\n";
    t += "```\n";
    t += "python3 -c 'import json; [print(f[\"sha256\"] + \"  \" + f[\"path\"]) for f in json.load(open(\"manifest.json\"))[\"files\"]]' | sha256sum -c\n";
    t += "```\n\n";
    t += "rsasim versions that have it check the same with `rsasim verify THIS_FOLDER`.\n\n";
    t += "## Writing results (software under test)\n\n";
    if blind {
        t += "Write the software's reconstruction of each run as `runs/<run-id>/measured.json` \
              (format `rsasim-measured/1`: `run`, `software`, and `sources[]`, `detectors[]`, \
              `phantoms[]` with the ids of `scenario.toml`, in the box frame, mm), or all runs as \
              one CSV long table `run,kind,id,x_mm,y_mm,z_mm` plus an optional rotation. Whoever \
              holds the truth folder then scores it with \
              `rsasim evaluate THIS_FOLDER --truth TRUTH_FOLDER`. Do not change the files listed \
              in `manifest.json`.\n";
    } else {
        t += "Give the software the images, `phantoms/` and the nominal set-up, never `truth.json`. \
              Write its reconstruction of each run as `runs/<run-id>/measured.json` (format \
              `rsasim-measured/1`: `run`, `software`, and `sources[]`, `detectors[]`, `phantoms[]` \
              with the ids of `truth.json`, in the box frame, mm), or all runs as one CSV long \
              table `run,kind,id,x_mm,y_mm,z_mm` plus an optional rotation. Then \
              `rsasim evaluate THIS_FOLDER` scores it by ISO 5725 (trueness ± precision). Do not \
              change the files listed in `manifest.json`.\n";
    }
    t
}

/// `README.md` of a blind layout's truth folder.
fn truth_readme(s: &Scenario, runs: &[Run]) -> String {
    let mut t = String::new();
    let _ = writeln!(t, "# rsasim truth: {}\n", s.name);
    let _ = writeln!(
        t,
        "This folder was written by {} (rsasim: a Radio Stereometric Analysis simulator). It is \
         the **ground truth** of a blind test: the images given to the software under test are in \
         a separate images folder, which this folder's `manifest.json` names and binds by the \
         SHA-256 of its `manifest.json`. Keep this folder away from the software under test.\n",
        super::program()
    );
    let _ = writeln!(
        t,
        "Scenario `{}`, seed {}: {} run(s).\n",
        s.name,
        s.seed,
        runs.len()
    );
    t += "## Layout\n\n```\n";
    t += "README.md          this file\n";
    t += "manifest.json      program and build, scenario SHA-256, seed, the images folder's binding, every file with its SHA-256\n";
    t += "scenario.toml      the full scenario as run, with its seed and random ranges\n";
    t += "phantoms/          the phantom files the scenario reads\n";
    if s.study.is_some() {
        t += "study.json         the clinical study: which run is which exam of which patient, and the true migration\n";
    }
    t += "runs/<run-id>/truth.json   exact poses of sources, detectors and phantoms; beads in 3D and in pixels\n";
    t += "```\n\n";
    t += "Score the software's results with `rsasim evaluate IMAGES_FOLDER --truth THIS_FOLDER`, \
          and check both folders with `rsasim verify THIS_FOLDER`. Conventions (box frame, mm, \
          degrees, rotation columns = local axes, pixel centres at i + 0.5) are those of the \
          images folder's `README.md`.\n";
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_readme_names_every_run_detector_and_image_and_is_deterministic() {
        let loaded = crate::scenario::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../scenarios/golden/small_biplanar.toml"),
        )
        .unwrap();
        let models = crate::phantom::build(&loaded).unwrap();
        let runs = crate::expand::expand(&loaded.scenario, &models);
        let text = folder_readme(&loaded.scenario, &runs, None);
        assert_eq!(text, folder_readme(&loaded.scenario, &runs, None));
        for r in &runs {
            assert!(text.contains(&format!("`{}`", r.id)), "run {}", r.id);
        }
        for d in &loaded.scenario.detectors {
            assert!(text.contains(&format!("`{}`", d.id)));
        }
        assert!(text.contains("sha256sum") && text.contains("rsasim verify"));
        assert!(text.contains("measured.json"));
        assert!(text.contains(&format!("seed {}", loaded.scenario.seed)));
        // The blind images folder's README names no seed and no truth file as present.
        let blind = folder_readme(&loaded.scenario, &runs, Some(Layout::Images));
        assert!(
            !blind.contains("seed 42") && !blind.contains("truth.json"),
            "{blind}"
        );
        assert!(blind.contains("--truth"));
        let truth = folder_readme(&loaded.scenario, &runs, Some(Layout::Truth));
        assert!(truth.contains("seed 42") && truth.contains("truth.json"));
    }
}
