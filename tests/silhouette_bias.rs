//! Model-based RSA on graded (attenuation-mode) images: where the silhouette fit's orientation
//! error comes from.

use crate::common;

use std::path::PathBuf;

use common::truths;
use glam::{DVec2, DVec3};
use rsasim::geometry::{DetectorFrame, euler_xyz_deg};
use rsasim::output::decode::read_image;
use rsasim::output::exam::load_setup;
use rsasim::reconstruct::density::{Reading, density};
use rsasim::reconstruct::edge::{EdgeWindows, edge_points_along_outline, graded_outline};
use rsasim::reconstruct::model_outline::{OutlineModel, OutlineSegment};
use rsasim::reconstruct::silhouette::{Remeasure, SilhouetteView, fit_silhouette};
use rsasim::trace::{Object, render_binary};

/// Signed distance of `p` from the nearest segment (positive on the side of the segment's
/// left normal), and that segment's index.
fn signed_distance(segments: &[OutlineSegment], p: DVec2) -> Option<(f64, usize)> {
    let mut best: Option<(f64, f64, usize)> = None;
    for (k, s) in segments.iter().enumerate() {
        let d = s.uv[1] - s.uv[0];
        let l2 = d.length_squared();
        if l2 == 0.0 {
            continue;
        }
        let lambda = ((p - s.uv[0]).dot(d) / l2).clamp(0.0, 1.0);
        let q = s.uv[0] + d * lambda;
        let dist = (p - q).length();
        if best.is_none_or(|b| dist < b.1) {
            let n = DVec2::new(-d.y, d.x) / l2.sqrt();
            best = Some((n.dot(p - q), dist, k));
        }
    }
    best.map(|(s, _, k)| (s, k))
}

/// Diagnosis on an existing output (`RSASIM_PROBE_OUT`): per run, the edge points measured
/// along the TRUE outline (true geometry, true pose) and their signed distance from it
/// (outward positive), and the fit with the true geometry. Run with
/// `cargo test --test integration silhouette_bias:: -- --ignored --nocapture`.
#[test]
#[ignore = "measures an existing output named by RSASIM_PROBE_OUT"]
fn probe_silhouette_bias_on_an_output() {
    let Ok(out) = std::env::var("RSASIM_PROBE_OUT") else {
        eprintln!("set RSASIM_PROBE_OUT");
        return;
    };
    let out = PathBuf::from(out);
    let setup = load_setup(&out).unwrap();
    let mut mesh = (*setup.meshes["femur"]).clone();
    if mesh.signed_volume_mm3() < 0.0 {
        mesh.flip_winding();
    }
    let model = OutlineModel::new(&mesh).unwrap();
    let imaging = &setup.scenario.imaging;
    for (dir, truth) in truths(&out) {
        let run = &truth.run;
        let femur = run.phantoms.iter().find(|p| p.id == "femur").unwrap();
        let true_pose = femur.pose();
        let mut views = Vec::new();
        for det in &run.detectors {
            let frame: DetectorFrame = det.frame();
            let source = run.source_of(det);
            let (w, _, px) = read_image(&dir, &format!("model-{}", det.id)).unwrap();
            let img = density(&px, w as usize, Reading::of(imaging, det.i_max()));
            let source_z = frame.pose.to_local(source).z;
            let model_z = frame.pose.to_local(true_pose.position_mm).z;
            let windows = EdgeWindows::for_imaging(
                imaging,
                det.pixel_pitch_mm[0],
                model_z / (source_z - model_z),
            );
            let segments = model.outline(&true_pose, source, &frame);
            let points = edge_points_along_outline(&img, &segments, windows, None);
            // Outward: away from the denser side.
            let mut d: Vec<f64> = Vec::new();
            for p in &points {
                let Some((s, k)) = signed_distance(&segments, *p) else {
                    continue;
                };
                let sg = &segments[k];
                let dd = sg.uv[1] - sg.uv[0];
                let n = DVec2::new(-dd.y, dd.x).normalize();
                let mid = (sg.uv[0] + sg.uv[1]) / 2.0;
                let at = |q: DVec2| {
                    img.at(
                        (q.x.floor() as usize).min(img.width - 1),
                        (q.y.floor() as usize).min(img.height - 1),
                    )
                };
                let sign = if at(mid + n * 4.0) > at(mid - n * 4.0) {
                    -1.0
                } else {
                    1.0
                };
                d.push(sign * s);
            }
            let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
            eprintln!(
                "{} {}: {} points along the true outline ({} segments), mean outward offset {mean:+.4} px",
                run.id,
                det.id,
                d.len(),
                segments.len()
            );
            // The expected shadow area from the mesh at its true pose (the program takes the
            // nominal pose).
            let area = render_binary(
                &frame,
                source,
                &[Object::Mesh {
                    bvh: model.bvh(),
                    pose: true_pose,
                }],
                1,
            )
            .iter()
            .filter(|&&v| v != 0)
            .count() as f64;
            let o = graded_outline(&img, windows, Some(area)).unwrap();
            views.push((frame, source, o, img, windows));
        }
        let sviews: Vec<SilhouetteView> = views
            .iter()
            .map(|(frame, source, o, _, _)| SilhouetteView {
                frame: *frame,
                source_mm: *source,
                outline: o,
            })
            .collect();
        let remeasure = |k: usize, _: &rsasim::geometry::Pose, segments: &[OutlineSegment]| {
            edge_points_along_outline(&views[k].3, segments, views[k].4, None)
        };
        let fit =
            fit_silhouette(&model, &sviews, true_pose, Some(&remeasure as Remeasure)).unwrap();
        let e = euler_xyz_deg(&(fit.pose.rotation * true_pose.rotation.transpose()));
        let dp: DVec3 = fit.pose.position_mm - true_pose.position_mm;
        eprintln!(
            "{} fit with true geometry: position {:+.4} {:+.4} {:+.4} mm, α β γ {:+.4} {:+.4} {:+.4}°, residual {:.3} px",
            run.id, dp.x, dp.y, dp.z, e[0], e[1], e[2], fit.mean_distance_px
        );
    }
}
