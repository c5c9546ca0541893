//! Bad scenarios: each gives a clear error that names the file, the line and the key, exit code
//! 2, and writes nothing.

use crate::common;

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
        "vector with an extra number",
        "position_mm = [0.0, 0.0, 1000.0]",
        "position_mm = [0.0, 0.0, 1000.0, 5.0]",
        "expected exactly 3 numbers, got 4",
        "position_mm = [0.0, 0.0, 1000.0, 5.0]",
    ),
    (
        "pixel counts with a missing number",
        "pixels = [64, 64]",
        "pixels = [64]",
        "expected exactly 2 numbers, got 1",
        "pixels = [64]",
    ),
    (
        "phantom outside every detector",
        "position_mm = [10.0, 0.0, 0.0]",
        "position_mm = [98.0, 0.0, 0.0]",
        "phantom `beads` lies outside the field of every detector in run n0-r00",
        "position_mm = [0.0, 0.0, 0.0]",
    ),
    (
        "runs_per_level typo",
        "runs_per_level = 1",
        "runs_per_level = 1000000000",
        "more than the cap of 100000",
        "runs_per_level = 1000000000",
    ),
    (
        "schema's largest detector as TIFF",
        "pixels = [64, 64]",
        "pixels = [65535, 65535]",
        "more than the 4 GiB a classic TIFF file can hold",
        "pixels = [65535, 65535]",
    ),
    (
        "id longer than a file name",
        "id = \"calibration\"",
        "id = \"calibrationcalibrationcalibrationcalibrationcalibrationcalibrationcalibrationcalibrationcalibrationcalibrationcalibration\"",
        "is 121 bytes long, more than 100",
        "id = \"calibrationcalibration",
    ),
    (
        "Windows device name as id",
        "id = \"det1\"",
        "id = \"NUL\"",
        "`NUL` is a device name Windows reserves",
        "id = \"NUL\"",
    ),
    (
        "id with a trailing dot",
        "id = \"det1\"",
        "id = \"det1.\"",
        "starts or ends with `.`",
        "id = \"det1.\"",
    ),
    (
        "image names equal but for case",
        "[[exposures]]\nid = \"calibration\"",
        "[[exposures]]\nid = \"Calibration\"\nphantoms = [\"beads\"]\n\n[[exposures]]\nid = \"calibration\"",
        "same name on case-insensitive file systems",
        "id = \"calibration\"",
    ),
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
    (
        "no rays per pixel",
        "seed = 1",
        "seed = 1\n[imaging]\npixel_samples = 0",
        "pixel_samples = 0 is out of range",
        "pixel_samples = 0",
    ),
    (
        "negative focal spot",
        "seed = 1",
        "seed = 1\n[imaging]\nfocal_spot = { size_mm = -1.2 }",
        "focal spot size -1.2 mm is out of range",
        "focal_spot = { size_mm = -1.2 }",
    ),
    (
        "too many focal spot sub-sources",
        "seed = 1",
        "seed = 1\n[imaging.focal_spot]\nsize_mm = 0.6\nsamples = 40",
        "samples = 40 is out of range",
        "samples = 40",
    ),
    (
        "unknown focal spot profile",
        "seed = 1",
        "seed = 1\n[imaging.focal_spot]\nsize_mm = 0.6\nprofile = \"round\"",
        "unknown variant `round`",
        "profile = \"round\"",
    ),
    (
        "unknown ray sampling",
        "seed = 1",
        "seed = 1\n[imaging]\nray_sampling = \"some\"",
        "unknown variant `some`, expected `adaptive` or `full`",
        "ray_sampling = \"some\"",
    ),
    (
        "DICOM date not a calendar date",
        "[[sources]]",
        "[output]\nformats = [\"dicom\"]\ndicom.study_date = \"2023-02-30\"\n\n[[sources]]",
        "`2023-02-30` is not a date of the form YYYY-MM-DD",
        "dicom.study_date",
    ),
    (
        "DICOM intent listed twice",
        "[[sources]]",
        "[output]\nformats = [\"dicom\"]\n\n[output.dicom]\nintents = [\"processing\", \"processing\"]\n\n[[sources]]",
        "\"processing\" is listed twice",
        "intents = [",
    ),
    (
        "unknown DICOM intent",
        "[[sources]]",
        "[output]\nformats = [\"dicom\"]\ndicom.intents = [\"raw\"]\n\n[[sources]]",
        "unknown variant `raw`",
        "dicom.intents",
    ),
    (
        "format listed twice",
        "[[sources]]",
        "[output]\nformats = [\"tiff\", \"tiff\"]\n\n[[sources]]",
        "\"tiff\" is listed twice",
        "formats = [",
    ),
    (
        "DICOM with too few bits per pixel",
        "bpp = 12\nposition_mm = [0.0, 0.0, -300.0]",
        "bpp = 4\nposition_mm = [0.0, 0.0, -300.0]\n\n[output]\nformats = [\"tiff\", \"dicom\"]",
        "a DICOM Digital X-Ray image stores 6 to 16",
        "bpp = 4",
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
                stderr.len() < 4_000,
                "{case}: {} bytes of errors",
                stderr.len()
            );
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
        // The detector's half-width of 100 mm at magnification 1.3 is 76.92 mm at the bead:
        // a 1 mm bead at x = 76.9 mm straddles the edge.
        BASE.replacen(
            "position_mm = [10.0, 0.0, 0.0]",
            "position_mm = [76.9, 0.0, 0.0]",
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
fn a_soft_tissue_envelope_or_a_carried_bone_cut_by_the_field_is_no_warning_but_its_bead_is() {
    // At magnification 1.3 the field is ±76.92 mm wide at the beads' depth. A 300 mm cylinder
    // crosses it in every run, as a thigh does in a knee radiograph, and so does a wide solid
    // fixed to the bead set; neither is worth a warning. A bead of a phantom fixed to the bead set
    // that straddles the edge is.
    let background = "[[phantoms]]\nid = \"leg\"\nelliptic_cylinder = { radii_mm = [40.0, 40.0], length_mm = 300.0 }\nrotation_deg = [90.0, 0.0, 0.0]\n[[phantoms]]\nid = \"slab\"\nfixed_to = \"beads\"\nelliptic_cylinder = { radii_mm = [200.0, 5.0], length_mm = 10.0 }\n";
    let carried = "[[phantoms]]\nid = \"carried\"\nfixed_to = \"beads\"\n[[phantoms.beads]]\nid = \"C1\"\nposition_mm = [76.9, 0.0, 0.0]\n";
    let scenario = |extra: &str, ids: &str| {
        BASE.replace(
            "phantoms = [\"beads\"]",
            &format!("phantoms = [\"beads\", {ids}]"),
        ) + background
            + extra
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("leg.toml");
    let validate = |text: String| {
        std::fs::write(&file, text).unwrap();
        let o = rsasim(&["validate", file.to_str().unwrap()], &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let stderr = validate(scenario("", "\"leg\", \"slab\""));
    assert!(!stderr.contains("warning"), "{stderr}");
    let stderr = validate(scenario(carried, "\"leg\", \"slab\", \"carried\""));
    assert!(
        stderr.contains(
            "a bead of phantom `carried` falls partly outside the field of detector `det1`"
        ) && !stderr.contains("`slab`")
            && !stderr.contains("`leg`"),
        "{stderr}"
    );
}

#[test]
fn every_shipped_scenario_validates_without_a_warning() {
    let mut checked = 0;
    for e in std::fs::read_dir(common::root().join("scenarios")).unwrap() {
        let path = e.unwrap().path();
        if path.extension().and_then(|x| x.to_str()) != Some("toml") {
            continue;
        }
        let o = rsasim(&["validate", path.to_str().unwrap()], &[]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{}: {stderr}", path.display());
        assert!(!stderr.contains("warning"), "{}: {stderr}", path.display());
        checked += 1;
    }
    assert!(checked >= 9, "{checked} scenarios");
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

/// Writes a closed sphere of radius 10 mm as `ball.stl` into `dir`.
fn write_ball(dir: &Path) {
    let m = rsasim::phantom::TriMesh::uv_sphere(10.0, 16, 16);
    rsasim::phantom::mesh_io::write_stl(&m, std::fs::File::create(dir.join("ball.stl")).unwrap())
        .unwrap();
}

#[test]
fn a_bead_never_visible_warns_with_its_phantom_and_the_images_checked() {
    let dir = tempfile::tempdir().unwrap();
    write_ball(dir.path());
    // B9 projects outside the detector in every image; P1 sits inside the ball, so its ray
    // crosses the mesh in every image; P2 sits outside the ball, in the open.
    let text = BASE.replacen(
        "position_mm = [10.0, 0.0, 0.0]\n",
        "position_mm = [10.0, 0.0, 0.0]\n\n[[phantoms.beads]]\nid = \"B9\"\nposition_mm = [98.0, 0.0, 0.0]\n",
        1,
    ) + r#"
[[phantoms]]
id = "ball"
position_mm = [-40.0, 0.0, 0.0]

[phantoms.mesh]
file = "ball.stl"

[[phantoms.mesh.beads]]
id = "P1"
position_mm = [0.0, 0.0, 5.0]

[[phantoms.mesh.beads]]
id = "P2"
position_mm = [20.0, 0.0, 0.0]

[[exposures]]
id = "model"
phantoms = ["ball"]
"#;
    let file = dir.path().join("beads.toml");
    std::fs::write(&file, &text).unwrap();
    let o = rsasim(&["validate", file.to_str().unwrap()], &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!("beads.toml:{}:", line_of(&text, "id = \"B9\"")))
            && stderr.contains(
                "bead `B9` of phantom `beads` is visible in none of the 2 images it was checked in (outside the detector in 2"
            ),
        "{stderr}"
    );
    assert!(
        stderr.contains(&format!("beads.toml:{}:", line_of(&text, "id = \"P1\"")))
            && stderr.contains(
                "bead `P1` of phantom `ball` is visible in none of the 2 images it was checked in (outside the detector in 0, in a mesh's shadow in 2)"
            ),
        "{stderr}"
    );
    assert!(
        !stderr.contains("`P2`") && !stderr.contains("`B1`"),
        "{stderr}"
    );
}

/// A tiny deterministic generator (xorshift64*), so the mutation test needs no dependency.
struct Mutator(u64);

impl Mutator {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn pick<'a>(&mut self, items: &[&'a str]) -> &'a str {
        items[(self.next() % items.len() as u64) as usize]
    }

    /// BASE with one line changed: a number replaced by an extreme one, an array grown, a
    /// string replaced by one no file system accepts, or the line deleted or repeated.
    fn mutate(&mut self, base: &str) -> String {
        let mut lines: Vec<String> = base.lines().map(String::from).collect();
        let i = (self.next() % lines.len() as u64) as usize;
        let line = lines[i].clone();
        let long = "x".repeat(300);
        match self.next() % 5 {
            0 => {
                let number = self.pick(&[
                    "-1",
                    "0",
                    "1e308",
                    "nan",
                    "inf",
                    "-inf",
                    "4294967296",
                    "65535",
                    "1000000000",
                    "-0.0",
                    "1e-300",
                ]);
                let mut out = String::new();
                let mut replaced = false;
                for token in line.split_inclusive([' ', '[', ',', ']']) {
                    let digits = token.trim_end_matches([' ', '[', ',', ']']);
                    if !replaced && !digits.is_empty() && digits.parse::<f64>().is_ok() {
                        out.push_str(&token.replacen(digits, number, 1));
                        replaced = true;
                    } else {
                        out.push_str(token);
                    }
                }
                lines[i] = out;
            }
            1 => lines[i] = line.replacen(']', ", 5.0]", 1),
            2 => {
                let value = self.pick(&["", "CON", "a/b", "a:b", "é", "a.", "LONG"]);
                let value = if value == "LONG" {
                    long.as_str()
                } else {
                    value
                };
                if let (Some(a), Some(b)) = (line.find('"'), line.rfind('"')) {
                    if a < b {
                        lines[i] = format!("{}\"{value}\"{}", &line[..a], &line[b + 1..]);
                    }
                }
            }
            3 => {
                lines.remove(i);
            }
            _ => lines.insert(i, line),
        }
        lines.join("\n") + "\n"
    }
}

#[test]
fn seeded_mutations_give_exit_0_or_a_located_error_and_never_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("m.toml");
    let mut m = Mutator(0x5eed_0017);
    let mut refused = 0;
    for n in 0..120 {
        let text = m.mutate(BASE);
        std::fs::write(&file, &text).unwrap();
        let o = rsasim(&["validate", file.to_str().unwrap()], &[]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        let context = format!("mutation {n}:\n{text}\n--- stderr:\n{stderr}");
        match o.status.code() {
            Some(0) => assert!(stderr.contains(": valid: "), "{context}"),
            Some(2) => {
                refused += 1;
                for line in stderr.lines().filter(|l| l.starts_with("error: ")) {
                    assert!(line.contains("m.toml:"), "unlocated error in {context}");
                }
                assert!(stderr.len() < 8_000, "{} bytes: {context}", stderr.len());
            }
            code => panic!("exit {code:?} in {context}"),
        }
    }
    // The mutations reach both outcomes.
    assert!((20..100).contains(&refused), "{refused} of 120 refused");
}
