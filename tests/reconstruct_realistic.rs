//! The reference RSA program on attenuation-mode radiographs: bead detection rate and centre
//! error against the truth at several exposures, sharp and blurred, beads over the implant
//! reported occluded rather than matched, and the model found by markers and by its outline.
//!
//! The scene is a scaled-down clinical knee exam (85 kVp, CsI, acrylic plates, the CoCr
//! component in a soft-tissue thigh) on 400 × 400 px detectors of 0.5 mm pitch, so that its
//! 1.5 mm tantalum beads image about 4 px across, as the 1 mm beads of `biplanar_realistic`
//! do on its 0.2986 mm pixels. Bead K7 lies in front of the component's centre on beamline 1.

use crate::common;

use std::path::{Path, PathBuf};

use common::{rsasim, truths};
use glam::DVec2;
use rsasim::output::measured::Measured;
use rsasim::reconstruct::beads::{Centre, find_beads_by, metal_mask};
use rsasim::reconstruct::density::{Reading, density};
use rsasim::reconstruct::shadow::dense_shadow;

/// The scene; `POLARITY` is replaced by the polarity under test.
const SCENARIO: &str = include_str!("scenarios/realistic_small.toml");

/// Writes the scenario with `polarity` into `dir` and runs it into `dir/out`.
fn simulate(dir: &Path, polarity: &str) -> PathBuf {
    simulate_text(dir, &SCENARIO.replace("POLARITY", polarity))
}

/// The scene made as unsharp as `biplanar_realistic_blurred`: 2 × 2 rays per pixel, a 1.2 mm
/// focal spot, a σ 0.15 mm PSF (0.3 px here), scatter at SPR 0.2 (σ 40 mm) and 2 DN of
/// electronic noise, in `polarity`, at exposure ×1 only.
fn blurred_scenario(polarity: &str) -> String {
    SCENARIO
        .replace("POLARITY", polarity)
        .replace(
            "exposure_levels = [1.0, 0.25, 0.0625]",
            "exposure_levels = [1.0]",
        )
        .replace(
            "max_energy_bins = 16",
            "max_energy_bins = 16\npixel_samples = 2\nfocal_spot = { size_mm = 1.2, samples = 3 }",
        )
        .replace(
            "polarity = \"",
            "psf = { sigma_mm = 0.15 }\nscatter = { ratio = 0.2, sigma_mm = 40.0 }\nelectronic_noise_dn = 2.0\npolarity = \"",
        )
}

/// Writes the scenario `text` into `dir` and runs it into `dir/out`.
fn simulate_text(dir: &Path, text: &str) -> PathBuf {
    let models = common::root().join("scenarios/models");
    let text = text.replace("MODELS", models.to_str().unwrap());
    let scenario = dir.join("scene.toml");
    std::fs::write(&scenario, text).unwrap();
    let out = dir.join("out");
    let o = rsasim(
        &[
            scenario.to_str().unwrap(),
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

/// Per image of `exposure`: the truth's projected beads (inside, not occluded) and what the
/// detector found, after an optional blur.
struct Tally {
    beads: usize,
    found: usize,
    errors_px: Vec<f64>,
    /// Detections within 3 px of a bead the truth marks occluded (must stay 0).
    on_occluded: usize,
    occluded: usize,
}

fn tally(
    out: &Path,
    exposure_factor: f64,
    exposure: &str,
    blur_px: f64,
    radius_px: f64,
    centre: Centre,
) -> Tally {
    let mut t = Tally {
        beads: 0,
        found: 0,
        errors_px: Vec::new(),
        on_occluded: 0,
        occluded: 0,
    };
    for (dir, truth) in truths(out) {
        if truth.run.exposure_factor != Some(exposure_factor) {
            continue;
        }
        for image in truth.images.iter().filter(|i| i.exposure == exposure) {
            let (w, _, px) =
                common::read_tiff(&dir.join(format!("{exposure}-{}.tiff", image.detector)));
            let reading = Reading::Radiograph {
                range: 7.0,
                i_max: u16::MAX,
            };
            let mut img = density(&px, w as usize, reading);
            if blur_px > 0.0 {
                img = img.blurred(blur_px);
            }
            let metal = metal_mask(&img, 400);
            let found = find_beads_by(&img, radius_px, &metal, centre);
            // Box beads of the plates facing this beamline only (F1, C1 for det1; F2, C2 for
            // det2): a plate seen edge-on images its beads as overlapping lines.
            let beamline = image.detector.chars().last();
            let facing = |m: &&rsasim::output::truth::ProjectedMarker| {
                m.phantom != "box"
                    || m.id.split('-').next().and_then(|p| p.chars().last()) == beamline
            };
            for m in image.markers.iter().filter(|m| m.inside).filter(facing) {
                let at = DVec2::from(m.pixel);
                let nearest = found
                    .iter()
                    .map(|b| (b.centroid - at).length())
                    .fold(f64::INFINITY, f64::min);
                if m.occluded == Some(true) {
                    t.occluded += 1;
                    if nearest < 3.0 {
                        t.on_occluded += 1;
                    }
                    continue;
                }
                if m.metal_fraction.is_some_and(|f| f > 0.0) {
                    continue; // partly over the metal: may be dropped, never counted as found
                }
                t.beads += 1;
                if nearest < 1.5 {
                    t.found += 1;
                    t.errors_px.push(nearest);
                }
            }
        }
    }
    t
}

fn mean_p95(v: &[f64]) -> (f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let mean = s.iter().sum::<f64>() / s.len().max(1) as f64;
    let p95 = s
        .get(((s.len() as f64 * 0.95) as usize).min(s.len().saturating_sub(1)))
        .copied();
    (mean, p95.unwrap_or(f64::NAN))
}

#[test]
fn beads_are_found_at_every_exposure_sharp_and_blurred_and_never_over_the_metal() {
    let tmp = tempfile::tempdir().unwrap();
    let out = simulate(tmp.path(), "radiograph");
    // Box beads (1.5 mm at magnification 1.32–1.45 on 0.5 mm pixels): radius about 2.1 px. The
    // images sample one ray per pixel centre, so the image itself pixel-locks a bead's centre;
    // a blur applied after that sampling (as here) cannot undo it and widens the bead beyond
    // the window, so the blurred bounds are looser, not tighter.
    let mut failures = Vec::new();
    for (factor, blur, rate_min, mean_max, p95_max) in [
        (1.0, 0.0, 0.98, 0.08, 0.18),
        (0.25, 0.0, 0.98, 0.08, 0.18),
        (0.0625, 0.0, 0.97, 0.10, 0.20),
        (1.0, 1.0, 0.95, 0.15, 0.32),
        (0.0625, 1.0, 0.95, 0.15, 0.32),
    ] {
        let t = tally(&out, factor, "calibration", blur, 2.1, Centre::default());
        let (mean, p95) = mean_p95(&t.errors_px);
        let rate = t.found as f64 / t.beads as f64;
        eprintln!(
            "box, exposure ×{factor}, blur σ {blur} px: {}/{} found ({rate:.3}), centre error mean {mean:.3} px, p95 {p95:.3} px",
            t.found, t.beads
        );
        if t.beads < 150 || rate < rate_min || mean > mean_max || p95 > p95_max {
            failures.push(format!(
                "×{factor} σ {blur}: {t_beads} beads, rate {rate}, mean {mean}, p95 {p95}",
                t_beads = t.beads
            ));
        }
    }
    // The intensity centroid, a Gaussian fit and a sphere fit, on the same detections. The
    // sharp images sample one ray per pixel centre from a point source: the Gaussian does not
    // match that profile and pixel-locks, the sphere (which the reference program uses on such
    // images) much less. Blurred after sampling, neither shape is the profile's, and the sphere
    // must gain nothing worth having over the Gaussian that the reference program keeps on
    // blurred images: the Gaussian's mean and p95 within a tenth of the sphere's.
    for (factor, blur) in [(1.0, 0.0), (0.0625, 0.0), (1.0, 1.0), (0.0625, 1.0)] {
        let c = tally(&out, factor, "calibration", blur, 2.1, Centre::Centroid);
        let g = tally(&out, factor, "calibration", blur, 2.1, Centre::GaussianFit);
        let p = tally(&out, factor, "calibration", blur, 2.1, Centre::SphereFit);
        let (cm, cp) = mean_p95(&c.errors_px);
        let (gm, gp) = mean_p95(&g.errors_px);
        let (sm, sp) = mean_p95(&p.errors_px);
        eprintln!(
            "×{factor} σ {blur}: centroid mean {cm:.3} p95 {cp:.3}; Gaussian fit mean {gm:.3} p95 {gp:.3}; sphere fit mean {sm:.3} p95 {sp:.3} px"
        );
        let sphere_wins = sm < 0.6 * gm && sp < 0.6 * gp;
        let gaussian_holds = gm <= 1.1 * sm && gp <= 1.1 * sp;
        if gm > cm * 1.05 || (blur == 0.0 && !sphere_wins) || (blur > 0.0 && !gaussian_holds) {
            failures.push(format!(
                "×{factor} σ {blur}: centroid {cm}/{cp}, Gaussian {gm}/{gp}, sphere {sm}/{sp} (mean/p95 px)"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    // Model beads over bone-free soft tissue, and K7 over the component on beamline 1: no
    // detection ever sits on an occluded bead.
    for factor in [1.0, 0.0625] {
        let t = tally(
            &out,
            factor,
            "model",
            0.0,
            1.5 * 1.385 / 0.5 / 2.0,
            Centre::default(),
        );
        eprintln!(
            "model, exposure ×{factor}: {}/{} found, {} occluded, {} detections on them",
            t.found, t.beads, t.occluded, t.on_occluded
        );
        assert!(t.occluded >= 2, "the scene must hide K7 in every run");
        assert_eq!(t.on_occluded, 0);
        assert!(t.found as f64 >= 0.95 * t.beads as f64);
    }
}

/// Runs `rsasim reconstruct --model-method method` on `out` (of `polarity`) and reads every
/// run's results.
fn reconstruct(out: &Path, polarity: &str, method: &str) -> Vec<Measured> {
    let o = rsasim(
        &[
            "reconstruct",
            out.to_str().unwrap(),
            "--model-method",
            method,
        ],
        &[],
    );
    assert!(
        o.status.success(),
        "{polarity} {method}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    results(out, &format!("measured-rsasim-dlt-{method}.json"))
}

/// Every run's results of `name`.
fn results(out: &Path, name: &str) -> Vec<Measured> {
    truths(out)
        .iter()
        .map(|(dir, _)| serde_json::from_slice(&std::fs::read(dir.join(name)).unwrap()).unwrap())
        .collect()
}

/// Every combination of the unsharpness options, each on or off (area sampling 2 × 2 rays, a
/// 1.2 mm focal spot without or with a 10 %/100 mm heel effect, a σ 0.15 mm PSF, scatter at SPR
/// 0.2, 2 DN electronic noise): 48 scenes, exposure ×1, two runs each. The reference program
/// must calibrate both beamlines and find the model by its markers in every run, within 0.5 mm.
/// (At 0.7.0 a PSF alone failed calibration on every view: the detector took the PSF's
/// correlated noise for beads, and measured a bead's area where blur shrinks it.)
#[test]
fn the_reference_program_calibrates_and_fits_under_every_combination_of_unsharpness() {
    let base = SCENARIO.replace("POLARITY", "radiograph").replace(
        "exposure_levels = [1.0, 0.25, 0.0625]",
        "exposure_levels = [1.0]",
    );
    let spots = [
        "",
        "\nfocal_spot = { size_mm = 1.2, samples = 3 }",
        "\nfocal_spot = { size_mm = 1.2, samples = 3, heel_percent_per_100_mm = 10.0, anode_direction = \"-c\" }",
    ];
    let mut worst: f64 = 0.0;
    let mut scenes = 0;
    for area in [false, true] {
        for spot in spots {
            for psf in [false, true] {
                for scatter in [false, true] {
                    for noise in [false, true] {
                        let imaging = format!(
                            "max_energy_bins = 16{}{spot}",
                            if area { "\npixel_samples = 2" } else { "" }
                        );
                        let detector = format!(
                            "{}{}{}polarity = \"",
                            if psf {
                                "psf = { sigma_mm = 0.15 }\n"
                            } else {
                                ""
                            },
                            if scatter {
                                "scatter = { ratio = 0.2, sigma_mm = 40.0 }\n"
                            } else {
                                ""
                            },
                            if noise {
                                "electronic_noise_dn = 2.0\n"
                            } else {
                                ""
                            },
                        );
                        let label = format!(
                            "area {area}, spot {}, psf {psf}, scatter {scatter}, noise {noise}",
                            ["off", "on", "with heel"]
                                [spots.iter().position(|s| *s == spot).unwrap()]
                        );
                        let text = base
                            .replace("max_energy_bins = 16", &imaging)
                            .replace("polarity = \"", &detector);
                        let tmp = tempfile::tempdir().unwrap();
                        let out = simulate_text(tmp.path(), &text);
                        let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
                        let err = String::from_utf8_lossy(&o.stderr);
                        assert!(o.status.success(), "{label}: {err}");
                        assert!(!err.contains("calibration failed"), "{label}: {err}");
                        assert!(err.contains("0 of 2 model fit(s) failed"), "{label}: {err}");
                        for ((_, truth), m) in truths(&out)
                            .iter()
                            .zip(results(&out, "measured-rsasim-dlt-markers.json"))
                        {
                            let femur = m.phantoms.iter().find(|p| p.id == "femur").unwrap();
                            let real = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
                            let e =
                                (glam::DVec3::from(femur.position_mm) - real.position_mm).length();
                            assert!(e < 0.5, "{label} {}: femur off by {e} mm", truth.run.id);
                            worst = worst.max(e);
                        }
                        scenes += 1;
                    }
                }
            }
        }
    }
    eprintln!("{scenes} scenes: worst femur position error {worst:.3} mm");
    assert_eq!(scenes, 48);
}

#[test]
fn reconstruct_measures_radiographs_and_raw_images_and_reports_occluded_beads() {
    for polarity in ["radiograph", "raw"] {
        let tmp = tempfile::tempdir().unwrap();
        let out = simulate(tmp.path(), polarity);
        for method in ["markers", "silhouette"] {
            for ((_, truth), m) in truths(&out).iter().zip(reconstruct(&out, polarity, method)) {
                assert_eq!(m.detectors.len(), 2, "{polarity} {method} {}", truth.run.id);
                let femur = m
                    .phantoms
                    .iter()
                    .find(|p| p.id == "femur")
                    .unwrap_or_else(|| {
                        panic!("{polarity} {method} {}: femur not found", truth.run.id)
                    });
                let real = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
                let err = (glam::DVec3::from(femur.position_mm) - real.position_mm).length();
                eprintln!(
                    "{polarity} {method} {}: femur position error {err:.3} mm",
                    truth.run.id
                );
                assert!(err < 0.25, "{polarity} {method} {}: {err} mm", truth.run.id);
                if method == "markers" {
                    // K7 is hidden on det1 in every run, and reported so.
                    let q = femur.quality.as_ref().unwrap();
                    assert!(
                        q.occluded
                            .iter()
                            .any(|o| o.bead == "K7" && o.detector == "det1"),
                        "{polarity} {}: {:?}",
                        truth.run.id,
                        q.occluded
                    );
                    // And every bead the truth marks occluded on an image is reported.
                    for image in truth.images.iter().filter(|i| i.exposure == "model") {
                        for mk in image.markers.iter().filter(|mk| mk.occluded == Some(true)) {
                            assert!(
                                q.occluded
                                    .iter()
                                    .any(|o| o.bead == mk.id && o.detector == image.detector),
                                "{polarity} {}: {} on {} not reported",
                                truth.run.id,
                                mk.id,
                                image.detector
                            );
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn on_blurred_scattered_images_the_implant_is_segmented_and_both_methods_find_it() {
    // With scatter the component no longer clips (its shadow reads the scatter veil, about 3.5
    // here); it must still be recognised as metal (K7 over it reported occluded, never matched)
    // and its outline must still fit.
    for polarity in ["radiograph", "raw"] {
        let tmp = tempfile::tempdir().unwrap();
        let out = simulate_text(tmp.path(), &blurred_scenario(polarity));
        // Nothing of the implant clips: the old clipped-component test would find no metal.
        for (dir, truth) in truths(&out) {
            for image in truth.images.iter().filter(|i| i.exposure == "model") {
                let (w, _, px) =
                    common::read_tiff(&dir.join(format!("model-{}.tiff", image.detector)));
                let reading = match polarity {
                    "raw" => Reading::Raw {
                        offset: 0.0,
                        i_max: u16::MAX,
                    },
                    _ => Reading::Radiograph {
                        range: 7.0,
                        i_max: u16::MAX,
                    },
                };
                let img = density(&px, w as usize, reading);
                assert_eq!(
                    metal_mask(&img, 400).iter().filter(|m| **m).count(),
                    0,
                    "{polarity} {}: the implant clips",
                    image.detector
                );
                let shadow = dense_shadow(&img, None).unwrap();
                assert!(
                    shadow.blob.area > 2000,
                    "{polarity} {}: shadow of {} px",
                    image.detector,
                    shadow.blob.area
                );
            }
        }
        for method in ["markers", "silhouette"] {
            for ((_, truth), m) in truths(&out).iter().zip(reconstruct(&out, polarity, method)) {
                let femur = m
                    .phantoms
                    .iter()
                    .find(|p| p.id == "femur")
                    .unwrap_or_else(|| {
                        panic!("{polarity} {method} {}: femur not found", truth.run.id)
                    });
                let (err, angle_deg) = femur_error(truth, femur);
                eprintln!(
                    "blurred {polarity} {method} {}: femur position error {err:.3} mm, {angle_deg:.3}°",
                    truth.run.id
                );
                assert!(
                    err < 0.1 && angle_deg < 0.2,
                    "{polarity} {method} {}: {err} mm, {angle_deg}°",
                    truth.run.id
                );
                if method == "markers" {
                    let q = femur.quality.as_ref().unwrap();
                    assert!(
                        q.occluded
                            .iter()
                            .any(|o| o.bead == "K7" && o.detector == "det1"),
                        "{polarity} {}: {:?}",
                        truth.run.id,
                        q.occluded
                    );
                }
            }
        }
    }
}

/// The femur's position error (mm, between the origins) and orientation error (degrees, the
/// angle of `R_measured · R_trueᵀ`) of a measured pose against the run's truth.
fn femur_error(
    truth: &rsasim::output::Truth,
    femur: &rsasim::output::measured::MeasuredPose,
) -> (f64, f64) {
    let real = truth.run.phantoms.iter().find(|p| p.id == "femur").unwrap();
    let err = (glam::DVec3::from(femur.position_mm) - real.position_mm).length();
    let rows = femur.rotation.unwrap();
    let r = glam::DMat3::from_cols_array_2d(&rows).transpose();
    let m = r * real.rotation.transpose();
    let angle_deg = ((m.x_axis.x + m.y_axis.y + m.z_axis.z - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    (err, angle_deg)
}

/// Issue 32, item 5: run n2-r19 of the shipped `biplanar_realistic_blurred.toml` (×0.5; shard
/// 59 of 100) settled in a wrong minimum of the outline fit, 2.4 mm and 6.2° off. On graded
/// images each start's fit is refined on edge points measured along its own outline, and the
/// first start, wrong, paired about half of its outline closely enough to pass the mean-distance
/// check. A fit is now also checked against the shadow segmented without the model
/// (`silhouette::outline_agreement`); the run must land within issue 32's 0.1 mm and 0.1°.
#[test]
fn the_blurred_run_whose_outline_fit_fell_into_a_wrong_minimum_is_fitted() {
    blurred_run_within_issue_32_bounds(59, "n2-r19");
}

/// Issue 32, item 5: runs n2-r03 (×0.5; shard 43 of 100) and n0-r17 (×2; shard 17) of the
/// shipped `biplanar_realistic_blurred.toml` settled at the right minimum but 0.18° off, mostly
/// about the axis perpendicular to both beams (`bench/outline_bias.py`, docs/src/results/biases.md).
/// Each round of the fit re-measures its edge points along its own outline, and a pose turned
/// slightly about that axis admitted edge points that held it there, pulling with the Huber
/// weight of 1 px. With `silhouette::HUBER_PX` = 0.25 px at the last search radius both runs land
/// within issue 32's 0.1 mm and 0.1°. Run n0-r15 (×2; shard 15) is the other side: at a fixed
/// 0.25 px from the first iteration, its first start lost the lateral view and was kept 0.9 mm
/// off; the threshold shrinks with the search radius, so it does not. With the calibration that
/// leaves the edge-on plates out, n0-r15 fell into a start that lost one view's outline, and
/// n2-r08 (×0.5; shard 48) and n3-r10 (×0.25; shard 70) into wrong minima that agreed with the
/// segmented outline more than the right fit did: the search now ends only at a fit agreeing in
/// every view, and ranks the fits it tried by closeness first.
#[test]
fn blurred_runs_held_off_by_their_own_edge_points_are_fitted() {
    blurred_run_within_issue_32_bounds(43, "n2-r03");
    blurred_run_within_issue_32_bounds(17, "n0-r17");
    blurred_run_within_issue_32_bounds(15, "n0-r15");
    blurred_run_within_issue_32_bounds(48, "n2-r08");
    blurred_run_within_issue_32_bounds(70, "n3-r10");
}

/// Simulates run `id` (shard `shard` of 100) of the shipped blurred scenario alone, fits the femur
/// by its silhouette and requires it within 0.1 mm and 0.1°, with no quality flag.
fn blurred_run_within_issue_32_bounds(shard: u32, id: &str) {
    run_within_issue_32_bounds("biplanar_realistic_blurred.toml", shard, id, "silhouette");
}

/// Runs of the sharp scenario that were just beyond issue 32's bounds: n2-r15 (×0.5) and n4-r14
/// (×0.125) by markers, 0.101° and 0.111° off while the bead centres came from a Gaussian, which
/// pixel-locks on these images; n3-r06 (×0.25) and n4-r17 (×0.125) by silhouette, 0.106° and
/// 0.101° off while the edge model blurred the predicted edge by a pixel's area, which one ray per
/// pixel centre does not average. Each is simulated alone and must be within 0.1 mm and 0.1° by
/// the method that missed.
#[test]
fn sharp_runs_once_held_off_by_the_bead_model_or_the_edge_blur_are_within_bounds() {
    for (shard, id, method) in [
        (55, "n2-r15", "markers"),
        (94, "n4-r14", "markers"),
        (66, "n3-r06", "silhouette"),
        (97, "n4-r17", "silhouette"),
    ] {
        run_within_issue_32_bounds("biplanar_realistic.toml", shard, id, method);
    }
}

/// Simulates run `id` (shard `shard` of 100) of the shipped scenario `file` alone, fits the femur
/// by `method` and requires it within 0.1 mm and 0.1°, with no quality flag.
fn run_within_issue_32_bounds(file: &str, shard: u32, id: &str, method: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = common::root().join("scenarios").join(file);
    let o = rsasim(
        &[
            scenario.to_str().unwrap(),
            "--shard",
            &format!("{shard}/100"),
            "--out",
            tmp.path().to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = tmp.path().join(format!("shard-{shard}-of-100"));
    let measured = reconstruct(&out, "radiograph", method);
    let runs = truths(&out);
    assert_eq!(runs.len(), 1);
    let truth = &runs[0].1;
    assert_eq!(truth.run.id, id);
    let femur = (measured[0].phantoms.iter())
        .find(|p| p.id == "femur")
        .expect("the femur is fitted");
    let (err, angle_deg) = femur_error(truth, femur);
    eprintln!("{file} {id} {method}: femur position error {err:.3} mm, {angle_deg:.3}°");
    assert!(
        err < 0.1 && angle_deg < 0.1,
        "{file} {id} {method}: {err} mm, {angle_deg}°"
    );
    // A silhouette fit always reports its quality; a markers fit may not.
    assert!(
        femur.quality.is_some() || method == "markers",
        "{id}: no quality"
    );
    if let Some(q) = &femur.quality {
        assert!(q.flags.is_empty(), "{file} {id} {method}: {:?}", q.flags);
    }
}

/// The detection tables of docs/src/results/accuracy.md: per exposure level of an existing radiograph-polarity
/// output (`RSASIM_MEASURE_OUT`, e.g. a run of `scenarios/biplanar_realistic.toml`), the box and
/// model beads' detection rate and centre error (centres measured as the reference program
/// measures them on those images) against the truth, with the beads' radius in pixels from
/// `RSASIM_MEASURE_RADIUS_PX` (default 2.32: 1 mm at magnification 1.385 on 0.2986 mm pixels)
/// and an optional blur `RSASIM_MEASURE_BLUR_PX`. Run with
/// `cargo test --release --test integration reconstruct_realistic:: -- --ignored --nocapture`.
#[test]
#[ignore = "measures an existing output named by RSASIM_MEASURE_OUT"]
fn measure_detection_on_an_output() {
    let Ok(out) = std::env::var("RSASIM_MEASURE_OUT") else {
        eprintln!("set RSASIM_MEASURE_OUT to an attenuation-mode output folder");
        return;
    };
    let num = |name: &str, default: f64| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let radius = num("RSASIM_MEASURE_RADIUS_PX", 2.32);
    let blur = num("RSASIM_MEASURE_BLUR_PX", 0.0);
    let out = PathBuf::from(out);
    let mut factors: Vec<f64> = truths(&out)
        .iter()
        .filter_map(|(_, t)| t.run.exposure_factor)
        .collect();
    factors.sort_by(|a, b| b.total_cmp(a));
    factors.dedup();
    // The centres the reference program measures on these images (`--bead-centre auto`); a blur
    // added here after sampling makes them blurred images.
    let scenario = rsasim::scenario::load(&out.join("scenario.toml"))
        .expect("the output's scenario")
        .scenario;
    let centre = match rsasim::reconstruct::pipeline::bead_centre_method(&scenario) {
        Centre::SphereFit if blur > 0.0 => Centre::GaussianFit,
        c => c,
    };
    println!(
        "| exposure | image | found | rate | centre error mean (px) | p95 (px) | occluded | detections on them |"
    );
    println!("|---:|---|---:|---:|---:|---:|---:|---:|");
    for factor in factors {
        for exposure in ["calibration", "model"] {
            let t = tally(&out, factor, exposure, blur, radius, centre);
            let (mean, p95) = mean_p95(&t.errors_px);
            println!(
                "| ×{factor} | {exposure} | {}/{} | {:.4} | {mean:.3} | {p95:.3} | {} | {} |",
                t.found,
                t.beads,
                t.found as f64 / t.beads.max(1) as f64,
                t.occluded,
                t.on_occluded
            );
        }
    }
}

/// On blurred images, each acrylic plate seen edge-on images as a dense band along its beads,
/// and their centres shorten the measured source distance (docs/src/results/biases.md,
/// `bench/bias.py`). By default the DLT leaves those beads out where the plates are imaged; with
/// `--edge-on-plates fit` it fits them. On the same images (two runs of the shipped blurred
/// scenario, both beamlines), the default must put the sources nearer their true distance, use
/// fewer beads, and say nothing in `software`; the fitted variant names itself.
#[test]
fn on_blurred_images_the_edge_on_plates_are_left_out_and_the_source_distance_kept() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = common::root().join("scenarios/biplanar_realistic_blurred.toml");
    let o = rsasim(
        &[
            scenario.to_str().unwrap(),
            "--shard",
            "0/50",
            "--out",
            tmp.path().to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = tmp.path().join("shard-00-of-50");
    // (mean |depth error| mm, mean beads per view, software) of the results `name`.
    let score = |name: &str| {
        let (mut depth, mut beads, mut n) = (0.0, 0.0, 0.0);
        let mut software = String::new();
        for ((_, truth), m) in truths(&out).iter().zip(results(&out, name)) {
            software = m.software.clone();
            for s in &m.sources {
                let t = truth.run.sources.iter().find(|t| t.id == s.id).unwrap();
                let det = truth
                    .run
                    .detectors
                    .iter()
                    .find(|d| d.source == s.id)
                    .unwrap();
                let axis = (t.position_mm - det.position_mm).normalize();
                depth += (glam::DVec3::from_array(s.position_mm) - t.position_mm)
                    .dot(axis)
                    .abs();
                beads += s.quality.as_ref().unwrap().beads_used.unwrap() as f64;
                n += 1.0;
            }
        }
        (depth / n, beads / n, software)
    };
    let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = rsasim(
        &[
            "reconstruct",
            out.to_str().unwrap(),
            "--edge-on-plates",
            "fit",
            "--measured",
            "measured-fitted.json",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (skipped_mm, skipped_beads, skipped_name) = score("measured-rsasim-dlt-markers.json");
    let (fitted_mm, fitted_beads, fitted_name) = score("measured-fitted.json");
    eprintln!(
        "mean |source depth error|: {skipped_mm:.3} mm on {skipped_beads:.0} beads per view by \
         default, {fitted_mm:.3} mm on {fitted_beads:.0} with the edge-on plates"
    );
    assert!(skipped_mm < 0.5 && skipped_mm < 0.5 * fitted_mm);
    assert!(skipped_beads < fitted_beads);
    assert!(!skipped_name.contains("edge-on"), "{skipped_name}");
    assert!(
        fitted_name.ends_with(", edge-on plates fitted)"),
        "{fitted_name}"
    );
}
