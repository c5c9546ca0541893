//! Hostile and broken mesh files (issue 17): each gives exit code 2 from `validate` and from a
//! run, names the scenario key (`phantoms[1].mesh.file`, with its line) and the file, quotes no
//! byte of any file it refused, writes nothing, and returns quickly (FIFOs, /dev/zero).

use crate::common;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use base64::Engine as _;
use common::rsasim;
use rsasim::phantom::TriMesh;
use rsasim::phantom::mesh_io::{glb_bytes, write_stl};

/// A scenario with a bead phantom and the mesh phantom `model` (phantoms[1]).
const SCENARIO: &str = r#"name = "hostile"
seed = 1

[protocol]
noise_levels = [0.0]
runs_per_level = 1

[[sources]]
id = "tube1"
position_mm = [0.0, 0.0, 1000.0]

[[detectors]]
id = "det1"
source = "tube1"
pixels = [32, 32]
size_mm = [200.0, 200.0]
bpp = 12
position_mm = [0.0, 0.0, -300.0]

[[phantoms]]
id = "beads"

[[phantoms.beads]]
id = "B1"
position_mm = [30.0, 0.0, 0.0]

[[phantoms]]
id = "model"

[phantoms.mesh]
file = "MESHFILE"
UNIT

[[exposures]]
id = "e"
phantoms = ["beads", "model"]
"#;

/// Content of the file outside the scenario's folder: a valid tetrahedron buffer whose index
/// bytes spell `in:/`, as the bytes of /etc/passwd did in the report.
const SECRET_MARK: &str = "in:/";

const TETRA_POS: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [10.0, 0.0, 0.0],
    [0.0, 10.0, 0.0],
    [0.0, 0.0, 10.0],
];
const TETRA_IDX: [u16; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];

fn tetra_bin() -> Vec<u8> {
    let mut bin = Vec::new();
    for c in TETRA_POS.iter().flatten() {
        bin.extend_from_slice(&c.to_le_bytes());
    }
    for i in TETRA_IDX {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin
}

fn tetra_mesh(last: [f32; 3]) -> TriMesh {
    let mut vertices = TETRA_POS.to_vec();
    vertices[3] = last;
    TriMesh {
        vertices,
        triangles: TETRA_IDX
            .chunks(3)
            .map(|t| [t[0] as u32, t[1] as u32, t[2] as u32])
            .collect(),
    }
}

/// A .gltf of the tetrahedron (mm, so unit_mm = 1) with the given buffer URI, bufferView 0 stride, POSITION type and node scale.
fn gltf(uri: &str, stride: &str, pos_type: &str, scale: &str) -> String {
    let bound = "[0,0,0]";
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0{scale}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"{pos_type}","min":{bound},"max":{bound}}},
                     {{"bufferView":1,"componentType":5123,"count":12,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48{stride}}},{{"buffer":0,"byteOffset":48,"byteLength":24}}],
        "buffers":[{{"byteLength":72,"uri":"{uri}"}}]}}"#
    )
}

fn data_uri() -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(tetra_bin())
    )
}

/// The test folder: `scn/` for the scenario, `secret.bin` and `secret.stl` beside it.
struct Case {
    _tmp: tempfile::TempDir,
    root: PathBuf,
    scn: PathBuf,
}

impl Case {
    fn new() -> Case {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path().to_path_buf();
        let scn = root.join("scn");
        std::fs::create_dir(&scn).unwrap();
        let mut secret = tetra_bin();
        secret[48..52].copy_from_slice(SECRET_MARK.as_bytes());
        std::fs::write(root.join("secret.bin"), &secret).unwrap();
        write_stl(
            &tetra_mesh([0.0, 0.0, 10.0]),
            std::fs::File::create(root.join("secret.stl")).unwrap(),
        )
        .unwrap();
        Case {
            _tmp: tmp,
            root,
            scn,
        }
    }

    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) {
        std::fs::write(self.scn.join(name), bytes).unwrap();
    }

    /// Runs `validate` and a run on the scenario naming `mesh`, asserting exit 2, the key and
    /// line, the `expected` words, no secret bytes, nothing written, and a quick answer.
    fn refused(&self, what: &str, mesh: &str, unit: &str, expected: &[&str]) {
        let text = SCENARIO.replace("MESHFILE", mesh).replace("UNIT", unit);
        let file = self.scn.join("s.toml");
        std::fs::write(&file, &text).unwrap();
        let line = text.lines().position(|l| l.starts_with("file = ")).unwrap() + 1;
        let out = self.root.join("out");
        for args in [
            vec!["validate", file.to_str().unwrap()],
            vec![file.to_str().unwrap(), "--out", out.to_str().unwrap()],
        ] {
            let start = Instant::now();
            let o = rsasim(&args, &[]);
            let elapsed = start.elapsed();
            let stderr = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{what}: {stderr}");
            assert!(
                elapsed < Duration::from_secs(20),
                "{what}: took {elapsed:?}"
            );
            assert!(
                stderr.contains(&format!("s.toml:{line}:"))
                    && stderr.contains("`phantoms[1].mesh.file`"),
                "{what}: no key and line in {stderr}"
            );
            for word in expected {
                assert!(
                    stderr.contains(word),
                    "{what}: `{word}` missing from {stderr}"
                );
            }
            for secret in [SECRET_MARK, "792358505", "root:", "PATH="] {
                assert!(
                    !stderr.contains(secret),
                    "{what}: echoes `{secret}`: {stderr}"
                );
            }
            assert!(!stderr.contains("panicked"), "{what}: {stderr}");
            assert!(
                !out.exists() && !self.root.join("out.partial").exists(),
                "{what}: wrote"
            );
        }
    }
}

#[test]
fn buffer_uris_outside_the_folder_are_refused_unread() {
    let case = Case::new();
    let secret = case.root.join("secret.bin");
    for uri in [
        "../secret.bin".to_string(),
        "%2e%2e/secret.bin".to_string(),
        "..%2fsecret.bin".to_string(),
        secret.to_string_lossy().into_owned(),
        "../../../../../../../../etc/passwd".into(),
        "/etc/passwd".into(),
        "/proc/self/environ".into(),
        "/dev/zero".into(),
        format!("{}/x.bin", "a".repeat(5000)),
    ] {
        case.write("m.gltf", gltf(&uri, "", "VEC3", ""));
        let shown: String = uri.chars().take(60).collect();
        case.refused(
            &format!("buffer {shown}"),
            "m.gltf",
            "unit_mm = 1.0",
            &["buffer 0", "m.gltf"],
        );
    }
}

#[test]
fn mesh_files_outside_devices_fifos_and_folders_are_refused() {
    let case = Case::new();
    std::os::unix::fs::symlink(case.root.join("secret.stl"), case.scn.join("link.stl")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", case.scn.join("zero.stl")).unwrap();
    std::fs::create_dir(case.scn.join("dir.stl")).unwrap();
    let fifo = case.scn.join("pipe.stl");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    for (mesh, expected) in [
        ("../secret.stl", "outside the folders"),
        ("link.stl", "outside the folders"),
        ("/dev/zero", "system file"),
        ("zero.stl", "system file"),
        ("/proc/self/environ", "system file"),
        ("pipe.stl", "FIFO"),
        ("dir.stl", "folder, not a regular file"),
        ("absent.stl", "does not exist"),
    ] {
        case.refused(mesh, mesh, "", &[expected]);
    }
    // Allowed explicitly, the folder's file is read.
    let text = SCENARIO
        .replace("MESHFILE", "../secret.stl")
        .replace("UNIT", "");
    let file = case.scn.join("ok.toml");
    std::fs::write(&file, text).unwrap();
    let o = rsasim(
        &[
            "validate",
            file.to_str().unwrap(),
            "--allow-dir",
            case.root.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn broken_meshes_are_refused_before_anything_is_written() {
    let case = Case::new();
    let nan = tetra_mesh([f32::NAN, 0.0, 10.0]);
    write_stl(
        &nan,
        std::fs::File::create(case.scn.join("nan.stl")).unwrap(),
    )
    .unwrap();
    case.write("nan.glb", glb_bytes(&nan).unwrap());
    case.write(
        "stride.gltf",
        gltf(&data_uri(), r#","byteStride":4"#, "VEC3", ""),
    );
    case.write("vec2.gltf", gltf(&data_uri(), "", "VEC2", ""));
    case.write(
        "scale.gltf",
        gltf(&data_uri(), "", "VEC3", r#","scale":[1e38,1e38,1e38]"#),
    );
    case.write("ok.gltf", gltf(&data_uri(), "", "VEC3", ""));
    case.write(
        "far.stl",
        "solid t\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 3e43 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n",
    );
    let mut count = std::fs::read(case.scn.join("nan.stl")).unwrap();
    count[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    case.write("count.stl", &count);
    case.write(
        "garbage.stl",
        "solid x\nfacet normal 0 0 0\nouter loop\nvertex 1 2 x\n",
    );
    for (mesh, unit, expected) in [
        ("nan.stl", "", "not a finite number"),
        ("nan.glb", "", "not a finite number"),
        ("stride.gltf", "unit_mm = 1.0", "byteStride 4"),
        ("vec2.gltf", "unit_mm = 1.0", "declared VEC2"),
        ("scale.gltf", "", "beyond ±1e6 mm"),
        ("ok.gltf", "unit_mm = 1e300", "unit_mm = 1e300 is too large"),
        ("far.stl", "", "beyond ±1e6 mm"),
        ("count.stl", "", "declares 4294967295 triangles"),
        ("garbage.stl", "", "line 4: expected a number"),
    ] {
        case.refused(mesh, mesh, unit, &[expected, mesh]);
    }
}

#[test]
fn a_gltf_in_metres_read_as_mm_warns_with_the_unit() {
    let case = Case::new();
    // The tetrahedron is 10 file units across: with unit_mm = 0.01 it would be 0.1 mm.
    case.write("ok.gltf", gltf(&data_uri(), "", "VEC3", ""));
    let text = SCENARIO
        .replace("MESHFILE", "ok.gltf")
        .replace("UNIT", "unit_mm = 0.01");
    let file = case.scn.join("s.toml");
    std::fs::write(&file, text).unwrap();
    let o = rsasim(&["validate", file.to_str().unwrap()], &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("warning") && stderr.contains("set unit_mm = "),
        "{stderr}"
    );
    assert!(stderr.contains("`phantoms[1].mesh.unit_mm`"), "{stderr}");
}

#[test]
fn reconstruct_reads_meshes_only_inside_the_output_folder() {
    let case = Case::new();
    // A tampered output folder whose scenario.toml points its model outside the folder.
    let out = case.scn.join("out");
    std::fs::create_dir_all(out.join("runs")).unwrap();
    std::fs::write(out.join("manifest.json"), "{}").unwrap();
    let text = SCENARIO
        .replace("MESHFILE", "../../secret.stl")
        .replace("UNIT", "");
    std::fs::write(out.join("scenario.toml"), text).unwrap();
    let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("outside the folders") && stderr.contains("`phantoms[1].mesh.file`"),
        "{stderr}"
    );
}
