//! Dynamic exams (`[sequence]`, `[phantoms.motion]`): every frame a run of its own with the
//! sequence's one geometry, the moving phantom where its keyframes put it (checked by hand), its
//! own noise, prefix-stable files, and the reference program tracking it frame by frame.

use crate::common;

use common::{ALLOW_MODELS, root, rsasim, rsasim_ok, run_scenario, truths};
use glam::{DMat3, DVec3};
use rsasim::evaluate::stats::Confidence;
use rsasim::evaluate::{MeasuredSource, Options, evaluate};

const SCENARIO: &str = "tests/scenarios/sequence.toml";
const DLT: &str = "measured-rsasim-dlt-markers.json";

/// The component's motion in tests/scenarios/sequence.toml, by hand: two keyframes (0 s and
/// 40 ms), so a straight line at constant speed, (0, 2, 1) mm over 40 ms, and 10° about x over
/// 40 ms, in the component's frame without motion.
fn motion_by_hand(t: f64) -> (DVec3, DMat3) {
    let u = (t / 0.04).min(1.0);
    let a = (10.0 * u).to_radians();
    let r = DMat3::from_cols(
        DVec3::X,
        DVec3::new(0.0, a.cos(), a.sin()),
        DVec3::new(0.0, -a.sin(), a.cos()),
    );
    (DVec3::new(0.0, 2.0, 1.0) * u, r)
}

#[test]
fn frames_are_runs_with_one_geometry_the_motion_by_hand_and_their_own_noise() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("seq");
    run_scenario(SCENARIO, &out, &[]);
    let o = rsasim_ok(&["verify", out.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("VERIFIED"));
    let t = truths(&out);
    let ids: Vec<&str> = t.iter().map(|(_, x)| x.run.id.as_str()).collect();
    assert_eq!(
        ids,
        [
            "n0-r00-f0000",
            "n0-r00-f0001",
            "n0-r00-f0002",
            "n0-r00-f0003",
            "n0-r00-f0004"
        ]
    );
    let first = &t[0].1.run;
    let femur = |run: &rsasim::expand::Run| {
        run.phantoms
            .iter()
            .find(|p| p.id == "femur")
            .unwrap()
            .pose()
    };
    let f0 = femur(first);
    for (k, (_, truth)) in t.iter().enumerate() {
        let run = &truth.run;
        let frame = run.frame.as_ref().expect("a frame record");
        assert_eq!(
            (frame.sequence.as_str(), frame.index, frame.count),
            ("n0-r00", k as u32, 5)
        );
        assert_eq!(frame.time_s, k as f64 / 100.0);
        assert_eq!(run.sources, first.sources);
        assert_eq!(run.detectors, first.detectors);
        assert_eq!(run.phantoms[0], first.phantoms[0], "the box stands still");
        // The femur's pose relative to frame 0 is the motion at the frame's time.
        let p = femur(run);
        let (dp, dr) = motion_by_hand(frame.time_s);
        let rel_r = f0.rotation.transpose() * p.rotation;
        let rel_p = f0.to_local(p.position_mm);
        assert!((rel_p - dp).length() < 1e-9, "frame {k}: {rel_p} vs {dp}");
        assert!((rel_r - dr).abs_diff_eq(DMat3::ZERO, 1e-12), "frame {k}");
    }
    // The box is where it was in every frame, but each frame has noise of its own.
    let image = |k: usize| std::fs::read(t[k].0.join("calibration-det1.tiff")).unwrap();
    assert_ne!(image(0), image(1));
}

#[test]
fn a_shorter_sequence_is_the_longer_ones_first_frames_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(root().join(SCENARIO))
        .unwrap()
        .replace("frames = 5", "frames = 2")
        .replace(
            "../../scenarios/models/femoral_component.glb",
            &root()
                .join("scenarios/models/femoral_component.glb")
                .to_string_lossy(),
        );
    let short = tmp.path().join("short.toml");
    std::fs::write(&short, text).unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    run_scenario(SCENARIO, &a, &[]);
    let o = rsasim(
        &[
            short.to_str().unwrap(),
            "--out",
            b.to_str().unwrap(),
            ALLOW_MODELS[0],
            root().join(ALLOW_MODELS[1]).to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for frame in ["n0-r00-f0000", "n0-r00-f0001"] {
        for image in [
            "calibration-det1.tiff",
            "calibration-det2.tiff",
            "model-det1.tiff",
            "model-det2.tiff",
        ] {
            let (x, y) = (
                std::fs::read(a.join("runs").join(frame).join(image)).unwrap(),
                std::fs::read(b.join("runs").join(frame).join(image)).unwrap(),
            );
            assert!(x == y, "{frame}/{image} differs between 5 and 2 frames");
        }
    }
    assert!(!b.join("runs/n0-r00-f0002").exists());
}

#[test]
fn the_reference_program_tracks_the_moving_component_frame_by_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("seq");
    run_scenario(SCENARIO, &out, &[]);
    rsasim_ok(&["reconstruct", out.to_str().unwrap()]);
    let report = evaluate(
        &out,
        &Options {
            measured: MeasuredSource::PerRun(DLT.into()),
            confidence: Confidence::default(),
            mtpm_threshold_mm: rsasim::evaluate::DEFAULT_MTPM_THRESHOLD_MM,
            study: Default::default(),
            xmalab_2d: Default::default(),
        },
    )
    .unwrap_or_else(|e| panic!("{e:?}"));
    assert!(report.excluded.is_empty(), "{:?}", report.excluded);
    let table = report
        .tables
        .iter()
        .find(|t| t.id == "phantom-femur")
        .expect("the femur's table");
    // One row (one noise level) over the 5 frames: every cell's RMS error within 0.1 mm / 0.1°.
    assert_eq!(table.rows.len(), 1);
    let row = &table.rows[0];
    assert_eq!(row.cells.len(), 6);
    for cell in &row.cells {
        let cell = cell.as_ref().expect("measured");
        assert_eq!(cell.n, 5);
        assert!(cell.rms < 0.1, "{cell:?}");
    }
}
