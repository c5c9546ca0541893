//! One exam from images to `measured.json`: calibrate every beamline from the box beads, then
//! find each model by marker-based RSA (triangulate its beads, fit its bead geometry) or by
//! model-based RSA (fit its mesh's projected outline to its shadow in every view).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use glam::{DMat3, DVec2, DVec3};

use super::beads::{Centre, find_beads_by, implant_metal_mask_with, metal_mask, touches};
use super::calibrate::{Beamline, Refined, calibrate};
use super::contour::outline;
use super::correspond::{Match, Prediction, match_beads, match_near};
use super::density::Density;
use super::detect::{Blob, bead_area_px, fits_one_bead};
use super::edge::{EdgeWindows, edge_points_along_outline, graded_outline_of, nominal_blur_px};
use super::edge_model::{EdgeModel, MetalTransmission};
use super::model::View;
use super::model_outline::OutlineModel;
use super::model_outline::OutlineSegment;
use super::overprojection::overprojected;
use super::run_images::{RunImage, RunImages};
use super::selvik::calibrate_selvik;
use super::silhouette::{
    GOOD_FIT_PX, MIN_OUTLINE_AGREEMENT, REMEASURE_ROUNDS, Remeasure, SilhouetteView,
    fit_silhouette, outline_agreement, refine_remeasured,
};
use super::split::bead_blobs;
use super::{EdgeOnPlates, Method, ModelMethod};
use crate::expand::{DetectorState, PhantomState};
use crate::geometry::{DetectorFrame, Pose, rotation_rows, rotation_xyz_deg};
use crate::output::exam::{Setup, TableBead};
use crate::output::measured::{
    FitQuality, MEASURED_FORMAT, Measured, MeasuredMethods, MeasuredPoint, MeasuredPose,
    OccludedBead,
};
use crate::scenario::{PlateRole, Scenario};
use crate::trace::{MeshBvh, Object, render_binary};

/// How far (pixels) a nominal prediction may be from the bead's real image.
const SEARCH_PX: f64 = 150.0;

/// A calibrated beamline with what it took.
struct Calibrated {
    beamline: Beamline,
    rms_px: f64,
    beads: usize,
    /// Box beads whose predicted image falls on the metal shadow (attenuation mode).
    occluded: Vec<String>,
}

/// The methods of one `reconstruct` call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Methods {
    /// How every beamline is calibrated.
    pub calibration: Method,
    /// How every model is found; `None`: by [`ModelMethod::for_model`].
    pub model: Option<ModelMethod>,
    /// The profile fitted to a bead in attenuation-mode images; `None`:
    /// [`bead_centre_method`].
    pub bead_centre: Option<Centre>,
    /// DLT: whether the beads of plates seen within 45° of edge-on are fitted.
    pub edge_on_plates: EdgeOnPlates,
}

/// What `software` of every results file rsasim writes starts with; a results file whose
/// `software` does not is another program's.
pub const SOFTWARE_PREFIX: &str = crate::output::measured::REFERENCE_SOFTWARE_PREFIX;

/// The software's name in the results file: `rsasim reconstruct <version> (<calibration>,
/// <model>)`, e.g. `rsasim reconstruct 0.1.0 (dlt, markers)`; `model` is the model method's
/// name, or `auto` when models use different methods (the file's `methods` says which). A
/// bead-centre profile chosen by hand and the edge-on plates' beads in a DLT follow.
pub fn software(
    calibration: Method,
    model: &str,
    bead_centre: Option<Centre>,
    edge_on_plates: EdgeOnPlates,
) -> String {
    let centre = match bead_centre {
        None => "",
        Some(Centre::Centroid) => ", centroid bead centres",
        Some(Centre::GaussianFit) => ", Gaussian bead centres",
        Some(Centre::SphereFit) => ", sphere bead centres",
    };
    let plates = match (calibration, edge_on_plates) {
        (Method::Dlt, EdgeOnPlates::Fit) => ", edge-on plates fitted",
        (Method::Dlt, EdgeOnPlates::Skip) => ", edge-on plates skipped",
        _ => "",
    };
    format!(
        "{SOFTWARE_PREFIX}{} ({}, {model}{centre}{plates})",
        env!("CARGO_PKG_VERSION"),
        calibration.name()
    )
}

/// One run's reconstruction and what could not be found in it.
pub struct RunResult {
    /// The results file's contents.
    pub measured: Measured,
    /// Detectors that could not be calibrated and models that could not be found, each with
    /// the reason, e.g. `model femur: not found: 2 beads visible`.
    pub failures: Vec<String>,
    /// Models (non-box phantoms) attempted.
    pub models_tried: usize,
    /// Models found.
    pub models_found: usize,
}

/// What the calibration knows of each plate of the box: its role, whether it faces the
/// beamline, and whether its beads are fitted when it does not.
#[derive(Debug, Clone, Copy)]
struct PlateUse {
    role: Option<PlateRole>,
    facing: bool,
    fitted_edge_on: bool,
}

/// Reconstructs one run folder. Entities that cannot be found (too few beads) are left out of
/// the result, as a real software would report a failure, and listed in
/// [`RunResult::failures`]. Every beamline is calibrated by `methods.calibration`; each model is
/// found by `methods.model`, with the outline models of `outlines` (by phantom id) for
/// model-based RSA. `software` names the program in the file.
pub fn reconstruct_run(
    setup: &Setup,
    outlines: &BTreeMap<String, OutlineModel>,
    metal: &MetalMeshes,
    run_id: &str,
    dir: &Path,
    methods: Methods,
    software: &str,
) -> Result<RunResult, String> {
    let method = methods.calibration;
    let nominal = &setup.nominal;
    let box_id = setup
        .scenario
        .phantoms
        .iter()
        .find(|p| p.calibration_box.is_some())
        .map(|p| p.id.clone());
    let calibration_exposure = box_id.as_ref().and_then(|b| {
        setup
            .scenario
            .exposures
            .iter()
            .find(|e| e.phantoms.contains(b))
    });
    let mut measured = Measured {
        format: MEASURED_FORMAT.into(),
        run: run_id.into(),
        software: software.into(),
        methods: Some(MeasuredMethods {
            calibration: method.name().into(),
            models: BTreeMap::new(),
        }),
        sources: vec![],
        detectors: vec![],
        phantoms: vec![],
    };
    let mut failures = Vec::new();
    let (mut models_tried, mut models_found) = (0, 0);
    let (Some(box_id), Some(exposure)) = (box_id, calibration_exposure) else {
        return Err(
            "the scenario has no calibration box in any exposure: the scene cannot be calibrated"
                .into(),
        );
    };
    let box_beads = setup
        .beads
        .get(&box_id)
        .ok_or("no bead table for the calibration box in phantoms/")?;
    let plates: Vec<&str> = {
        let mut p: Vec<&str> = box_beads.iter().map(|b| b.plate.as_str()).collect();
        p.dedup();
        p
    };
    // Each plate's normal in the box frame, from the nominal set-up (plates of the first box).
    let box_plates = || {
        setup
            .scenario
            .phantoms
            .iter()
            .filter_map(|p| p.calibration_box.as_ref())
            .flat_map(|b| &b.plates)
    };
    let plate_roles: Vec<Option<PlateRole>> = plates
        .iter()
        .map(|id| box_plates().find(|p| p.id == *id).map(|p| p.role))
        .collect();
    // A plate is imaged when it has a thickness in an attenuation-mode image.
    let plate_fitted_edge_on: Vec<bool> = plates
        .iter()
        .map(|id| {
            let imaged = setup.scenario.imaging.is_attenuation()
                && box_plates().any(|p| p.id == *id && p.thickness_mm.is_some());
            methods.edge_on_plates.fits(imaged)
        })
        .collect();
    let plate_normals: Vec<Option<DVec3>> = plates
        .iter()
        .map(|id| {
            setup
                .scenario
                .phantoms
                .iter()
                .filter_map(|p| p.calibration_box.as_ref())
                .flat_map(|b| &b.plates)
                .find(|p| p.id == *id)
                .map(|p| {
                    let box_rotation = nominal
                        .phantoms
                        .iter()
                        .find(|x| x.kind == "calibration_box")
                        .map_or(glam::DMat3::IDENTITY, |x| x.rotation);
                    box_rotation * rotation_xyz_deg(p.rotation_deg) * DVec3::Z
                })
        })
        .collect();

    let images = RunImages::new(dir, &setup.scenario.imaging);
    let mut beamlines: BTreeMap<String, (Calibrated, &DetectorState)> = BTreeMap::new();
    for det in &nominal.detectors {
        let image = images.get(&exposure.id, det)?;
        let source = nominal.source_of(det);
        let frame = det.frame();
        let preds: Vec<Prediction> = box_beads
            .iter()
            .enumerate()
            .filter_map(|(k, b)| {
                let group = plates.iter().position(|p| *p == b.plate).unwrap_or(0);
                predict(&frame, source, b.position_mm, b.diameter_mm, k, group)
            })
            .collect();
        // The first match uses only the plates that face this beamline: a plate seen edge-on
        // projects into dense lines of beads where a nominal prediction cannot tell neighbours
        // apart. Its beads join once a calibration predicts them to a fraction of a pixel.
        let s_axis = det.rotation.z_axis;
        let facing: Vec<Prediction> = preds
            .iter()
            .filter(|p| plate_normals[p.group].is_none_or(|n| n.dot(s_axis).abs() > 0.7))
            .cloned()
            .collect();
        let uses: Vec<PlateUse> = plate_normals
            .iter()
            .zip(&plate_roles)
            .zip(&plate_fitted_edge_on)
            .map(|((n, role), fitted)| PlateUse {
                role: *role,
                facing: n.is_none_or(|n| n.dot(s_axis).abs() > 0.7),
                fitted_edge_on: *fitted,
            })
            .collect();
        let fit = |matches: &[Match]| fit_beamline(method, matches, box_beads, &plates, &uses, det);
        let image = BeadImage::read(
            setup,
            det,
            &image,
            mean_radius_px(&preds),
            implant_in(setup, metal, &exposure.id, &frame, source),
            methods.bead_centre,
        );
        match calibrate_beamline(&facing, &preds, &image, box_beads, det, fit) {
            Ok(c) => {
                beamlines.insert(det.id.clone(), (c, det));
            }
            Err(e) => failures.push(format!("detector {}: calibration failed: {e}", det.id)),
        }
    }
    for (id, (c, det)) in &beamlines {
        let quality = Some(FitQuality {
            beads_used: Some(c.beads),
            reprojection_rms_px: Some(c.rms_px),
            occluded: c
                .occluded
                .iter()
                .map(|bead| OccludedBead {
                    bead: bead.clone(),
                    detector: id.clone(),
                })
                .collect(),
            ..Default::default()
        });
        if !measured.sources.iter().any(|s| s.id == det.source) {
            measured.sources.push(MeasuredPoint {
                id: det.source.clone(),
                position_mm: c.beamline.source_mm.to_array(),
                quality: quality.clone(),
            });
        }
        measured.detectors.push(MeasuredPose {
            id: id.clone(),
            position_mm: c.beamline.detector.position_mm.to_array(),
            rotation: Some(rotation_rows(&c.beamline.detector.rotation)),
            markers: vec![],
            quality,
        });
    }

    // Found models' poses by id, for the phantoms fixed to them.
    let mut poses: BTreeMap<String, Pose> = BTreeMap::new();
    for phantom in &nominal.phantoms {
        if phantom.kind == "calibration_box" || fixed_to(setup, &phantom.id).is_some() {
            continue;
        }
        let Some(exposure) = setup
            .scenario
            .exposures
            .iter()
            .find(|e| e.phantoms.contains(&phantom.id))
        else {
            continue;
        };
        let beads = setup.beads.get(&phantom.id).filter(|b| !b.is_empty());
        let model_method = ModelMethod::for_model(methods.model, beads.is_some());
        if let Some(m) = measured.methods.as_mut() {
            m.models
                .insert(phantom.id.clone(), model_method.name().into());
        }
        models_tried += 1;
        let found = match model_method {
            ModelMethod::Markers => match beads {
                Some(beads) => find_model(
                    BeadReading {
                        setup,
                        metal,
                        centre: methods.bead_centre,
                    },
                    &images,
                    &exposure.id,
                    &beamlines,
                    beads,
                    box_beads,
                    phantom.position_mm,
                ),
                None => Err(
                    "the model has no beads; use --model-method silhouette for model-based RSA"
                        .into(),
                ),
            },
            ModelMethod::Silhouette => match outlines.get(&phantom.id) {
                Some(model) => find_model_by_outline(
                    setup,
                    metal,
                    &images,
                    &exposure.id,
                    &beamlines,
                    model,
                    phantom,
                ),
                None => Err(
                    "the model has no mesh; model-based RSA fits a mesh's outline (use --model-method markers)"
                        .into(),
                ),
            },
        };
        match found {
            Ok(pose) => {
                models_found += 1;
                if let Some(rows) = pose.rotation {
                    poses.insert(
                        phantom.id.clone(),
                        Pose {
                            position_mm: DVec3::from(pose.position_mm),
                            rotation: DMat3::from_cols_array_2d(&rows).transpose(),
                        },
                    );
                }
                measured.phantoms.push(MeasuredPose {
                    id: phantom.id.clone(),
                    ..pose
                })
            }
            Err(e) => failures.push(format!(
                "model {} ({}): not found: {e}",
                phantom.id,
                model_method.name()
            )),
        }
    }
    measured.phantoms.extend(fixed_poses(setup, &mut poses));
    Ok(RunResult {
        measured,
        failures,
        models_tried,
        models_found,
    })
}

/// The phantom `id` is fixed to (`fixed_to` in the scenario), with its pose in that phantom's
/// frame; `None` for a phantom that moves on its own. In a sequence (`[sequence]`) a phantom
/// fixed to another may also move relative to it (its `motion`, which a blind folder does not
/// show), so there a phantom with beads of its own is fitted on its own.
pub(crate) fn fixed_to(setup: &Setup, id: &str) -> Option<(String, Pose)> {
    let p = setup.scenario.phantoms.iter().find(|p| p.id == id)?;
    let parent = p.fixed_to.clone()?;
    if setup.scenario.sequence.is_some() && setup.beads.get(id).is_some_and(|b| !b.is_empty()) {
        return None;
    }
    Some((
        parent,
        Pose::from_position_euler_deg(p.position_mm, p.rotation_deg),
    ))
}

/// The poses of the phantoms fixed to a found model (directly or through a chain): the model's
/// measured pose composed with their fixed pose in its frame, as the scenario states it. They
/// are added to `poses` and returned without a quality (nothing was fitted for them).
fn fixed_poses(setup: &Setup, poses: &mut BTreeMap<String, Pose>) -> Vec<MeasuredPose> {
    let mut out = Vec::new();
    for _ in 0..setup.scenario.phantoms.len() {
        let before = out.len();
        for p in &setup.scenario.phantoms {
            if poses.contains_key(&p.id) {
                continue;
            }
            let Some((parent, offset)) = fixed_to(setup, &p.id) else {
                continue;
            };
            if let Some(parent_pose) = poses.get(&parent).copied() {
                let pose = parent_pose.compose(&offset);
                poses.insert(p.id.clone(), pose);
                out.push(MeasuredPose {
                    id: p.id.clone(),
                    position_mm: pose.position_mm.to_array(),
                    rotation: Some(rotation_rows(&pose.rotation)),
                    markers: vec![],
                    quality: None,
                });
            }
        }
        if out.len() == before {
            break;
        }
    }
    out
}

/// The predicted blob of a bead: projected centre and expected area.
fn predict(
    frame: &DetectorFrame,
    source: DVec3,
    p: DVec3,
    diameter_mm: f64,
    index: usize,
    group: usize,
) -> Option<Prediction> {
    let uv = frame.project(source, p)?;
    let s = frame.pose.to_local(source);
    let z = frame.pose.to_local(p).z;
    let radius_px = diameter_mm / 2.0 * s.z / (s.z - z) / frame.pixel_pitch_mm[0];
    frame.contains_pixel(uv).then_some(Prediction {
        index,
        uv,
        expected_area: bead_area_px(radius_px),
        group,
    })
}

/// One calibration of a beamline from matched box beads by `method`: the fit and the number of
/// beads it used.
///
/// DLT: every matched bead of the plates that face the beamline, and of those seen edge-on
/// whose beads are fitted ([`EdgeOnPlates`]). Selvik: the beads of the fiducial plate that faces the beamline (the
/// one with the most matches, should several face it) and of every control plate that faces it;
/// beads of plates seen edge-on are left out.
fn fit_beamline(
    method: Method,
    matches: &[Match],
    beads: &[TableBead],
    plates: &[&str],
    uses: &[PlateUse],
    det: &DetectorState,
) -> Result<(Refined, usize), String> {
    let (pixels, pitch) = (det.pixels, det.pixel_pitch_mm);
    match method {
        Method::Dlt => {
            let fitted = |m: &&Match| {
                plates
                    .iter()
                    .position(|p| *p == beads[m.index].plate)
                    .is_none_or(|g| uses[g].facing || uses[g].fitted_edge_on)
            };
            let matches: Vec<&Match> = matches.iter().filter(fitted).collect();
            let points: Vec<DVec3> = matches.iter().map(|m| beads[m.index].position_mm).collect();
            let uvs: Vec<DVec2> = matches.iter().map(|m| m.uv).collect();
            let refined = calibrate(&points, &uvs, pixels, pitch)?;
            let used = matches.len() - refined.dropped.len();
            Ok((refined, used))
        }
        Method::Selvik => {
            let group = |m: &Match| plates.iter().position(|p| *p == beads[m.index].plate);
            let of_group = |g: usize| matches.iter().filter(move |m| group(m) == Some(g));
            let fiducial_plate = (0..plates.len())
                .filter(|&g| uses[g].facing && uses[g].role == Some(PlateRole::Fiducial))
                .max_by_key(|&g| of_group(g).count())
                .ok_or(
                    "Selvik's method needs a fiducial plate facing the beamline; the box has none",
                )?;
            let (f, fu): (Vec<DVec3>, Vec<DVec2>) = of_group(fiducial_plate)
                .map(|m| (beads[m.index].position_mm, m.uv))
                .unzip();
            let (c, cu): (Vec<DVec3>, Vec<DVec2>) = matches
                .iter()
                .filter(|m| {
                    group(m)
                        .is_some_and(|g| uses[g].facing && uses[g].role == Some(PlateRole::Control))
                })
                .map(|m| (beads[m.index].position_mm, m.uv))
                .unzip();
            let refined = calibrate_selvik((&f, &fu), (&c, &cu), pixels, pitch)?;
            let used = f.len() + c.len() - refined.dropped.len();
            Ok((refined, used))
        }
    }
}

/// Match the `first` predictions → calibrate with `fit` → re-predict all `preds` with the
/// calibration → match tightly → calibrate again, until the matches settle.
fn calibrate_beamline(
    first: &[Prediction],
    preds: &[Prediction],
    image: &BeadImage,
    beads: &[TableBead],
    det: &DetectorState,
    fit: impl Fn(&[Match]) -> Result<(Refined, usize), String>,
) -> Result<Calibrated, String> {
    let found = &image.blobs;
    let mut matches = match_beads(first, found, SEARCH_PX);
    let mut result = None;
    for _ in 0..3 {
        let (refined, beads_used) = fit(&matches)?;
        let frame = refined.beamline.frame(det.pixels, det.pixel_pitch_mm);
        let repredicted: Vec<Prediction> = preds
            .iter()
            .filter_map(|p| {
                predict(
                    &frame,
                    refined.beamline.source_mm,
                    beads[p.index].position_mm,
                    beads[p.index].diameter_mm,
                    p.index,
                    p.group,
                )
            })
            .collect();
        result = Some(Calibrated {
            beamline: refined.beamline,
            rms_px: refined.rms_px,
            beads: beads_used,
            occluded: repredicted
                .iter()
                .filter(|p| image.occludes(p.uv, (p.expected_area / std::f64::consts::PI).sqrt()))
                .map(|p| beads[p.index].id.clone())
                .collect(),
        });
        let next = match_near(&repredicted, found, 2.5);
        if next.len() == matches.len()
            && next
                .iter()
                .zip(&matches)
                .all(|(a, b)| a.index == b.index && a.blob == b.blob)
        {
            break;
        }
        matches = next;
    }
    result.ok_or_else(|| "no calibration".into())
}

/// One image's bead candidates and, in attenuation mode, its metal shadow.
struct BeadImage {
    /// Bead candidates: blobs at I_max (binary mode) or [`find_beads_by`]'s beads.
    blobs: Vec<Blob>,
    /// The metal shadow ([`implant_metal_mask`] in an image of a metal implant, else the clipped
    /// components only), row-major; empty in binary mode.
    metal: Vec<bool>,
    /// Image width, pixels.
    width: usize,
}

impl BeadImage {
    /// The candidates of one image of detector `det` for beads of about `radius_px` pixels;
    /// `implant`: the metal implant the image shows ([`implant_in`]); `centre`: the profile fitted
    /// to a bead (`None`: [`bead_centre_method`]).
    fn read(
        setup: &Setup,
        det: &DetectorState,
        image: &RunImage,
        radius_px: f64,
        implant: Option<Implant>,
        centre: Option<Centre>,
    ) -> BeadImage {
        let imaging = &setup.scenario.imaging;
        let width = image.width;
        if !imaging.is_attenuation() {
            return BeadImage {
                blobs: bead_blobs(&image.pixels, width, det.i_max(), radius_px),
                metal: Vec::new(),
                width,
            };
        }
        let img = image.density();
        let bead_area = bead_area_px(radius_px);
        let min_area = (METAL_BEAD_AREAS * bead_area).max(50.0) as usize;
        let metal = match implant {
            Some(i) => implant_metal_mask_with(
                img,
                min_area,
                image.dense_shadow(i.expected_area_px).as_deref(),
            ),
            None => metal_mask(img, min_area),
        };
        BeadImage {
            blobs: find_beads_by(
                img,
                radius_px,
                &metal,
                centre.unwrap_or_else(|| bead_centre_method(&setup.scenario)),
            ),
            metal,
            width,
        }
    }

    /// Whether a bead of `radius_px` pixels imaged at `uv` touches the metal shadow (within one
    /// pixel): its centre cannot be measured there.
    fn occludes(&self, uv: DVec2, radius_px: f64) -> bool {
        !self.metal.is_empty() && touches(&self.metal, self.width, uv, radius_px + 1.0)
    }
}

/// How bead centres are measured in the attenuation images of `scenario` ([`Centre`]): by the
/// sphere's chord profile when its nominal imaging chain declares one ray per pixel centre from a
/// point source, with no detector PSF or MTF and no motion during a pulse (the profile is then
/// the sphere's, and the Gaussian pixel-locks); by the Gaussian otherwise.
pub fn bead_centre_method(scenario: &Scenario) -> Centre {
    let imaging = &scenario.imaging;
    let point_sampled = imaging.pixel_samples.unwrap_or(1) <= 1 && imaging.focal_spot.is_none();
    let unblurred = imaging.detector.psf.is_none() && imaging.detector.mtf.is_none();
    let still =
        (scenario.sequence.as_ref()).is_none_or(|s| !(s.pulse_ms > 0.0) || s.pulse_samples <= 1);
    if point_sampled && unblurred && still {
        Centre::SphereFit
    } else {
        Centre::GaussianFit
    }
}

/// What reading the beads of an image of a set-up needs: the set-up, its metal meshes (for an
/// implant's expected shadow) and the profile fitted to a bead (`None`: [`bead_centre_method`]).
#[derive(Clone, Copy)]
struct BeadReading<'a> {
    setup: &'a Setup,
    metal: &'a MetalMeshes,
    centre: Option<Centre>,
}

/// A metal implant known to be in an image.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Implant {
    /// The area its shadow should cover (pixels), from its meshes at their nominal poses; `None`
    /// when it has no mesh.
    expected_area_px: Option<f64>,
}

/// The meshes of the metal phantoms (by phantom id), each with its bounding volume hierarchy,
/// built once for every run: an implant's expected shadow is rendered for each image, and
/// building the hierarchy anew each time showed in `reconstruct`'s profile.
pub struct MetalMeshes(BTreeMap<String, MeshBvh>);

impl MetalMeshes {
    /// The metal phantoms' meshes of `setup`.
    pub fn of(setup: &Setup) -> MetalMeshes {
        let scenario = &setup.scenario;
        MetalMeshes(
            (scenario.phantoms.iter())
                .filter(|p| p.material.as_deref().is_some_and(|m| scenario.is_metal(m)))
                .filter_map(|p| Some((p.id.clone(), MeshBvh::new(setup.meshes.get(&p.id)?))))
                .collect(),
        )
    }
}

/// The metal implant in the image of `exposure` taken on `frame` from `source_mm`: `None` when
/// the exposure shows no phantom of metal ([`crate::scenario::Scenario::is_metal`]). The
/// operator knows when an implant is in the picture, and only then is a dense shadow that does
/// not clip taken for metal: an acrylic plate seen edge-on is as dense, and must not hide its
/// beads. The expected area is that of the metal meshes' shadow at their nominal poses,
/// rendered at a quarter of the resolution.
fn implant_in(
    setup: &Setup,
    meshes: &MetalMeshes,
    exposure: &str,
    frame: &DetectorFrame,
    source_mm: DVec3,
) -> Option<Implant> {
    let scenario = &setup.scenario;
    let exposure = scenario.exposures.iter().find(|e| e.id == exposure)?;
    let metal: Vec<&str> = scenario
        .phantoms
        .iter()
        .filter(|p| {
            exposure.phantoms.contains(&p.id)
                && p.material.as_deref().is_some_and(|m| scenario.is_metal(m))
        })
        .map(|p| p.id.as_str())
        .collect();
    if metal.is_empty() {
        return None;
    }
    let bvhs: Vec<(&MeshBvh, Pose)> = metal
        .iter()
        .filter_map(|id| {
            let bvh = meshes.0.get(*id)?;
            let pose = setup.nominal.phantoms.iter().find(|p| p.id == *id)?.pose();
            Some((bvh, pose))
        })
        .collect();
    if bvhs.is_empty() {
        return Some(Implant {
            expected_area_px: None,
        });
    }
    let coarse = DetectorFrame {
        pixels: frame.pixels.map(|n| n.div_ceil(COARSE_RENDER)),
        pixel_pitch_mm: frame.pixel_pitch_mm.map(|p| p * f64::from(COARSE_RENDER)),
        ..*frame
    };
    let objects: Vec<Object> = bvhs
        .iter()
        .map(|(bvh, pose)| Object::Mesh { bvh, pose: *pose })
        .collect();
    let covered = render_binary(&coarse, source_mm, &objects, 1)
        .iter()
        .filter(|&&v| v != 0)
        .count();
    Some(Implant {
        expected_area_px: Some(covered as f64 * f64::from(COARSE_RENDER * COARSE_RENDER)),
    })
}

/// The expected implant area is rendered at one pixel per this many pixels along each axis.
const COARSE_RENDER: u32 = 4;

/// A clipped component or an implant's shadow is metal when it is at least this many beads' areas.
pub const METAL_BEAD_AREAS: f64 = 20.0;

/// The radius (pixels) of the mean expected bead area of `preds` (1 px when there are none).
fn mean_radius_px(preds: &[Prediction]) -> f64 {
    if preds.is_empty() {
        return 1.0;
    }
    let area = preds.iter().map(|p| p.expected_area).sum::<f64>() / preds.len() as f64;
    (area / std::f64::consts::PI).sqrt()
}

/// Marker-based RSA of one model from its bead-sized blobs in every calibrated view (see
/// [`super::model`]). In attenuation mode, the beads whose fitted image falls on the metal
/// shadow of a view are reported occluded there.
///
/// Blobs that share pixels with the predicted image of a box bead (`box_beads`) are left out
/// of their view ([`overprojected`]): their centre is pulled towards the box bead. The model
/// beads so left out are reported `overprojected`. Should the model not be found without them,
/// it is found with them.
fn find_model(
    reading: BeadReading,
    run_images: &RunImages,
    exposure: &str,
    beamlines: &BTreeMap<String, (Calibrated, &DetectorState)>,
    beads: &[TableBead],
    box_beads: &[TableBead],
    nominal_position_mm: DVec3,
) -> Result<MeasuredPose, String> {
    let mut views = Vec::new();
    let mut clear_views = Vec::new();
    let mut images = Vec::new();
    for (c, det) in beamlines.values() {
        let image = run_images.get(exposure, det)?;
        let frame = c.beamline.frame(det.pixels, det.pixel_pitch_mm);
        // A bead's expected blob area, from the calibrated magnification at the model's nominal
        // position (the box may sit far from the model, as under a uniplanar table).
        let s = frame.pose.to_local(c.beamline.source_mm);
        let z = frame.pose.to_local(nominal_position_mm).z;
        let diameter = beads.iter().map(|b| b.diameter_mm).fold(0.0, f64::max);
        let radius_px = diameter / 2.0 * s.z / (s.z - z) / det.pixel_pitch_mm[0];
        let expected = bead_area_px(radius_px);
        let image = BeadImage::read(
            reading.setup,
            det,
            &image,
            radius_px,
            implant_in(
                reading.setup,
                reading.metal,
                exposure,
                &frame,
                c.beamline.source_mm,
            ),
            reading.centre,
        );
        let candidates: Vec<DVec2> = image
            .blobs
            .iter()
            .filter(|b| fits_one_bead(b.area, expected))
            .map(|b| b.centroid)
            .collect();
        let box_images: Vec<Prediction> = box_beads
            .iter()
            .enumerate()
            .filter_map(|(k, b)| {
                predict(
                    &frame,
                    c.beamline.source_mm,
                    b.position_mm,
                    b.diameter_mm,
                    k,
                    0,
                )
            })
            .collect();
        let clear = candidates
            .iter()
            .copied()
            .filter(|uv| !overprojected(*uv, radius_px, &box_images))
            .collect();
        views.push(View {
            beamline: &c.beamline,
            pixels: det.pixels,
            pitch: det.pixel_pitch_mm,
            blobs: candidates,
        });
        clear_views.push(View {
            beamline: &c.beamline,
            pixels: det.pixels,
            pitch: det.pixel_pitch_mm,
            blobs: clear,
        });
        images.push((
            det.id.clone(),
            frame,
            c.beamline.source_mm,
            radius_px,
            image,
            box_images,
        ));
    }
    let local: Vec<DVec3> = beads.iter().map(|b| b.position_mm).collect();
    let found = super::model::find_model(&clear_views, &local)
        .or_else(|_| super::model::find_model(&views, &local))?;
    let fit = &found.fit;
    let flags =
        crate::migration::quality_flags(Some(fit.mean_error_mm), Some(fit.condition_number));
    let occluded = images
        .iter()
        .flat_map(|(id, frame, source_mm, radius_px, image, _)| {
            beads.iter().filter_map(move |b| {
                let uv = frame.project(*source_mm, fit.pose.to_world(b.position_mm))?;
                (frame.contains_pixel(uv) && image.occludes(uv, *radius_px)).then(|| OccludedBead {
                    bead: b.id.clone(),
                    detector: id.clone(),
                })
            })
        })
        .collect();
    let overprojected_beads = images
        .iter()
        .flat_map(|(id, frame, source_mm, radius_px, _, box_images)| {
            beads.iter().filter_map(move |b| {
                let uv = frame.project(*source_mm, fit.pose.to_world(b.position_mm))?;
                (frame.contains_pixel(uv) && overprojected(uv, *radius_px, box_images)).then(|| {
                    OccludedBead {
                        bead: b.id.clone(),
                        detector: id.clone(),
                    }
                })
            })
        })
        .collect();
    let mut pose = model_pose(
        &fit.pose,
        FitQuality {
            beads_used: Some(found.beads_used),
            crossing_line_error_mm: Some(found.crossing_line_error_mm),
            mean_error_mm: Some(fit.mean_error_mm),
            condition_number: Some(fit.condition_number),
            flags,
            occluded,
            overprojected: overprojected_beads,
            ..Default::default()
        },
    );
    // The triangulated centres: what marker-based RSA between exams (a study's migration) fits.
    pose.markers = found
        .beads
        .iter()
        .map(|&(k, centre, crossing_mm)| MeasuredPoint {
            id: beads[k].id.clone(),
            position_mm: centre.to_array(),
            quality: Some(FitQuality {
                crossing_line_error_mm: Some(crossing_mm),
                ..Default::default()
            }),
        })
        .collect();
    Ok(pose)
}

/// A model's measured pose (its id filled in by the caller) with the fit's quality.
fn model_pose(pose: &Pose, quality: FitQuality) -> MeasuredPose {
    MeasuredPose {
        id: String::new(),
        position_mm: pose.position_mm.to_array(),
        rotation: Some(rotation_rows(&pose.rotation)),
        markers: vec![],
        quality: Some(quality),
    }
}

/// Attenuation mode: the edge windows for a model near `nominal` in the view of `c` and `det`
/// (the focal spot's penumbra at the model's nominal depth: object-to-detector over
/// source-to-object distance). `None` in binary mode.
fn attenuation_windows(
    setup: &Setup,
    c: &Calibrated,
    det: &DetectorState,
    nominal: Pose,
) -> Option<(EdgeWindows, f64)> {
    let imaging = &setup.scenario.imaging;
    if !imaging.is_attenuation() {
        return None;
    }
    let frame = c.beamline.frame(det.pixels, det.pixel_pitch_mm);
    let source_z = frame.pose.to_local(c.beamline.source_mm).z;
    let model_z = frame.pose.to_local(nominal.position_mm).z;
    let sigma_px = nominal_blur_px(
        imaging,
        det.pixel_pitch_mm[0].min(det.pixel_pitch_mm[1]),
        model_z / (source_z - model_z),
    );
    Some((EdgeWindows::for_blur(sigma_px), sigma_px))
}

/// The median attenuation of `img` 5 px beside an outline's segments, on the side of each that
/// is less dense (the background the implant lies on); `None` without a segment inside the image.
fn background_beside(img: &Density, segments: &[OutlineSegment]) -> Option<f64> {
    let at = |p: DVec2| {
        (p.x >= 0.0 && p.y >= 0.0 && p.x < img.width as f64 && p.y < img.height as f64)
            .then(|| img.at(p.x as usize, p.y as usize))
    };
    let mut levels: Vec<f64> = segments
        .iter()
        .filter_map(|s| {
            let d = s.uv[1] - s.uv[0];
            let n = DVec2::new(-d.y, d.x).normalize_or_zero() * BACKGROUND_OFFSET_PX;
            let mid = (s.uv[0] + s.uv[1]) / 2.0;
            Some(at(mid + n)?.min(at(mid - n)?))
        })
        .collect();
    if levels.is_empty() {
        return None;
    }
    let mid = levels.len() / 2;
    Some(*levels.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// How far beside the outline [`background_beside`] reads the background, pixels.
const BACKGROUND_OFFSET_PX: f64 = 5.0;

/// The material of phantom `id` as the scenario names it.
fn phantom_material<'s>(setup: &'s Setup, id: &str) -> Option<&'s str> {
    (setup.scenario.phantoms.iter())
        .find(|p| p.id == id)
        .and_then(|p| p.material.as_deref())
}

/// Model-based RSA of one model: its shadow's outline in every calibrated view, fitted from the
/// nominal pose (see [`super::silhouette`]). In attenuation mode, the best fit is refined
/// [`REMEASURE_ROUNDS`] more times on edge points corrected by the crossing its mesh and
/// material predict ([`super::edge_model`]).
fn find_model_by_outline(
    setup: &Setup,
    metal: &MetalMeshes,
    images: &RunImages,
    exposure: &str,
    beamlines: &BTreeMap<String, (Calibrated, &DetectorState)>,
    model: &OutlineModel,
    phantom: &PhantomState,
) -> Result<MeasuredPose, String> {
    let nominal = phantom.pose();
    let mut outlines = Vec::new();
    let mut graded_images = Vec::new();
    for (c, det) in beamlines.values() {
        let image = images.get(exposure, det)?;
        let frame = c.beamline.frame(det.pixels, det.pixel_pitch_mm);
        let found = if let Some((windows, sigma_px)) = attenuation_windows(setup, c, det, nominal) {
            let expected_area_px = implant_in(setup, metal, exposure, &frame, c.beamline.source_mm)
                .and_then(|i| i.expected_area_px);
            (image.dense_shadow(expected_area_px))
                .and_then(|shadow| graded_outline_of(image.density(), windows, &shadow))
                .map(|o| (o, Some((Arc::clone(&image), windows, sigma_px))))
        } else {
            outline(&image.pixels, image.width, det.i_max()).map(|o| (o, None))
        };
        if let Some((o, graded)) = found {
            outlines.push((frame, c.beamline.source_mm, o));
            graded_images.push(graded);
        }
    }
    let views: Vec<SilhouetteView> = outlines
        .iter()
        .map(|(frame, source_mm, outline)| SilhouetteView {
            frame: *frame,
            source_mm: *source_mm,
            outline,
        })
        .collect();
    // Graded images: every start's fit is refined again on edge points measured along its
    // outline's normals (`edge::edge_points_along_outline`), independent of the segmentation.
    let remeasure = |k: usize, _: &Pose, segments: &[OutlineSegment]| match &graded_images[k] {
        Some((image, windows, _)) => {
            edge_points_along_outline(image.density(), segments, *windows, None)
        }
        None => views[k].outline.edge_points.clone(),
    };
    let graded = graded_images.iter().all(Option::is_some);
    let mut fit = fit_silhouette(
        model,
        &views,
        nominal,
        graded.then_some(&remeasure as Remeasure),
    )?;
    // The implant's own graded edge: the points corrected by the crossing predicted from its
    // mesh and material, for the beam hardened by the tissue around it as each view's
    // background beside the outline says.
    let metals: Option<Vec<MetalTransmission>> = match (&setup.physics, graded) {
        (Some(physics), true) => (graded_images.iter().zip(&views))
            .map(|(g, view)| {
                let (image, _, _) = g.as_ref()?;
                let img = image.density();
                let segments = model.outline(&fit.pose, view.source_mm, &view.frame);
                MetalTransmission::of_material(
                    physics,
                    phantom_material(setup, &phantom.id)?,
                    (setup.scenario.phantoms.iter())
                        .find(|p| p.id == phantom.id)
                        .and_then(|p| p.inside.as_deref())
                        .and_then(|around| phantom_material(setup, around)),
                    background_beside(img, &segments)?,
                )
            })
            .collect(),
        _ => None,
    };
    if let Some(metals) = &metals {
        let corrected = |k: usize, pose: &Pose, segments: &[OutlineSegment]| {
            let Some((image, windows, sigma_px)) = &graded_images[k] else {
                return Vec::new();
            };
            let img = image.density();
            let (view, edge) = (
                &views[k],
                EdgeModel {
                    model,
                    metal: &metals[k],
                    sigma_px: *sigma_px,
                    windows: *windows,
                },
            );
            let predict =
                |q: DVec2, n: DVec2| edge.crossing_px(pose, view.source_mm, &view.frame, q, n);
            edge_points_along_outline(img, segments, *windows, Some(&predict))
        };
        fit = refine_remeasured(model, &views, fit, &corrected, REMEASURE_ROUNDS)?;
    }
    let mut flags = Vec::new();
    if fit.mean_distance_px > GOOD_FIT_PX {
        flags.push(format!("contour distance > {GOOD_FIT_PX} px"));
    }
    let agreement = outline_agreement(model, &views, &fit.pose);
    if agreement < MIN_OUTLINE_AGREEMENT {
        flags.push(format!(
            "outline agrees with the segmented shadow on {:.0} % of its edge points (< {:.0} %)",
            100.0 * agreement,
            100.0 * MIN_OUTLINE_AGREEMENT
        ));
    }
    Ok(model_pose(
        &fit.pose,
        FitQuality {
            contour_distance_px: Some(fit.mean_distance_px),
            contour_points: Some(fit.points_used),
            flags,
            ..Default::default()
        },
    ))
}
