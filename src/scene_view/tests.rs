use super::*;
use crate::simulate::{Allowances, check};
use scene::Point;

/// The small uniplanar golden scenario (a cage, a meshed ball with a hidden bead, random source
/// and detector poses), checked.
fn uniplanar() -> Checked {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    check(
        &root.join("scenarios/golden/small_uniplanar.toml"),
        &Allowances {
            dirs: vec![root.join("scenarios/models")],
            large: false,
        },
    )
    .unwrap()
}

#[test]
fn objects_stand_where_the_first_run_puts_them_and_envelopes_cover_the_ranges() {
    let checked = uniplanar();
    let s = &checked.loaded.scenario;
    let first = crate::expand::runs(s, &checked.models).next().unwrap();
    let scene = build(s, &checked.models, &checked.warnings, &|_| Vec::new());
    assert_eq!(scene.run, first.id);
    assert_eq!(scene.envelope_runs, scene.total_runs);
    // The cage (the box frame) stands at z = −450 mm in the scanner frame the page draws in.
    let scanner = first.box_pose_in_scanner;
    assert_eq!(scanner.position_mm, glam::DVec3::new(0.0, 0.0, -450.0));
    for (view, (state, nominal)) in scene
        .sources
        .iter()
        .zip(first.sources.iter().zip(&s.sources))
    {
        let p = scanner.to_world(state.position_mm);
        for k in 0..3 {
            assert!((view.position[k] - p[k]).abs() <= 0.005);
        }
        // The envelope holds the first run's focus and lies inside nominal ± range.
        let [lo, hi] = view.envelope.expect("the sources move");
        for k in 0..3 {
            let r = nominal.randomize.position_mm[k];
            assert!(lo[k] <= view.position[k] && view.position[k] <= hi[k]);
            assert!(lo[k] >= nominal.position_mm[k] - r - 0.01);
            assert!(hi[k] <= nominal.position_mm[k] + r + 0.01);
        }
    }
    // A detector's corners: a rectangle of its active area, centred on its position.
    let d = &scene.detectors[0];
    let state = &first.detectors[0];
    let side = |a: Point, b: Point| ((0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>()).sqrt();
    let size = [
        state.pixels[0] as f64 * state.pixel_pitch_mm[0],
        state.pixels[1] as f64 * state.pixel_pitch_mm[1],
    ];
    assert!((side(d.corners[0], d.corners[1]) - size[0]).abs() < 0.02);
    assert!((side(d.corners[1], d.corners[2]) - size[1]).abs() < 0.02);
    let centre: Vec<f64> = (0..3)
        .map(|k| d.corners.iter().map(|c| c[k]).sum::<f64>() / 4.0)
        .collect();
    let p = scanner.to_world(state.position_mm);
    for k in 0..3 {
        assert!((centre[k] - p[k]).abs() < 0.02);
    }
    assert!(d.envelope.is_some());
    // The cage has no random range: no envelope. Its beads are the first run's.
    let cage = &scene.phantoms[0];
    assert!(cage.envelope.is_none());
    assert_eq!(cage.beads.len(), first.phantoms[0].markers.len());
    let b = &first.phantoms[0].markers[3];
    let p = scanner.to_world(b.position_mm);
    for k in 0..3 {
        assert!((cage.beads[3][k] - p[k]).abs() <= 0.005);
    }
    assert_eq!(cage.beads[3][3], b.diameter_mm / 2.0);
}

#[test]
fn warnings_stand_at_the_object_or_bead_they_concern() {
    let checked = uniplanar();
    // The cage spans both detectors by design, so no check warns about it: a phantom-level
    // warning is added here, as `validate` would put one (at the phantom's position key).
    let mut warnings = checked.warnings.clone();
    warnings.push(
        checked.loaded.locator.warning(
            crate::diagnostic::KeyPath::root()
                .key("phantoms")
                .index(0)
                .key("position_mm"),
            "phantom `cage` falls partly outside the field of detector `left`",
        ),
    );
    let scene = build(
        &checked.loaded.scenario,
        &checked.models,
        &warnings,
        &|_| Vec::new(),
    );
    assert_eq!(scene.warnings.len(), warnings.len());
    let cage = &scene.phantoms[0];
    let outside: Vec<_> = scene
        .warnings
        .iter()
        .filter(|w| w.text.contains("falls partly outside the field"))
        .collect();
    assert_eq!(outside.len(), 1);
    for w in outside {
        assert_eq!(w.key.as_deref(), Some("phantoms[0].position_mm"));
        assert_eq!(w.at, Some(cage.centre));
    }
    let hidden = scene
        .warnings
        .iter()
        .find(|w| w.text.contains("bead `B1`"))
        .unwrap();
    let bead = scene.phantoms[1].beads[0];
    assert_eq!(hidden.at, Some([bead[0], bead[1], bead[2]]));
    // A warning about no object stands nowhere.
    let general = crate::diagnostic::Diagnostic::file_error(Path::new("x.toml"), "general");
    let scene = build(
        &checked.loaded.scenario,
        &checked.models,
        &[general],
        &|_| Vec::new(),
    );
    assert_eq!(scene.warnings[0].at, None);
}

#[test]
fn the_page_is_self_contained_deterministic_and_lists_the_first_run_images() {
    let scene = scene_of(uniplanar(), true).unwrap();
    // One thumbnail per exposure and detector, each a PNG of at most 160 px a side.
    for d in &scene.detectors {
        assert_eq!(d.images.len(), 2);
        for im in &d.images {
            use base64::Engine;
            let b64 = im.src.strip_prefix("data:image/png;base64,").unwrap();
            let png = base64::engine::general_purpose::STANDARD
                .decode(b64)
                .unwrap();
            let reader = png::Decoder::new(std::io::Cursor::new(png))
                .read_info()
                .unwrap();
            let info = reader.info();
            assert!(info.width.max(info.height) <= thumbnails::THUMBNAIL_MAX_SIDE_PX);
            assert!(info.width.max(info.height) >= 100);
        }
    }
    let page = page(&scene);
    assert_eq!(page, super::page(&scene_of(uniplanar(), true).unwrap()));
    for remote in ["http:", "https:", "<link", "<iframe", "src=\"//", "@import"] {
        assert!(!page.contains(remote), "{remote}");
    }
    assert_eq!(page.matches("<img src=\"data:image/png;base64,").count(), 4);
    assert!(page.contains(&format!(
        "<meta name=\"generator\" content=\"{GENERATOR} {}\"/>",
        env!("CARGO_PKG_VERSION")
    )));
    // The JSON parses back to the scene's values, and no "</script" ends it early.
    let start = page.find("id=\"scene-data\">").unwrap() + "id=\"scene-data\">".len();
    let json = &page[start..start + page[start..].find("</script>").unwrap()];
    let value: serde_json::Value = serde_json::from_str(json).unwrap();
    assert_eq!(value["name"], "small_uniplanar");
    // One warning: bead `B1` lies inside the ball (the cage spans both detectors by design).
    assert_eq!(value["warnings"].as_array().unwrap().len(), 1);
    assert_eq!(page.matches("<li><code>").count(), 1);
    assert!(page.contains(VIEWER_JS) && page.contains(VIEWER_CSS));
    // Size: under 300 KiB with four noisy thumbnails and a 2,500-triangle mesh at most.
    assert!(page.len() < 300 * 1024, "{}", page.len());
}

#[test]
fn a_page_replaces_only_an_earlier_page() {
    let dir = tempfile::tempdir().unwrap();
    let mine = dir.path().join("notes.html");
    std::fs::write(&mine, "<html>my notes</html>").unwrap();
    let err = check_page_target(&mine).unwrap_err();
    assert!(
        err.message.contains("not a page rsasim scene wrote"),
        "{}",
        err.message
    );
    assert!(check_page_target(&dir.path().join("new.html")).is_ok());
    assert!(check_page_target(dir.path()).is_err());
    let earlier = dir.path().join("scene.html");
    let checked = uniplanar();
    let scene = build(&checked.loaded.scenario, &checked.models, &[], &|_| {
        Vec::new()
    });
    std::fs::write(&earlier, page(&scene)).unwrap();
    assert!(check_page_target(&earlier).is_ok());
}
