//! A clinical study's runs: every exam of every patient, with the implant's prescribed migration
//! relative to the bone applied to the drawn geometry.
//!
//! # Seeds and ids
//!
//! Exam `x` of patient `pNN` draws its geometry (tubes, detectors, the limb's repositioning —
//! the reference phantom's `randomize` — and every other phantom's ranges) from the stream keyed
//! by SHA-256(`"rsasim/study/v1/<seed>/pNN/<x>"`), in the file order of a protocol run (see the
//! parent module). The patient's own draws (its migration factor) come from
//! `"rsasim/study/v1/<seed>/pNN"`. So patients 1..k are identical whether the study has k or 20
//! patients. The run id is `pNN-e<i>-<x>` (`i` the exam's 0-based place in the list, as many
//! digits as the last index needs), so the run folders of a patient sort in exam order. The
//! noise of run `p·E + i` (patient `p` 0-based, `E` exams) is keyed like protocol run
//! `p·E + i` of level 0.
//!
//! # Migration
//!
//! With `B` the reference segment's pose, `A` its anatomical frame (a pose in `B`'s frame) and
//! `I` an implant's pose, `P = (B·A)⁻¹·I` is the implant's pose in the anatomical frame. At the
//! nominal set-up it is `P₀`. At exam `e` the implant is placed at `I_e = B_e·A·M_e·P₀`, where
//! `M_e` rotates by the exam's prescribed `R` (X-Y-Z Euler angles about the anatomical axes)
//! about the implant's centre `c` (the centroid of its MTPM points, anatomical frame) and then
//! translates by `t`: `M_e(x) = R·(x − c) + c + t`. So `P_e·P_ref⁻¹ = M_e` (the reference exam
//! has `M = I`), and the migration `study.json` reports is `t` and the angles of `R`.

use glam::{DMat3, DVec3};

use super::{Drawn, RunHeader, assemble, draw, fixed_poses, still};
use crate::expand::Run;
use crate::geometry::{Pose, rotation_xyz_deg};
use crate::phantom::PhantomModel;
use crate::random;
use crate::scenario::{Scenario, SegmentRole, StudyDesign};

/// The id of patient `patient` (0-based): `p01`, `p02`, … (at least two digits).
pub fn patient_id(patient: u32) -> String {
    format!("p{:02}", u64::from(patient) + 1)
}

/// The run id of exam `exam` (0-based index into the list) of patient `patient` (0-based).
pub fn exam_run_id(d: &StudyDesign, patient: u32, exam: usize) -> String {
    let width = d.exams.len().saturating_sub(1).to_string().len();
    format!(
        "{}-e{exam:0width$}-{}",
        patient_id(patient),
        d.exams[exam].id
    )
}

/// The label of the geometry stream of one exam of one patient.
pub fn exam_stream_label(seed: u64, patient: u32, exam_id: &str) -> String {
    format!("rsasim/study/v1/{seed}/{}/{exam_id}", patient_id(patient))
}

/// The label of a patient's own stream (its migration factor).
pub fn patient_stream_label(seed: u64, patient: u32) -> String {
    format!("rsasim/study/v1/{seed}/{}", patient_id(patient))
}

/// The factor on patient `patient`'s prescribed migration: `1 + u`, `u` uniform in
/// [−spread, +spread), the first draw of the patient's stream.
pub fn migration_factor(s: &Scenario, d: &StudyDesign, patient: u32) -> f64 {
    let mut rng = random::stream(&patient_stream_label(s.seed, patient));
    1.0 + random::symmetric(&mut rng, d.migration_spread)
}

/// An implant segment in the anatomical frame of the nominal set-up.
#[derive(Debug, Clone)]
pub struct ImplantFrame {
    /// Index of its phantom in the scenario.
    pub phantom: usize,
    /// Its pose in the anatomical frame, `P₀ = (B·A)⁻¹·I` at the nominal set-up.
    pub in_anatomical: Pose,
    /// Its MTPM points in its local frame, mm.
    pub mtpm_points_local: Vec<DVec3>,
    /// Its centre (the centroid of the MTPM points) in the anatomical frame, mm.
    pub centre: DVec3,
}

/// The frames a study's migration is built from.
#[derive(Debug, Clone)]
pub struct StudyFrames {
    /// Index of the reference segment's phantom.
    pub reference: usize,
    /// The anatomical frame as a pose in the reference segment's local frame (`A`).
    pub anatomical: Pose,
    /// Every implant segment, in the order of `segments`.
    pub implants: Vec<ImplantFrame>,
}

/// The local positions of a phantom's beads, by id (free beads or a mesh's beads).
fn bead_positions(s: &Scenario, phantom: usize) -> Vec<(String, DVec3)> {
    let ph = &s.phantoms[phantom];
    let beads = match (&ph.beads, &ph.mesh) {
        (Some(b), _) => b.as_slice(),
        (None, Some(m)) => m.beads.as_slice(),
        (None, None) => &[],
    };
    beads
        .iter()
        .map(|b| (b.id.clone(), DVec3::from_array(b.position_mm)))
        .collect()
}

/// The ids of a segment's markers: its `markers`, or every bead of its phantom.
pub fn segment_markers(s: &Scenario, segment: &crate::scenario::SegmentSpec) -> Vec<String> {
    match &segment.markers {
        Some(m) => m.clone(),
        None => s
            .phantoms
            .iter()
            .position(|p| p.id == segment.phantom)
            .map(|i| bead_positions(s, i).into_iter().map(|(id, _)| id).collect())
            .unwrap_or_default(),
    }
}

/// The study's frames from the nominal set-up. Validation guarantees the segments exist.
pub fn frames(s: &Scenario, d: &StudyDesign) -> StudyFrames {
    let index = |id: &str| s.phantoms.iter().position(|p| p.id == id).unwrap_or(0);
    let nominal: Vec<Pose> = s
        .phantoms
        .iter()
        .map(|p| Pose::from_position_euler_deg(p.position_mm, p.rotation_deg))
        .collect();
    let nominal = fixed_poses(s, &nominal, &still(s));
    let reference_segment = d.reference_segment();
    let reference = reference_segment.map_or(0, |g| index(&g.phantom));
    let anatomical = reference_segment
        .and_then(|g| g.anatomical_frame.as_ref())
        .map_or(Pose::IDENTITY, |f| {
            Pose::from_position_euler_deg(f.position_mm, f.rotation_deg)
        });
    let to_anatomical = nominal[reference].compose(&anatomical).inverse();
    let implants = d
        .segments
        .iter()
        .filter(|g| g.role == SegmentRole::Implant)
        .map(|g| {
            let phantom = index(&g.phantom);
            let in_anatomical = to_anatomical.compose(&nominal[phantom]);
            let mtpm_points_local: Vec<DVec3> = match &g.mtpm_points_mm {
                Some(points) => points.iter().map(|p| DVec3::from_array(*p)).collect(),
                None => {
                    let markers = segment_markers(s, g);
                    bead_positions(s, phantom)
                        .into_iter()
                        .filter(|(id, _)| markers.contains(id))
                        .map(|(_, p)| p)
                        .collect()
                }
            };
            let sum: DVec3 = mtpm_points_local.iter().copied().sum();
            let centre_local = sum / mtpm_points_local.len().max(1) as f64;
            ImplantFrame {
                phantom,
                in_anatomical,
                mtpm_points_local,
                centre: in_anatomical.to_world(centre_local),
            }
        })
        .collect();
    StudyFrames {
        reference,
        anatomical,
        implants,
    }
}

/// The prescribed migration at exam `exam` scaled by `factor`: the rigid motion `M` of the
/// anatomical frame that rotates by the exam's angles about `centre` and then translates by its
/// translation (a double examination has the migration of the exam it repeats).
pub fn prescribed_motion(d: &StudyDesign, exam: usize, factor: f64, centre: DVec3) -> Pose {
    let e = &d.exams[d.migration_exam(exam)];
    let t = DVec3::from_array(e.translation_mm.unwrap_or([0.0; 3])) * factor;
    let angles = e.rotation_deg.unwrap_or([0.0; 3]).map(|a| a * factor);
    let r: DMat3 = rotation_xyz_deg(angles);
    Pose {
        position_mm: centre + t - r * centre,
        rotation: r,
    }
}

/// The displacement (segment's local frame) of bead `bead` of phantom `phantom` at exam `exam`
/// of patient `patient` (0-based), if it is loose by then.
pub fn loose_displacement(
    d: &StudyDesign,
    patient: u32,
    exam: usize,
    phantom: &str,
    bead: &str,
) -> Option<DVec3> {
    d.loose_markers
        .iter()
        .find(|l| {
            u64::from(l.patient) == u64::from(patient) + 1 && l.phantom == phantom && l.bead == bead
        })
        .filter(|l| d.exam_index(&l.from_exam).is_some_and(|from| exam >= from))
        .map(|l| DVec3::from_array(l.displacement_mm))
}

/// Whether patient `patient` (0-based) lacks bead `bead` of phantom `phantom`.
pub fn is_missing(d: &StudyDesign, patient: u32, phantom: &str, bead: &str) -> bool {
    d.missing_markers.iter().any(|m| {
        u64::from(m.patient) == u64::from(patient) + 1
            && m.phantom == phantom
            && m.beads.iter().any(|b| b == bead)
    })
}

/// Exam `exam` (0-based index into the list) of patient `patient` (0-based) as a run.
pub fn expand_exam(
    s: &Scenario,
    d: &StudyDesign,
    models: &[PhantomModel],
    patient: u32,
    exam: usize,
) -> Run {
    let label = exam_stream_label(s.seed, patient, &d.exams[exam].id);
    let Drawn {
        sources,
        detectors,
        phantoms: mut own,
    } = draw(s, &mut random::stream(&label));
    let f = frames(s, d);
    let placed = fixed_poses(s, &own, &still(s));
    let limb = placed[f.reference].compose(&f.anatomical);
    let factor = migration_factor(s, d, patient);
    for implant in &f.implants {
        let motion = prescribed_motion(d, exam, factor, implant.centre);
        own[implant.phantom] = limb.compose(&motion).compose(&implant.in_anatomical);
    }
    let phantoms = fixed_poses(s, &own, &still(s));
    let run_index = u64::from(patient) * d.exams.len() as u64 + exam as u64;
    assemble(
        s,
        models,
        RunHeader {
            id: exam_run_id(d, patient, exam),
            level_index: 0,
            level: s.study_level(d),
            run_index: u32::try_from(run_index).unwrap_or(u32::MAX),
            geometry_stream: label,
        },
        Drawn {
            sources,
            detectors,
            phantoms: own,
        },
        &phantoms,
        &|pi, b| {
            let phantom = &s.phantoms[pi].id;
            if is_missing(d, patient, phantom, &b.id) {
                return None;
            }
            let loose = loose_displacement(d, patient, exam, phantom, &b.id);
            Some(b.position_mm + loose.unwrap_or(DVec3::ZERO))
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::ExamSpec;

    fn exam(id: &str, double_of: Option<&str>, t: Option<[f64; 3]>) -> ExamSpec {
        ExamSpec {
            id: id.into(),
            days: 0,
            reference: id == "postop",
            double_of: double_of.map(Into::into),
            translation_mm: t,
            rotation_deg: t,
        }
    }

    fn design(exams: Vec<ExamSpec>) -> StudyDesign {
        StudyDesign {
            patients: 1,
            noise_level: 0.0,
            exposure_factor: None,
            migration_spread: 0.0,
            segments: vec![],
            exams,
            loose_markers: vec![],
            missing_markers: vec![],
        }
    }

    #[test]
    fn run_ids_sort_in_exam_order_with_as_many_digits_as_the_last_index_needs() {
        let five = design(
            ["postop", "double", "3m", "1y", "2y"]
                .iter()
                .map(|id| exam(id, None, None))
                .collect(),
        );
        let ids: Vec<String> = (0..5).map(|i| exam_run_id(&five, 6, i)).collect();
        assert_eq!(ids[0], "p07-e0-postop");
        assert_eq!(ids[4], "p07-e4-2y");
        let mut sorted = ids.clone();
        sorted.sort();
        assert_eq!(sorted, ids);
        let eleven = design(
            (0..11)
                .map(|i| exam(&format!("x{i}"), None, None))
                .collect(),
        );
        assert_eq!(exam_run_id(&eleven, 0, 3), "p01-e03-x3");
        assert_eq!(patient_id(119), "p120");
    }

    #[test]
    fn a_double_has_the_migration_of_the_exam_it_repeats_about_the_centre() {
        let d = design(vec![
            exam("postop", None, None),
            exam("1y", None, Some([0.3, -0.2, 0.1])),
            exam("1y-double", Some("1y"), None),
            exam("1y-triple", Some("1y-double"), None),
        ]);
        assert_eq!(d.migration_exam(3), 1);
        let centre = DVec3::new(10.0, -20.0, 5.0);
        let m = prescribed_motion(&d, 3, 2.0, centre);
        // The centre moves by the translation times the factor; the rotation is about it.
        assert!((m.to_world(centre) - centre - DVec3::new(0.6, -0.4, 0.2)).length() < 1e-12);
        let angles = crate::geometry::euler_xyz_deg(&m.rotation);
        for (a, want) in angles.iter().zip([0.6, -0.4, 0.2]) {
            assert!((a - want).abs() < 1e-12, "{angles:?}");
        }
        assert_eq!(prescribed_motion(&d, 0, 2.0, centre), Pose::IDENTITY);
    }
}
