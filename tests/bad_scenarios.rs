//! Bad scenarios: each gives a clear error that names the file, the line and the key, exit code
//! 2, and writes nothing.

mod common;

use std::path::Path;

use common::rsasim;

/// A small valid scenario; each case below breaks one thing in it.
const BASE: &str = r#"name = "base"
seed = 1

[protocol]
noise_levels = [0.0, 0.5]
runs_per_level = 1

[[sources]]
id = "tube1"
position_mm = [0.0, 0.0, 1000.0]

[[detectors]]
id = "det1"
source = "tube1"
pixels = [64, 64]
size_mm = [200.0, 200.0]
bpp = 12
position_mm = [0.0, 0.0, -300.0]

[[phantoms]]
id = "beads"
position_mm = [0.0, 0.0, 0.0]

[[phantoms.beads]]
id = "B1"
position_mm = [10.0, 0.0, 0.0]

[[exposures]]
id = "calibration"
phantoms = ["beads"]
"#;

const MESH_PHANTOM: &str = r#"
[[phantoms]]
id = "model"

[phantoms.mesh]
file = "MESHFILE"

[[exposures]]
id = "model"
phantoms = ["model"]
"#;

/// (what is broken, text to replace in BASE, its replacement, expected message part, a text
/// whose line the error must point at)
const CASES: &[(&str, &str, &str, &str, &str)] = &[
    (
        "unknown key",
        "bpp = 12",
        "bpp = 12\npixel_size = 0.3",
        "unknown field `pixel_size`",
        "pixel_size = 0.3",
    ),
    (
        "negative size",
        "size_mm = [200.0, 200.0]",
        "size_mm = [-200.0, 200.0]",
        "detector size must be positive",
        "size_mm = [-200.0",
    ),
    (
        "bpp too large",
        "bpp = 12",
        "bpp = 17",
        "bpp 17 is out of range",
        "bpp = 17",
    ),
    (
        "wrong type",
        "bpp = 12",
        "bpp = \"12\"",
        "invalid type",
        "bpp = \"12\"",
    ),
    (
        "noise level above 1",
        "noise_levels = [0.0, 0.5]",
        "noise_levels = [0.0, 1.5]",
        "noise level 1.5 is outside [0, 1]",
        "noise_levels",
    ),
    (
        "zero runs",
        "runs_per_level = 1",
        "runs_per_level = 0",
        "runs_per_level is 0",
        "runs_per_level = 0",
    ),
    (
        "unknown source",
        "source = \"tube1\"",
        "source = \"tube9\"",
        "no source has the id `tube9`",
        "source = \"tube9\"",
    ),
    (
        "size and pitch",
        "bpp = 12",
        "bpp = 12\npixel_pitch_mm = [0.3, 0.3]",
        "both size_mm and pixel_pitch_mm",
        "pixel_pitch_mm",
    ),
    (
        "zero pixels",
        "pixels = [64, 64]",
        "pixels = [0, 64]",
        "pixel counts [0, 64] are out of range",
        "pixels = [0, 64]",
    ),
    (
        "duplicate id",
        "position_mm = [10.0, 0.0, 0.0]\n",
        "position_mm = [10.0, 0.0, 0.0]\n\n[[phantoms.beads]]\nid = \"B1\"\nposition_mm = [0.0, 5.0, 0.0]\n",
        "two beads have the id `B1`",
        "id = \"B1\"\nposition_mm = [0.0, 5.0",
    ),
    (
        "unknown phantom in exposure",
        "phantoms = [\"beads\"]",
        "phantoms = [\"bead\"]",
        "no phantom has the id `bead`",
        "phantoms = [\"bead\"]",
    ),
    (
        "phantom behind the detector",
        "position_mm = [0.0, 0.0, 0.0]",
        "position_mm = [0.0, 0.0, -400.0]",
        "is not between source `tube1` and detector `det1`",
        "position_mm = [0.0, 0.0, -400.0]",
    ),
    (
        "no shape",
        "[[phantoms.beads]]\nid = \"B1\"\nposition_mm = [10.0, 0.0, 0.0]\n",
        "",
        "must have exactly one of",
        "[[phantoms]]",
    ),
    ("bad syntax", "seed = 1", "seed = = 1", "", "seed = = 1"),
    (
        "missing mesh",
        "",
        MESH_PHANTOM,
        "does not exist",
        "file = \"MESHFILE\"",
    ),
    (
        "open mesh",
        "",
        MESH_PHANTOM,
        "is not a closed surface",
        "file = \"MESHFILE\"",
    ),
    (
        "unreadable mesh",
        "",
        MESH_PHANTOM,
        "cannot read mesh",
        "file = \"MESHFILE\"",
    ),
];

fn line_of(text: &str, needle: &str) -> usize {
    let at = text
        .find(needle)
        .unwrap_or_else(|| panic!("`{needle}` not in the scenario"));
    text[..at].matches('\n').count() + 1
}

fn prepare_mesh(case: &str, dir: &Path) -> String {
    let path = dir.join("model.stl");
    match case {
        "open mesh" => {
            let mut m = rsasim::phantom::TriMesh::uv_sphere(10.0, 8, 8);
            m.triangles.pop();
            rsasim::phantom::mesh_io::write_stl(&m, std::fs::File::create(&path).unwrap()).unwrap();
        }
        "unreadable mesh" => std::fs::write(&path, b"this is not an STL file").unwrap(),
        _ => {}
    }
    "model.stl".into()
}

#[test]
fn each_bad_scenario_is_named_located_and_writes_nothing() {
    for &(case, from, to, message, locate) in CASES {
        let dir = tempfile::tempdir().unwrap();
        let mesh = prepare_mesh(case, dir.path());
        let text = if from.is_empty() {
            format!("{BASE}{}", to.replace("MESHFILE", &mesh))
        } else {
            BASE.replacen(from, to, 1)
        };
        assert_ne!(text, BASE, "{case}: the mutation did not apply");
        let file = dir.path().join("bad.toml");
        std::fs::write(&file, &text).unwrap();
        let out = dir.path().join("out");
        let line = line_of(&text, &locate.replace("MESHFILE", &mesh));
        for args in [
            vec!["validate", file.to_str().unwrap()],
            vec![file.to_str().unwrap(), "--out", out.to_str().unwrap()],
        ] {
            let o = rsasim(&args, &[]);
            let stderr = String::from_utf8_lossy(&o.stderr);
            assert_eq!(
                o.status.code(),
                Some(2),
                "{case}: exit code, stderr:\n{stderr}"
            );
            assert!(
                stderr.contains(message),
                "{case}: expected `{message}` in:\n{stderr}"
            );
            let at = format!("bad.toml:{line}:");
            assert!(
                stderr.contains(&at),
                "{case}: expected the location `{at}` in:\n{stderr}"
            );
            assert!(stderr.contains("nothing was written"), "{case}: {stderr}");
            assert!(
                !out.exists() && !dir.path().join("out.partial").exists(),
                "{case}: something was written"
            );
        }
    }
}

#[test]
fn errors_say_what_is_valid() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.toml");
    std::fs::write(&file, BASE.replacen("bpp = 12", "bpp = 17", 1)).unwrap();
    let o = rsasim(&["validate", file.to_str().unwrap()], &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("`detectors[0].bpp`") && stderr.contains("help: bpp must be 1..=16"),
        "{stderr}"
    );
    std::fs::write(&file, BASE.replacen("bpp = 12", "bpp = 12\nbpx = 1", 1)).unwrap();
    let stderr =
        String::from_utf8_lossy(&rsasim(&["validate", file.to_str().unwrap()], &[]).stderr)
            .into_owned();
    assert!(
        stderr.contains("expected one of") && stderr.contains("`size_mm`"),
        "{stderr}"
    );
}

#[test]
fn a_phantom_partly_outside_the_field_is_a_warning_not_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("edge.toml");
    std::fs::write(
        &file,
        BASE.replacen(
            "position_mm = [10.0, 0.0, 0.0]",
            "position_mm = [98.0, 0.0, 0.0]",
            1,
        ),
    )
    .unwrap();
    let o = rsasim(&["validate", file.to_str().unwrap()], &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning")
            && stderr.contains("partly outside the field of detector `det1`"),
        "{stderr}"
    );
}

#[test]
fn an_existing_output_folder_is_refused_without_force() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ok.toml");
    std::fs::write(&file, BASE).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("keep.txt"), b"x").unwrap();
    let o = rsasim(
        &[file.to_str().unwrap(), "--out", out.to_str().unwrap()],
        &[],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--force"));
    assert!(out.join("keep.txt").exists());
    let o = rsasim(
        &[
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--force",
        ],
        &[],
    );
    // A folder rsasim did not write is never replaced, even with --force (issue 10).
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not written by rsasim"));
    assert!(out.join("keep.txt").exists() && !out.join("manifest.json").exists());
}
