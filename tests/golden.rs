//! Golden outputs: the small golden scenarios regenerate byte for byte, on any thread count.
//!
//! To bless new hashes after a deliberate change: `RSASIM_BLESS=1 cargo test --test golden`,
//! and say why in the commit message.

mod common;

use common::{hashes, root, run_scenario};

const GOLDEN: &[&str] = &["small_biplanar", "small_uniplanar"];

#[test]
fn golden_scenarios_reproduce_their_hashes() {
    for name in GOLDEN {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join(name);
        run_scenario(&format!("scenarios/golden/{name}.toml"), &out, &[]);
        let got: String = hashes(&out)
            .iter()
            .map(|(p, h)| format!("{h}  {p}\n"))
            .collect();
        let file = root().join("golden").join(format!("{name}.sha256"));
        if std::env::var_os("RSASIM_BLESS").is_some() {
            std::fs::write(&file, &got).unwrap();
            continue;
        }
        let want = std::fs::read_to_string(&file).unwrap_or_else(|_| {
            panic!(
                "{} is missing: bless it with RSASIM_BLESS=1",
                file.display()
            )
        });
        let (want_lines, got_lines): (Vec<_>, Vec<_>) =
            (want.lines().collect(), got.lines().collect());
        let differing: Vec<_> = got_lines
            .iter()
            .filter(|l| !want_lines.contains(l))
            .collect();
        assert!(
            differing.is_empty() && want_lines.len() == got_lines.len(),
            "{name}: outputs differ from golden/{name}.sha256 ({} of {} lines differ, first: {:?})",
            differing.len(),
            got_lines.len(),
            differing.first()
        );
    }
}

#[test]
fn outputs_are_identical_on_one_and_two_threads() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("t1"), tmp.path().join("t2"));
    run_scenario(
        "scenarios/golden/small_biplanar.toml",
        &a,
        &[("RAYON_NUM_THREADS", "1")],
    );
    run_scenario(
        "scenarios/golden/small_biplanar.toml",
        &b,
        &[("RAYON_NUM_THREADS", "2")],
    );
    let (ha, hb) = (hashes(&a), hashes(&b));
    assert!(ha.len() > 20);
    assert_eq!(ha, hb);
}

#[test]
fn shipped_scenarios_carry_the_generated_knee_beads() {
    let beads = rsasim::phantom::femoral::femoral_component().beads;
    for file in ["scenarios/biplanar.toml", "scenarios/uniplanar.toml"] {
        let loaded =
            rsasim::scenario::load(&root().join(file)).unwrap_or_else(|e| panic!("{file}: {e:?}"));
        let femur = loaded
            .scenario
            .phantoms
            .iter()
            .find(|p| p.id == "femur")
            .unwrap();
        let listed = &femur.mesh.as_ref().unwrap().beads;
        assert_eq!(listed.len(), beads.len(), "{file}");
        for (a, b) in listed.iter().zip(&beads) {
            assert_eq!(
                (a.id.as_str(), a.position_mm, a.diameter_mm),
                (b.id.as_str(), b.position_mm, b.diameter_mm),
                "{file}"
            );
        }
    }
}
