//! `rsasim scene` end to end: the page of a scenario, its thumbnails against the images the
//! simulation writes, what it refuses to replace, and the page in a real headless browser.

use crate::common;

use std::path::Path;

use base64::Engine;
use common::{ALLOW_MODELS, read_tiff, rsasim, run_scenario};

const SCENARIO: &str = "scenarios/golden/small_uniplanar.toml";

/// `rsasim scene SCENARIO --out page` with the models allowed: (exit code, stderr).
fn scene(scenario: &str, page: &Path) -> (Option<i32>, String) {
    let o = rsasim(
        &[
            "scene",
            scenario,
            "--out",
            page.to_str().unwrap(),
            ALLOW_MODELS[0],
            ALLOW_MODELS[1],
        ],
        &[],
    );
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The thumbnails' PNG bytes in page order, from their data URLs.
fn thumbnails(page: &str) -> Vec<Vec<u8>> {
    page.split("<img src=\"data:image/png;base64,")
        .skip(1)
        .map(|rest| {
            let b64 = &rest[..rest.find('"').unwrap()];
            base64::engine::general_purpose::STANDARD
                .decode(b64)
                .unwrap()
        })
        .collect()
}

#[test]
fn the_page_shows_the_first_run_and_replaces_only_its_own_kind() {
    let tmp = tempfile::tempdir().unwrap();
    let page = tmp.path().join("pages").join("scene.html");
    let (code, stderr) = scene(SCENARIO, &page);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        // small_uniplanar: bead `B1` inside the ball (its cage spans both detectors by design).
        stderr.contains("1 warning(s)") && stderr.contains("KiB ->"),
        "{stderr}"
    );
    let text = std::fs::read_to_string(&page).unwrap();
    // The thumbnails are the first run's images as the simulation writes them, each made into a
    // 160 px preview independently here.
    let out = tmp.path().join("out");
    run_scenario(SCENARIO, &out, &[]);
    let mut expected = Vec::new();
    for det in ["right", "left"] {
        for exposure in ["calibration", "model"] {
            let (w, h, px) = read_tiff(
                &out.join("runs/n0-r00")
                    .join(format!("{exposure}-{det}.tiff")),
            );
            expected.push(rsasim::output::preview::preview_png(&px, w, h, 160));
        }
    }
    assert_eq!(thumbnails(&text), expected);
    assert!(text.contains("<figcaption>calibration · right</figcaption>"));
    // The same scenario gives the same bytes; an earlier page is replaced.
    let (code, _) = scene(SCENARIO, &page);
    assert_eq!(code, Some(0));
    assert_eq!(std::fs::read_to_string(&page).unwrap(), text);
    // A file of the user's is left alone: exit 2, nothing written.
    let mine = tmp.path().join("mine.html");
    std::fs::write(&mine, "my page").unwrap();
    let (code, stderr) = scene(SCENARIO, &mine);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("not a page rsasim scene wrote"), "{stderr}");
    assert_eq!(std::fs::read_to_string(&mine).unwrap(), "my page");
    // A scenario with an error: exit 2, no page.
    let bad = tmp.path().join("bad.toml");
    std::fs::write(&bad, "name = \"bad\"\nseed = -1\n").unwrap();
    let none = tmp.path().join("none.html");
    let (code, _) = scene(bad.to_str().unwrap(), &none);
    assert_eq!(code, Some(2));
    assert!(!none.exists());
    // Without images: no simulation, no thumbnails.
    let o = rsasim(
        &[
            "scene",
            SCENARIO,
            "--no-images",
            "--out",
            none.to_str().unwrap(),
            ALLOW_MODELS[0],
            ALLOW_MODELS[1],
        ],
        &[],
    );
    assert!(o.status.success());
    let text = std::fs::read_to_string(&none).unwrap();
    assert!(thumbnails(&text).is_empty() && text.contains("--no-images"));
}

#[test]
fn the_page_draws_in_a_headless_browser_without_console_messages() {
    let test = "the_page_draws_in_a_headless_browser_without_console_messages";
    let Some(browser) = common::browser::chromium_or_skip(test) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let page = tmp.path().join("scene.html");
    let (code, stderr) = scene(SCENARIO, &page);
    assert_eq!(code, Some(0), "{stderr}");
    let (console, shot) = common::browser::screenshot(&browser, &page, 1200, 800);
    assert!(console.is_empty(), "{console:?}");
    // The canvas (900 × 640 CSS px from (16, ~75)) is drawn: many pixels differ from its
    // background, in several colours (detectors, cones, sources, labels).
    assert_eq!((shot.width, shot.height), (1200, 800));
    let mut drawn = 0usize;
    let mut colours = std::collections::BTreeSet::new();
    for y in 120..700 {
        for x in 30..900 {
            let rgb = shot.pixel(x, y);
            if rgb != [0xfb, 0xfb, 0xfb] {
                drawn += 1;
                colours.insert(rgb.map(|c| c / 32));
            }
        }
    }
    let total = 580 * 870;
    assert!(drawn > total / 50, "only {drawn} of {total} pixels drawn");
    assert!(colours.len() >= 8, "{} colours", colours.len());
}
