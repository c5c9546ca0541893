//! Marker-based RSA of a model from calibrated views, without trusting its nominal pose.
//!
//! A model carries only a few beads, and its pose may differ from the nominal one by many bead
//! spacings in the image, so nearest-neighbour matching is ambiguous. Instead:
//! 1. every pair of bead-sized blobs from two calibrated views is triangulated; pairs whose rays
//!    pass within [`CROSSING_LIMIT_MM`] of each other are candidate bead positions;
//! 2. the bead table is matched to the candidates by their mutual distances: each triple of beads
//!    against each ordered triple of candidates whose distances agree within [`DISTANCE_TOL_MM`]
//!    gives a rigid fit, scored by how many beads it puts on a candidate;
//! 3. the best assignment is refitted with all its beads.

use glam::{DVec2, DVec3};

use super::calibrate::{Beamline, ray_through_pixel};
use crate::geometry::{RigidFit, fit_rigid, triangulate};

/// Largest distance between two views' rays for a candidate bead, mm.
pub const CROSSING_LIMIT_MM: f64 = 1.0;
/// Tolerance on inter-bead distances, mm.
pub const DISTANCE_TOL_MM: f64 = 0.5;

/// One calibrated view: its beamline, pixel grid and the centroids of its bead-sized blobs.
pub struct View<'a> {
    /// The calibrated beamline.
    pub beamline: &'a Beamline,
    /// Pixel counts.
    pub pixels: [u32; 2],
    /// Pixel pitch, mm.
    pub pitch: [f64; 2],
    /// Blob centroids that could be beads.
    pub blobs: Vec<DVec2>,
}

/// A candidate bead in 3-D.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    position: DVec3,
    crossing_mm: f64,
}

/// The model's pose from its beads.
#[derive(Debug, Clone)]
pub struct ModelFit {
    /// Rigid fit of the bead table (model frame) to the triangulated beads (box frame).
    pub fit: RigidFit,
    /// Beads used.
    pub beads_used: usize,
    /// Mean crossing-line error of the beads used, mm.
    pub crossing_line_error_mm: f64,
    /// The beads used: index in the bead table, triangulated centre (box frame, mm) and its
    /// crossing-line error (mm), in bead-table order.
    pub beads: Vec<(usize, DVec3, f64)>,
}

fn candidates(views: &[View]) -> Vec<Candidate> {
    let mut out = Vec::new();
    for a in 0..views.len() {
        for b in a + 1..views.len() {
            let (va, vb) = (&views[a], &views[b]);
            for &ua in &va.blobs {
                let ra = ray_through_pixel(va.beamline, va.pixels, va.pitch, ua);
                for &ub in &vb.blobs {
                    let rb = ray_through_pixel(vb.beamline, vb.pixels, vb.pitch, ub);
                    let (p, err) = triangulate(&[ra, rb]);
                    if err.is_finite() && err <= CROSSING_LIMIT_MM {
                        out.push(Candidate {
                            position: p,
                            crossing_mm: err,
                        });
                    }
                }
            }
        }
    }
    out
}

/// Finds the model's pose from `views` and its bead table `model` (model frame, mm).
pub fn find_model(views: &[View], model: &[DVec3]) -> Result<ModelFit, String> {
    if model.len() < 3 {
        return Err(format!(
            "the model has {} bead(s); marker-based RSA needs 3",
            model.len()
        ));
    }
    let cands = candidates(views);
    if cands.len() < 3 {
        return Err(format!(
            "only {} bead(s) seen in two views; marker-based RSA needs 3",
            cands.len()
        ));
    }
    let close = |a: DVec3, b: DVec3, d: f64| ((a - b).length() - d).abs() <= DISTANCE_TOL_MM;
    // The best assignment so far: (inliers, rms, pairs of (model index, candidate index)).
    type Assignment = (usize, f64, Vec<(usize, usize)>);
    let mut best: Option<Assignment> = None;
    let n = cands.len();
    for i in 0..model.len() {
        for j in i + 1..model.len() {
            for k in j + 1..model.len() {
                let (dij, dik, djk) = (
                    (model[i] - model[j]).length(),
                    (model[i] - model[k]).length(),
                    (model[j] - model[k]).length(),
                );
                for p in 0..n {
                    for q in 0..n {
                        if q == p || !close(cands[p].position, cands[q].position, dij) {
                            continue;
                        }
                        for r in 0..n {
                            if r == p
                                || r == q
                                || !close(cands[p].position, cands[r].position, dik)
                                || !close(cands[q].position, cands[r].position, djk)
                            {
                                continue;
                            }
                            let Ok(fit) = fit_rigid(
                                &[model[i], model[j], model[k]],
                                &[cands[p].position, cands[q].position, cands[r].position],
                            ) else {
                                continue;
                            };
                            let pairs = assign(&fit, model, &cands);
                            let rms = (pairs
                                .iter()
                                .map(|&(m, c)| {
                                    (fit.pose.to_world(model[m]) - cands[c].position)
                                        .length_squared()
                                })
                                .sum::<f64>()
                                / pairs.len() as f64)
                                .sqrt();
                            let better = match &best {
                                None => true,
                                Some((count, best_rms, _)) => {
                                    pairs.len() > *count
                                        || (pairs.len() == *count && rms < *best_rms)
                                }
                            };
                            if better {
                                best = Some((pairs.len(), rms, pairs));
                            }
                        }
                    }
                }
            }
        }
    }
    let (_, _, pairs) = best.ok_or("no three candidate beads match the bead table's distances")?;
    let (m, w): (Vec<DVec3>, Vec<DVec3>) = pairs
        .iter()
        .map(|&(m, c)| (model[m], cands[c].position))
        .unzip();
    let fit = fit_rigid(&m, &w)?;
    let crossing = pairs
        .iter()
        .map(|&(_, c)| cands[c].crossing_mm)
        .sum::<f64>()
        / pairs.len() as f64;
    let mut beads: Vec<(usize, DVec3, f64)> = pairs
        .iter()
        .map(|&(m, c)| (m, cands[c].position, cands[c].crossing_mm))
        .collect();
    beads.sort_by_key(|b| b.0);
    Ok(ModelFit {
        fit,
        beads_used: pairs.len(),
        crossing_line_error_mm: crossing,
        beads,
    })
}

/// For each model bead, the nearest candidate within 1 mm of where `fit` puts it (each
/// candidate used once).
fn assign(fit: &RigidFit, model: &[DVec3], cands: &[Candidate]) -> Vec<(usize, usize)> {
    let mut used = vec![false; cands.len()];
    let mut pairs = Vec::new();
    for (m, p) in model.iter().enumerate() {
        let at = fit.pose.to_world(*p);
        let nearest = (0..cands.len())
            .filter(|&c| !used[c])
            .map(|c| (c, (cands[c].position - at).length()))
            .filter(|&(_, d)| d <= 1.0)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((c, _)) = nearest {
            used[c] = true;
            pairs.push((m, c));
        }
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Pose, rotation_xyz_deg};

    #[test]
    fn finds_a_model_far_from_any_nominal_pose_among_distractors() {
        let pixels = [1440, 1440];
        let pitch = [430.0 / 1440.0; 2];
        let b1 = Beamline {
            source_mm: DVec3::new(5.0, -3.0, 1300.0),
            detector: Pose::from_position_euler_deg([2.0, 1.0, -500.0], [1.0, -1.0, 2.0]),
        };
        let b2 = Beamline {
            source_mm: DVec3::new(1300.0, 4.0, -6.0),
            detector: Pose::from_position_euler_deg([-500.0, 2.0, 3.0], [0.5, 90.0, -1.0]),
        };
        let model = [
            DVec3::new(6.0, 34.0, 12.0),
            DVec3::new(0.0, 36.0, 2.0),
            DVec3::new(-14.0, 40.0, -12.0),
            DVec3::new(-10.0, 52.0, 12.0),
            DVec3::new(-4.0, 52.0, 6.0),
            DVec3::new(14.0, 52.0, -6.0),
        ];
        let pose = Pose::from_position_euler_deg([7.0, -4.0, 9.0], [9.0, -10.0, 8.0]);
        let view = |b: &'static Beamline, hide: usize| -> View<'static> {
            let mut blobs: Vec<DVec2> = model
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != hide)
                .map(|(_, p)| b.project(pixels, pitch, pose.to_world(*p)).unwrap())
                .collect();
            blobs.push(DVec2::new(100.0, 200.0)); // a stray blob
            View {
                beamline: b,
                pixels,
                pitch,
                blobs,
            }
        };
        let (b1, b2): (&'static Beamline, &'static Beamline) =
            (Box::leak(Box::new(b1)), Box::leak(Box::new(b2)));
        // Bead 5 hidden in view 1, bead 0 hidden in view 2: four beads seen twice.
        let fit = find_model(&[view(b1, 5), view(b2, 0)], &model).unwrap();
        assert_eq!(fit.beads_used, 4);
        assert!((fit.fit.pose.position_mm - pose.position_mm).length() < 1e-6);
        assert!((fit.fit.pose.rotation - pose.rotation).abs_diff_eq(glam::DMat3::ZERO, 1e-9));
        assert!(fit.crossing_line_error_mm < 1e-6);
        let _ = rotation_xyz_deg([0.0; 3]);
    }
}
