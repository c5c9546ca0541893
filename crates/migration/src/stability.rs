//! A segment's motion between two exams from its markers, with marker stability: a marker that
//! moved relative to the others (a loose marker) is found by its residual after the rigid fit and
//! excluded, and the fit repeated.

use std::collections::BTreeMap;

use glam::{DMat3, DVec3};

use super::weighted_fit::{fit_rigid_weighted, triangulation_covariance};
use crate::geometry::{RigidFit, fit_rigid};

/// A marker's residual in a fit between exams.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerResidual {
    /// Bead id.
    pub bead: String,
    /// `|T·x_ref − x_exam|`, mm.
    pub residual_mm: f64,
}

/// The fit of a segment's follow-up markers to its reference markers after excluding the
/// unstable ones.
#[derive(Debug, Clone, PartialEq)]
pub struct StableFit {
    /// The final fit: its pose carries the markers' positions at the reference exam to their
    /// positions at the follow-up (`T` with `x_exam ≈ T·x_ref`); its mean error (ME) and condition
    /// number (CN) are those of the markers kept.
    pub fit: RigidFit,
    /// The markers kept, with their residuals after the final fit, in bead-id order.
    pub used: Vec<MarkerResidual>,
    /// The markers excluded, in the order they were, each with its leave-one-out residual when it
    /// was excluded.
    pub excluded: Vec<MarkerResidual>,
}

/// Fits the markers seen at both exams (`reference` and `follow_up`: bead id → position, in each
/// exam's own frame) and excludes unstable ones.
///
/// A marker's stability is judged by its leave-one-out residual: its distance at the follow-up
/// from where the fit of the *other* kept markers puts it. A loose marker cannot drag that fit,
/// so its residual is its own displacement relative to the others (a fit that includes it
/// absorbs part of the displacement: a marker 0.5 mm loose among six may show only 0.25 mm).
/// While the largest leave-one-out residual exceeds `threshold_mm` and more than three markers
/// are left, that marker is excluded and the check repeated (one at a time, since a loose marker
/// also raises the others' residuals). Needs three non-collinear markers common to both exams.
///
/// With the X-ray sources of both exams known (`reference_sources_mm`, `follow_up_sources_mm`,
/// each exam's frame; two or more each) every fit weighs each marker by its triangulation
/// covariance ([`fit_rigid_weighted`]): depth, the direction both beams share, counts for
/// less. Without them the fit is unweighted ([`fit_rigid`]).
pub fn fit_stable(
    reference: &BTreeMap<String, DVec3>,
    follow_up: &BTreeMap<String, DVec3>,
    reference_sources_mm: &[DVec3],
    follow_up_sources_mm: &[DVec3],
    threshold_mm: f64,
) -> Result<StableFit, String> {
    type Pair<'a> = (&'a String, DVec3, DVec3, Option<(DMat3, DMat3)>);
    let mut kept: Vec<Pair> = reference
        .iter()
        .filter_map(|(id, r)| {
            let f = follow_up.get(id)?;
            let covariances = triangulation_covariance(*r, reference_sources_mm)
                .zip(triangulation_covariance(*f, follow_up_sources_mm));
            Some((id, *r, *f, covariances))
        })
        .collect();
    let fit_of = |set: &[Pair]| {
        let (from, to): (Vec<DVec3>, Vec<DVec3>) = set.iter().map(|m| (m.1, m.2)).unzip();
        let covariances: Option<(Vec<DMat3>, Vec<DMat3>)> = set.iter().map(|m| m.3).collect();
        match covariances {
            Some((cov_from, cov_to)) => fit_rigid_weighted(&from, &to, &cov_from, &cov_to),
            None => fit_rigid(&from, &to),
        }
        .map_err(|e| format!("{} marker(s) seen at both exams: {e}", set.len()))
    };
    let mut excluded = Vec::new();
    loop {
        let fit = fit_of(&kept)?;
        if kept.len() > 3 {
            let mut worst: Option<(usize, f64)> = None;
            for k in 0..kept.len() {
                let mut others = kept.clone();
                let (_, r, f, _) = others.remove(k);
                // Three collinear others cannot place it: no verdict on this marker.
                let Ok(without) = fit_of(&others) else {
                    continue;
                };
                let residual = (without.pose.to_world(r) - f).length();
                if worst.is_none_or(|(_, w)| residual > w) {
                    worst = Some((k, residual));
                }
            }
            if let Some((k, residual_mm)) = worst.filter(|&(_, w)| w > threshold_mm) {
                let (id, _, _, _) = kept.remove(k);
                excluded.push(MarkerResidual {
                    bead: id.clone(),
                    residual_mm,
                });
                continue;
            }
        }
        let used = kept
            .iter()
            .map(|(id, r, f, _)| MarkerResidual {
                bead: (*id).clone(),
                residual_mm: (fit.pose.to_world(*r) - *f).length(),
            })
            .collect();
        return Ok(StableFit {
            fit,
            used,
            excluded,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;

    /// Eight bone markers spread over a 60 mm region, as surgeons place them.
    fn bone_markers() -> BTreeMap<String, DVec3> {
        [
            [22.0, -8.0, 14.0],
            [-18.0, 12.0, 9.0],
            [5.0, 25.0, -16.0],
            [-24.0, -20.0, -6.0],
            [15.0, 30.0, 20.0],
            [-6.0, -28.0, 18.0],
            [28.0, 5.0, -22.0],
            [-12.0, 2.0, -25.0],
        ]
        .iter()
        .enumerate()
        .map(|(k, p)| (format!("B{}", k + 1), DVec3::from_array(*p)))
        .collect()
    }

    fn moved(pose: &Pose, markers: &BTreeMap<String, DVec3>) -> BTreeMap<String, DVec3> {
        markers
            .iter()
            .map(|(id, p)| (id.clone(), pose.to_world(*p)))
            .collect()
    }

    #[test]
    fn stable_markers_give_the_exact_motion_and_none_is_excluded() {
        let reference = bone_markers();
        let t = Pose::from_position_euler_deg([12.0, -30.0, 4.0], [6.0, -9.0, 20.0]);
        let fit = fit_stable(&reference, &moved(&t, &reference), &[], &[], 0.3).unwrap();
        assert!(fit.excluded.is_empty());
        assert_eq!(fit.used.len(), 8);
        assert!(fit.fit.mean_error_mm < 1e-12);
        assert!((fit.fit.pose.position_mm - t.position_mm).length() < 1e-10);
        assert!(fit.fit.pose.rotation.abs_diff_eq(t.rotation, 1e-12));
    }

    #[test]
    fn a_marker_loose_by_half_a_millimetre_is_excluded_and_one_by_005_mm_kept() {
        let reference = bone_markers();
        let t = Pose::from_position_euler_deg([-4.0, 7.0, 11.0], [-3.0, 2.0, 15.0]);
        // B3 moved 0.5 mm along the bone's y axis at the follow-up, B6 0.05 mm along x.
        let mut follow_up = moved(&t, &reference);
        follow_up.insert(
            "B3".into(),
            t.to_world(reference["B3"] + DVec3::new(0.0, 0.5, 0.0)),
        );
        follow_up.insert(
            "B6".into(),
            t.to_world(reference["B6"] + DVec3::new(0.05, 0.0, 0.0)),
        );
        let fit = fit_stable(&reference, &follow_up, &[], &[], 0.3).unwrap();
        assert_eq!(fit.excluded.len(), 1, "{:?}", fit.excluded);
        assert_eq!(fit.excluded[0].bead, "B3");
        // Fitted from the other seven, B3 is off by its 0.5 mm displacement, give or take B6's
        // 0.05 mm share.
        assert!(
            (fit.excluded[0].residual_mm - 0.5).abs() < 0.02,
            "{:?}",
            fit.excluded
        );
        assert_eq!(fit.used.len(), 7);
        assert!(fit.used.iter().any(|m| m.bead == "B6"));
        // Without B3 the fit is off by B6's 0.05 mm only: its residual is at most 0.05 mm and the
        // pose is within a few hundredths of a millimetre of the truth over the markers.
        let b6 = fit.used.iter().find(|m| m.bead == "B6").unwrap();
        assert!(
            b6.residual_mm <= 0.05 + 1e-12 && b6.residual_mm > 0.03,
            "{b6:?}"
        );
        for p in reference.values() {
            assert!((fit.fit.pose.to_world(*p) - t.to_world(*p)).length() < 0.02);
        }
        // ME is the mean of the kept residuals.
        let me = fit.used.iter().map(|m| m.residual_mm).sum::<f64>() / 7.0;
        assert!((fit.fit.mean_error_mm - me).abs() < 1e-12);
        // A threshold above the loose marker's displacement keeps it; the fit then absorbs part
        // of it (the residual in the fit of all eight is below the displacement).
        let lax = fit_stable(&reference, &follow_up, &[], &[], 0.6).unwrap();
        let b3 = lax.used.iter().find(|m| m.bead == "B3").unwrap();
        assert!(b3.residual_mm < 0.5 && b3.residual_mm > 0.2, "{b3:?}");
        assert!(lax.excluded.is_empty() && lax.used.len() == 8);
    }

    #[test]
    fn only_markers_seen_at_both_exams_are_fitted_and_three_are_needed() {
        let reference = bone_markers();
        let mut follow_up = reference.clone();
        follow_up.retain(|id, _| id == "B1" || id == "B2" || id == "B5" || id == "B9");
        let fit = fit_stable(&reference, &follow_up, &[], &[], 0.3).unwrap();
        let used: Vec<&str> = fit.used.iter().map(|m| m.bead.as_str()).collect();
        assert_eq!(used, ["B1", "B2", "B5"]);
        follow_up.remove("B5");
        let e = fit_stable(&reference, &follow_up, &[], &[], 0.3).unwrap_err();
        assert!(e.contains("2 marker(s)") && e.contains("at least 3"), "{e}");
        // With three markers a moved one cannot be told from the others: nothing is excluded.
        let mut three: BTreeMap<String, DVec3> = reference.clone();
        three.retain(|id, _| id == "B1" || id == "B2" || id == "B3");
        let mut moved3 = three.clone();
        moved3.insert("B3".into(), three["B3"] + DVec3::new(0.0, 0.0, 2.0));
        let fit = fit_stable(&three, &moved3, &[], &[], 0.3).unwrap();
        assert!(fit.excluded.is_empty() && fit.fit.mean_error_mm > 0.3);
    }
}
