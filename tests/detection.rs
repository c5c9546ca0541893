//! Bead detection of the reference RSA program at every noise level of the paper: detection
//! rate and centroid error against the projected centres in truth.json (the paper's tested
//! program broke under noise; ours must not).

use crate::common;

use common::{read_tiff, run_scenario, truths};
use rsasim::reconstruct::detect::blobs;

#[test]
fn beads_are_found_with_sub_pixel_centroids_at_every_noise_level() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("det");
    run_scenario("tests/scenarios/detection.toml", &out, &[]);
    for (dir, truth) in truths(&out) {
        let (mut expected, mut found, mut errors) = (0, 0, Vec::new());
        for image in &truth.images {
            let det = truth
                .run
                .detectors
                .iter()
                .find(|d| d.id == image.detector)
                .unwrap();
            let (w, _, px) = read_tiff(&dir.join(&image.files[0].path));
            // Bead-sized blobs, as the reconstruction keeps them.
            let found_blobs: Vec<_> = blobs(&px, w as usize, det.i_max())
                .into_iter()
                .filter(|b| (6..=40).contains(&b.area))
                .collect();
            let centres: Vec<[f64; 2]> = image.markers.iter().map(|m| m.pixel).collect();
            for m in image.markers.iter().filter(|m| m.inside) {
                // Beads whose blobs cannot touch another bead's (more than two blob diameters apart).
                if centres
                    .iter()
                    .filter(|c| (c[0] - m.pixel[0]).hypot(c[1] - m.pixel[1]) < 12.0)
                    .count()
                    > 1
                {
                    continue;
                }
                expected += 1;
                let nearest = found_blobs
                    .iter()
                    .map(|b| (b.centroid.x - m.pixel[0]).hypot(b.centroid.y - m.pixel[1]))
                    .fold(f64::INFINITY, f64::min);
                if nearest < 1.0 {
                    found += 1;
                    errors.push(nearest);
                }
            }
        }
        let rate = found as f64 / expected as f64;
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        let max = errors.iter().copied().fold(0.0, f64::max);
        eprintln!(
            "noise {:>5.1}%: {found}/{expected} isolated beads detected ({:.1} %), centroid error mean {mean:.3} px, max {max:.3} px",
            truth.run.noise_level * 100.0,
            rate * 100.0
        );
        assert!(expected > 200, "{expected}");
        assert_eq!(
            found, expected,
            "noise {}: every isolated bead is found",
            truth.run.noise_level
        );
        // 1 mm beads are 4–5 px blobs: one ray per pixel quantises a centroid by up to ~0.3 px.
        assert!(
            mean < 0.2 && max < 0.4,
            "noise {}: mean {mean}, max {max}",
            truth.run.noise_level
        );
    }
}
