//! Tests that prove the geometry of the written images, not just that files appear.

use crate::common;

use common::{read_tiff, run_scenario, truths};
use rsasim::geometry::{DVec3, DetectorFrame, Pose, rotation_xyz_deg};
use rsasim::phantom::TriMesh;
use rsasim::trace::{MeshBvh, Object, render_binary};

/// The 8-connected component of covered pixels containing (i, j): its centroid in continuous
/// pixel coordinates and its pixel count.
fn blob(img: &[u16], w: usize, h: usize, i: usize, j: usize, on: u16) -> Option<([f64; 2], usize)> {
    if img[j * w + i] != on {
        return None;
    }
    let mut seen = std::collections::HashSet::new();
    let mut stack = vec![(i, j)];
    let (mut su, mut sv) = (0.0, 0.0);
    seen.insert((i, j));
    while let Some((x, y)) = stack.pop() {
        su += x as f64 + 0.5;
        sv += y as f64 + 0.5;
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    continue;
                }
                let p = (nx as usize, ny as usize);
                if img[p.1 * w + p.0] == on && seen.insert(p) {
                    stack.push(p);
                }
            }
        }
    }
    let n = seen.len();
    Some(([su / n as f64, sv / n as f64], n))
}

#[test]
fn noise_free_bead_blobs_are_centred_on_their_projected_centres() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("c");
    run_scenario("tests/scenarios/centroids.toml", &out, &[]);
    let mut checked = 0;
    let mut worst: f64 = 0.0;
    let mut bias = [0.0f64; 2];
    for (dir, truth) in truths(&out) {
        for image in &truth.images {
            let (w, h, img) = read_tiff(&dir.join(&image.files[0].path));
            let det = truth
                .run
                .detectors
                .iter()
                .find(|d| d.id == image.detector)
                .unwrap();
            let on = det.i_max();
            let centres: Vec<[f64; 2]> = image.markers.iter().map(|m| m.pixel).collect();
            for m in image.markers.iter().filter(|m| m.inside) {
                // Only beads whose blob (about 15 px across) cannot touch another bead's blob.
                let isolated = centres
                    .iter()
                    .filter(|c| (c[0] - m.pixel[0]).hypot(c[1] - m.pixel[1]) < 24.0)
                    .count()
                    == 1;
                if !isolated {
                    continue;
                }
                let (i, j) = (m.pixel[0] as usize, m.pixel[1] as usize);
                let (c, n) = blob(&img, w as usize, h as usize, i, j, on)
                    .expect("a bead centre pixel is covered");
                assert!((100..260).contains(&n), "blob of {} has {n} pixels", m.id);
                let err = (c[0] - m.pixel[0]).hypot(c[1] - m.pixel[1]);
                worst = worst.max(err);
                bias[0] += c[0] - m.pixel[0];
                bias[1] += c[1] - m.pixel[1];
                assert!(
                    err < 0.25,
                    "{} {}: centroid {c:?} vs projected {:?} ({err} px)",
                    truth.run.id,
                    m.id,
                    m.pixel
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 300, "only {checked} isolated beads checked");
    // Quantisation errors average out; a convention error (half a pixel, a flipped axis) does not.
    let bias = bias.map(|b| b / checked as f64);
    assert!(
        bias[0].abs() < 0.02 && bias[1].abs() < 0.02,
        "mean centroid error {bias:?} px"
    );
    eprintln!("{checked} bead blobs checked, worst centroid error {worst:.3} px, mean {bias:?} px");
}

#[test]
fn a_sphere_mesh_silhouette_has_the_area_of_the_exact_projection() {
    // A sphere of radius r at distance d from the source, off-axis by angle θ to the detector
    // normal, casts an ellipse: semi-axes a = H·sinα·cosα/(cos²θ − sin²α), b = H·sinα/√(cos²θ − sin²α),
    // α = asin(r/d), H the source-to-plane distance.
    let frame = DetectorFrame {
        pose: Pose::IDENTITY,
        pixels: [800, 800],
        pixel_pitch_mm: [0.25, 0.25],
    };
    let source = DVec3::new(0.0, 0.0, 1000.0);
    let (r, centre) = (8.0, DVec3::new(25.0, -15.0, 450.0));
    let axis = (centre - source).normalize();
    let (alpha, cos_t) = ((r / (centre - source).length()).asin(), -axis.z);
    let k = cos_t * cos_t - alpha.sin().powi(2);
    let exact = std::f64::consts::PI
        * (1000.0 * alpha.sin() * alpha.cos() / k)
        * (1000.0 * alpha.sin() / k.sqrt());
    let pixel_area = 0.0625;
    for (rings, segments, tolerance) in [(48, 96, 0.004), (96, 192, 0.0015)] {
        let mesh = TriMesh::uv_sphere(r, rings, segments);
        // The inscribed polyhedron's silhouette is smaller than the sphere's by at most
        // 1 − cos²(π/segments)-ish; the pixel grid adds its own quantisation.
        let bvh = MeshBvh::new(&mesh);
        let pose = Pose {
            position_mm: centre,
            rotation: rotation_xyz_deg([15.0, -30.0, 45.0]),
        };
        let img = render_binary(&frame, source, &[Object::Mesh { bvh: &bvh, pose }], 1);
        let area = img.iter().filter(|&&p| p == 1).count() as f64 * pixel_area;
        let rel = (area - exact) / exact;
        assert!(
            rel.abs() < tolerance,
            "{rings}x{segments}: area {area} vs exact {exact} ({rel:+.5})"
        );
        let sphere = render_binary(
            &frame,
            source,
            &[Object::Sphere {
                centre_mm: centre,
                radius_mm: r,
            }],
            1,
        );
        let exact_pixels = sphere.iter().filter(|&&p| p == 1).count() as f64 * pixel_area;
        assert!(
            ((exact_pixels - exact) / exact).abs() < 0.001,
            "exact sphere: {exact_pixels} vs {exact}"
        );
    }
}

#[test]
fn written_background_noise_has_the_poisson_mean_and_variance() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("g");
    run_scenario("scenarios/golden/small_biplanar.toml", &out, &[]);
    for (dir, truth) in truths(&out) {
        for image in &truth.images {
            let (_, _, img) = read_tiff(&dir.join(&image.files[0].path));
            let det = truth
                .run
                .detectors
                .iter()
                .find(|d| d.id == image.detector)
                .unwrap();
            let lambda = truth.run.noise_level * det.i_max() as f64;
            let background: Vec<f64> = img
                .iter()
                .filter(|&&p| p != det.i_max())
                .map(|&p| p as f64)
                .collect();
            let n = background.len() as f64;
            let mean = background.iter().sum::<f64>() / n;
            let var = background.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
            if lambda == 0.0 {
                assert!(background.iter().all(|&x| x == 0.0));
                continue;
            }
            // Mean within 5 standard errors; the variance of a Poisson sample variance is ≈ (λ + 2λ²)/n.
            assert!(
                (mean - lambda).abs() < 5.0 * (lambda / n).sqrt(),
                "{}: mean {mean} vs λ {lambda}",
                truth.run.id
            );
            assert!(
                (var - lambda).abs() < 5.0 * ((lambda + 2.0 * lambda * lambda) / n).sqrt(),
                "var {var} vs λ {lambda}"
            );
        }
    }
}
