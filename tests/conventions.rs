//! `docs/src/reference/conventions.md` is the contract a reviewer reads instead of the code. These tests pin each
//! formula and label it states against the code, so the document cannot drift from what rsasim does.

use crate::common;

use glam::{DMat3, DVec3};
use rsasim::geometry::{DetectorFrame, Pose, rotation_xyz_deg};
use rsasim::noise::NoiseKey;
use sha2::{Digest, Sha256};

fn conventions() -> String {
    std::fs::read_to_string(common::root().join("docs/src/reference/conventions.md")).unwrap()
}

/// The document states `text` verbatim.
fn states(text: &str) {
    assert!(
        conventions().contains(text),
        "docs/src/reference/conventions.md no longer states `{text}`: update it with the code"
    );
}

#[test]
fn geometry_stream_label_is_the_documented_one() {
    states("`rsasim/geometry/v1/{seed}/{n}/{r}`");
    assert_eq!(
        rsasim::expand::geometry_stream_label(42, 2, 7),
        "rsasim/geometry/v1/42/2/7"
    );
}

#[test]
fn noise_key_is_sha256_of_the_documented_label() {
    states("`rsasim/noise/v1/{seed}/{n}/{r}/{exposure}/{detector}`");
    let key = NoiseKey::derive(42, 2, 7, "ap", "det_a");
    let want: [u8; 32] = Sha256::digest(b"rsasim/noise/v1/42/2/7/ap/det_a").into();
    assert_eq!(key.as_bytes(), &want);
}

#[test]
fn electronic_noise_key_is_sha256_of_the_documented_label() {
    states("`rsasim/electronic/v1/{seed}/{n}/{r}/{exposure}/{detector}`");
    let key = NoiseKey::derive_electronic(42, 2, 7, "ap", "det_a");
    let want: [u8; 32] = Sha256::digest(b"rsasim/electronic/v1/42/2/7/ap/det_a").into();
    assert_eq!(key.as_bytes(), &want);
}

#[test]
fn gaussian_focal_spots_use_the_documented_fwhm() {
    states("σ = a/2.3548");
    let nodes = rsasim::sampling::spot_nodes(rsasim::scenario::SpotProfile::Gaussian, 2.3548, 3);
    // 3-point Gauss–Hermite: ±√3 σ with σ = 1.
    assert!(
        (nodes[2].0 - 3f64.sqrt() * 2.3548 / rsasim::sampling::focal_spot::FWHM_PER_SIGMA).abs()
            < 1e-12
    );
}

#[test]
fn uniform_doubles_are_the_top_53_bits() {
    states("`(x >> 11) · 2⁻⁵³`");
    // The documented mapping, applied to the generator's own u64s, gives the library's uniforms.
    use rand_core::Rng;
    let mut a = rsasim::random::stream("conventions");
    let mut b = rsasim::random::stream("conventions");
    for _ in 0..100 {
        let x = a.next_u64();
        let want = (x >> 11) as f64 / (1u64 << 53) as f64;
        assert_eq!(rsasim::random::uniform01(&mut b), want);
    }
}

#[test]
fn euler_angles_are_x_then_y_then_z_in_degrees() {
    states("`R = Rx(α)·Ry(β)·Rz(γ)`");
    let [a, b, c] = [10f64, -20.0, 30.0].map(f64::to_radians);
    let want = DMat3::from_rotation_x(a) * DMat3::from_rotation_y(b) * DMat3::from_rotation_z(c);
    let got = rotation_xyz_deg([10.0, -20.0, 30.0]);
    assert!((got - want).to_cols_array().iter().all(|d| d.abs() < 1e-14));
}

#[test]
fn rotation_columns_are_the_local_axes_in_world_coordinates() {
    states("`world = rotation · local + position`");
    let pose = Pose::from_position_euler_deg([1.0, 2.0, 3.0], [0.0, 0.0, 90.0]);
    // Local x turns into world y under a 90° turn about z.
    let w = pose.to_world(DVec3::X);
    assert!((w - DVec3::new(1.0, 3.0, 3.0)).length() < 1e-12);
}

#[test]
fn pixel_centres_are_at_half_integers_from_the_centre_of_the_active_area() {
    states("`x = (i + 0.5 − W/2)·pitch_x`, `y = (j + 0.5 − H/2)·pitch_y`");
    let frame = DetectorFrame {
        pose: Pose::from_position_euler_deg([0.0; 3], [0.0; 3]),
        pixels: [4, 2],
        pixel_pitch_mm: [0.5, 0.25],
    };
    let p = frame.pixel_centre_world(0, 1);
    assert_eq!(p, DVec3::new((0.5 - 2.0) * 0.5, (1.5 - 1.0) * 0.25, 0.0));
    // A point straight above that centre projects onto (i + 0.5, j + 0.5).
    let uv = frame
        .project(DVec3::new(p.x, p.y, 1000.0), DVec3::new(p.x, p.y, 10.0))
        .unwrap();
    assert_eq!((uv.x, uv.y), (0.5, 1.5));
}

#[test]
fn tau_is_the_one_sided_95_percent_student_quantile_by_default() {
    states("τ = 1.729 at N = 20");
    let tau = rsasim::evaluate::stats::Confidence::default()
        .tau(20)
        .unwrap();
    assert!((tau - 1.729).abs() < 5e-4, "τ = {tau}");
}

#[test]
fn plausibility_bounds_and_echo_length_are_the_documented_ones() {
    states("lies within ±1e6 (mm or degrees)");
    assert_eq!(rsasim::evaluate::input::MAX_ABS_MM, 1e6);
    states("Measured rotations within 1e-3 of a proper rotation");
    assert_eq!(rsasim::evaluate::rotation::REPAIR_TOLERANCE, 1e-3);
    states("cut at 200 characters, marked `… (N more bytes)`");
    assert_eq!(rsasim::diagnostic::ECHO_MAX_CHARS, 200);
    assert!(rsasim::diagnostic::cut(&"x".repeat(201)).ends_with("… (1 more bytes)"));
}

#[test]
fn attenuation_metal_density_and_fluence_are_the_documented_ones() {
    states("`f = (D/r)³`");
    states("density ≥ 4 g/cm³");
    assert_eq!(rsasim::attenuation::setup::METAL_DENSITY_G_CM3, 4.0);
    // A detector 1200 mm below the source, 1 mm pixels: the corner pixel's fluence is (D/r)³.
    let frame = DetectorFrame {
        pose: Pose {
            position_mm: DVec3::new(0.0, 0.0, -200.0),
            rotation: DMat3::IDENTITY,
        },
        pixels: [64, 64],
        pixel_pitch_mm: [1.0, 1.0],
    };
    let f = rsasim::response::point_source_fluence(&frame, DVec3::new(0.0, 0.0, 1000.0));
    let (x, y) = (0.5 - 32.0, 0.5 - 32.0);
    let r = (x * x + y * y + 1200.0f64 * 1200.0).sqrt();
    assert!((f[0] - (1200.0 / r).powi(3)).abs() < 1e-12);
}

#[test]
fn dicom_uids_are_the_documented_uuids_of_the_documented_labels() {
    states("`rsasim/dicom/v1/study/{scenario_sha256}/{run}`");
    states("`rsasim/dicom/v1/series/{scenario_sha256}/{run}/{exposure}/{intent}`");
    states("`rsasim/dicom/v1/instance/{scenario_sha256}/{run}/{exposure}/{detector}/{intent}`");
    let uid = |label: &str| {
        let d = Sha256::digest(label.as_bytes());
        let mut b = [0u8; 16];
        b.copy_from_slice(&d[..16]);
        b[6] = 0x80 | (b[6] & 0x0f);
        b[8] = 0x80 | (b[8] & 0x3f);
        format!("2.25.{}", u128::from_be_bytes(b))
    };
    use rsasim::output::dicom::uid;
    assert_eq!(
        uid::study_uid("ab12", "n1-r03"),
        uid("rsasim/dicom/v1/study/ab12/n1-r03")
    );
    assert_eq!(
        uid::series_uid("ab12", "n1-r03", "ap", "processing"),
        uid("rsasim/dicom/v1/series/ab12/n1-r03/ap/processing")
    );
    assert_eq!(
        uid::instance_uid("ab12", "n1-r03", "ap", "det_a", "presentation"),
        uid("rsasim/dicom/v1/instance/ab12/n1-r03/ap/det_a/presentation")
    );
}

#[test]
fn image_pitch_tags_are_the_documented_ones() {
    states("`10 / pitch_mm` pixels per");
    states("`xDensity = 25.4 / pitch_x`");
    states("`pitch_y \\ pitch_x` (row spacing first)");
    let r = rsasim::output::tiff::pixels_per_cm(0.3).unwrap();
    assert_eq!((r.n, r.d), (100, 3));
}

#[test]
fn exported_pixel_coordinates_are_the_documented_ones() {
    use rsasim::interop::camera::{dlt_pixel, opencv_pixel};
    states("`x = u − 0.5, y = H − v − 0.5`");
    states("`X = u + 0.5, Y = v + 0.5`");
    states("row j of the exported TIFF is row `H − 1 − j`");
    assert_eq!(opencv_pixel([10.25, 3.5], 200), [9.75, 196.0]);
    assert_eq!(dlt_pixel([10.25, 3.5]), [10.75, 4.0]);
    let flipped = rsasim::interop::export::export_pixels(&[1, 2, 3, 4, 5, 6], 2, 65535, false);
    assert_eq!(flipped, [5, 6, 3, 4, 1, 2]);
}

#[test]
fn the_exported_camera_is_the_documented_one() {
    use rsasim::expand::DetectorState;
    use rsasim::interop::camera::PinholeCamera;
    states("axes `x = r, y = −c, z = −s`");
    states("`c_x = a/pitch_x + W/2 − 0.5`, `c_y = H/2 − b/pitch_y − 0.5`");
    let rotation = rotation_xyz_deg([0.0, 90.0, 0.0]);
    let det = DetectorState {
        id: "d".into(),
        source: "s".into(),
        position_mm: DVec3::new(-500.0, 0.0, 0.0),
        rotation,
        pixels: [100, 80],
        pixel_pitch_mm: [0.5, 0.25],
        bpp: 12,
    };
    // Source 1800 mm in front, 10 mm along r and −4 mm along c off the detector centre.
    let pose = Pose {
        position_mm: det.position_mm,
        rotation,
    };
    let source = pose.to_world(DVec3::new(10.0, -4.0, 1800.0));
    let cam = PinholeCamera::of_beamline(source, &det).unwrap();
    assert!((cam.k[0][0] - 3600.0).abs() < 1e-9 && (cam.k[1][1] - 7200.0).abs() < 1e-9);
    assert!((cam.k[0][2] - (20.0 + 50.0 - 0.5)).abs() < 1e-9);
    assert!((cam.k[1][2] - (40.0 + 16.0 - 0.5)).abs() < 1e-9);
    let r = DMat3::from_cols(
        DVec3::from_array(cam.r[0]),
        DVec3::from_array(cam.r[1]),
        DVec3::from_array(cam.r[2]),
    );
    // The rows of R are r, −c, −s.
    for (row, axis) in [
        (r.x_axis, rotation.x_axis),
        (r.y_axis, -rotation.y_axis),
        (r.z_axis, -rotation.z_axis),
    ] {
        assert!((row - axis).length() < 1e-12);
    }
}

#[test]
fn shards_are_dealt_round_robin_as_documented() {
    states("shard K holds the runs with\n  `p mod N = K`");
    states("K =\n  `SLURM_ARRAY_TASK_ID − SLURM_ARRAY_TASK_MIN`");
    use rsasim::shard::{ShardSpec, runs_of_shard};
    for (r, n) in [(10, 3), (40, 7), (3, 5)] {
        for k in 0..n {
            let spec = ShardSpec::new(k, n).unwrap();
            let by_rule: Vec<usize> = (0..r).filter(|p| p % n == k).collect();
            assert_eq!(runs_of_shard(r, spec), by_rule);
        }
    }
    assert_eq!(
        ShardSpec::new(3, 12).unwrap().folder_name(),
        "shard-03-of-12"
    );
}

/// The binary-mode noise of a row, rebuilt from the document's recipe alone (table thresholds on
/// `x >> 11`, weights from the mode, cut at 2⁻⁶⁴, clamp at I_max), equals `add_noise`'s pixels.
#[test]
fn binary_noise_is_the_documented_table_inversion() {
    states("`x >> 11 < T_k`");
    states("`T_k = round(C_k / S · 2⁵³)`");
    states("first weight below 2⁻⁶⁴");
    for (level, i_max) in [(0.45, 65535u16), (0.001, 65535), (0.9, 255), (0.002, 4095)] {
        let lambda = level * f64::from(i_max);
        let cut = 2f64.powi(-64);
        let mode = lambda.floor();
        let mut up = vec![1.0f64];
        let mut k = mode;
        loop {
            let w = up[up.len() - 1] * (lambda / (k + 1.0));
            if w < cut {
                break;
            }
            up.push(w);
            k += 1.0;
        }
        let mut down = Vec::new();
        let (mut w, mut k) = (1.0f64, mode);
        while k > 0.0 {
            w *= k / lambda;
            if w < cut {
                break;
            }
            down.push(w);
            k -= 1.0;
        }
        let k_lo = mode as u64 - down.len() as u64;
        let weights: Vec<f64> = down.iter().rev().chain(&up).copied().collect();
        let total: f64 = weights.iter().sum();
        let k_hi = k_lo + weights.len() as u64 - 1;
        let last = k_hi.min(u64::from(i_max));
        let mut thresholds = Vec::new();
        let mut c = 0.0;
        for &w in &weights[..(last.saturating_sub(k_lo)) as usize] {
            c += w;
            thresholds.push(libm::round(c / total * 2f64.powi(53)) as u64);
        }
        thresholds.push(1 << 53);
        let k_lo = k_lo.min(u64::from(i_max));
        let key = NoiseKey::derive(7, 1, 2, "model", "det1");
        let width = 3000;
        let mut row = vec![0u16; width];
        rsasim::noise::add_noise(&mut row, width, level, i_max, &key);
        let mut rng = key.row_rng(0);
        for (i, &px) in row.iter().enumerate() {
            let u = rand_core::Rng::next_u64(&mut rng) >> 11;
            let index = thresholds.iter().position(|&t| u < t).unwrap() as u64;
            assert_eq!(u64::from(px), k_lo + index, "level {level}, pixel {i}");
        }
    }
}

#[test]
fn sweep_points_are_ordered_and_named_as_documented() {
    states("the cartesian product, the first parameter varying\n  slowest");
    states("(`p00`, `p01`, …; `p000` from 101 points on)");
    let ids: Vec<String> = [(0, 100), (99, 100), (0, 101), (100, 101)]
        .iter()
        .map(|&(i, n)| rsasim::sweep::points::point_id(i, n))
        .collect();
    assert_eq!(ids, ["p00", "p99", "p000", "p100"]);
    let record: rsasim::sweep::file::SweepRecord = toml::from_str(
        "scenario = \"s.toml\"\n[[parameters]]\nkey = \"a\"\nvalues = [1, 2]\n[[parameters]]\nkey = \"b\"\nvalues = [1, 2, 3]\n",
    )
    .unwrap();
    let order = rsasim::sweep::points::choices(&record);
    assert_eq!(order[..4], [vec![0, 0], vec![0, 1], vec![0, 2], vec![1, 0]]);
}

#[test]
fn a_sharded_sweeps_tasks_write_the_documented_shards() {
    states("task K writes shard `j = (K − o_p) mod N` of every point p");
    use rsasim::shard::ShardSpec;
    let runs = [3, 5, 2, 7];
    for n in [1, 2, 3, 4, 9] {
        for k in 0..n {
            let got = rsasim::sweep::split::point_shards(&runs, ShardSpec::new(k, n).unwrap());
            let mut o_p = 0;
            for (p, &r) in runs.iter().enumerate() {
                let j = (k + n * o_p - o_p) % n;
                assert_eq!(
                    got[p],
                    ShardSpec::new(j, n).unwrap(),
                    "K = {k}, N = {n}, p = {p}"
                );
                o_p += r;
            }
        }
    }
}

#[test]
fn study_stream_labels_and_run_ids_are_the_documented_ones() {
    states("`rsasim/study/v1/{seed}/{patient}/{exam}`");
    states("`rsasim/study/v1/{seed}/{patient}`");
    states("`{patient}-e{i}-{exam}`");
    assert_eq!(
        rsasim::expand::study::exam_stream_label(42, 2, "3m"),
        "rsasim/study/v1/42/p03/3m"
    );
    assert_eq!(
        rsasim::expand::study::patient_stream_label(42, 0),
        "rsasim/study/v1/42/p01"
    );
}
