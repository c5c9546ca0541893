//! Tests of mesh reading and writing; fixtures are written into temporary folders.

use super::*;
use base64::Engine as _;
use std::path::PathBuf;

/// A unit tetrahedron (file units), outward-wound.
const TETRA_POS: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
];
const TETRA_IDX: [u16; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];

/// The tetrahedron's buffer: 48 bytes of positions, then 24 bytes of u16 indices.
fn tetra_bin() -> Vec<u8> {
    let mut bin = Vec::new();
    for p in TETRA_POS {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in TETRA_IDX {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin
}

/// A .gltf document for the tetrahedron with the given buffer URI, primitive mode and nodes JSON
/// (node 0 is the scene's root).
fn tetra_gltf(uri: &str, mode: u32, nodes: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
        "meshes":[{{"name":"x","primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"mode":{mode}}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,1,1]}},
                     {{"bufferView":1,"componentType":5123,"count":12,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":24}}],
        "buffers":[{{"byteLength":72,"uri":"{uri}"}}]}}"#
    )
}

fn data_uri() -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(tetra_bin())
    )
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn default_units_are_metres_for_gltf_and_mm_for_stl() {
    assert_eq!(default_unit_mm(Path::new("a/b.GLB")), 1000.0);
    assert_eq!(default_unit_mm(Path::new("b.gltf")), 1000.0);
    assert_eq!(default_unit_mm(Path::new("b.stl")), 1.0);
}

#[test]
fn glb_round_trip_reproduces_the_mesh_in_mm() {
    let mesh = TriMesh::uv_sphere(12.5, 12, 24);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.glb");
    write_glb(&mesh, std::fs::File::create(&path).unwrap()).unwrap();
    let back = load_mesh(&path, default_unit_mm(&path)).unwrap();
    assert_eq!(back.triangles, mesh.triangles);
    assert_eq!(back.vertices.len(), mesh.vertices.len());
    for (a, b) in back.vertices.iter().zip(&mesh.vertices) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-4, "{a:?} vs {b:?}");
        }
    }
    back.check_closed().unwrap();
}

#[test]
fn glb_bytes_are_deterministic_aligned_and_in_metres() {
    let mesh = TriMesh::uv_sphere(10.0, 6, 8);
    let a = glb_bytes(&mesh).unwrap();
    assert_eq!(a, glb_bytes(&mesh).unwrap());
    assert_eq!(a.len() % 4, 0);
    assert_eq!(
        u32::from_le_bytes(a[8..12].try_into().unwrap()) as usize,
        a.len()
    );
    let json_len = u32::from_le_bytes(a[12..16].try_into().unwrap()) as usize;
    assert_eq!(json_len % 4, 0);
    let glb = gltf::binary::Glb::from_slice(&a).unwrap();
    let doc: serde_json::Value = serde_json::from_slice(&glb.json).unwrap();
    let max = doc["accessors"][0]["max"].as_array().unwrap();
    assert!(
        (max[0].as_f64().unwrap() - 0.010).abs() < 1e-6,
        "POSITION max must be in metres: {max:?}"
    );
    assert_eq!(doc["scenes"].as_array().unwrap().len(), 1);
    assert_eq!(doc["nodes"].as_array().unwrap().len(), 1);
}

#[test]
fn gltf_with_a_data_uri_loads() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "tetra.gltf",
        tetra_gltf(&data_uri(), 4, r#"[{"mesh":0}]"#),
    );
    let mesh = load_mesh(&path, 10.0).unwrap();
    mesh.check_closed().unwrap();
    assert_eq!(mesh.triangles.len(), 4);
    assert!((mesh.signed_volume_mm3() - 1000.0 / 6.0).abs() < 1e-3);
}

#[test]
fn gltf_with_an_external_bin_loads_and_a_missing_one_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "tetra data.bin", tetra_bin());
    let path = write(
        dir.path(),
        "tetra.gltf",
        tetra_gltf("tetra%20data.bin", 4, r#"[{"mesh":0}]"#),
    );
    let mesh = load_mesh(&path, 1.0).unwrap();
    mesh.check_closed().unwrap();
    assert_eq!(mesh.vertices.len(), 4);

    let path = write(
        dir.path(),
        "lost.gltf",
        tetra_gltf("missing.bin", 4, r#"[{"mesh":0}]"#),
    );
    let err = load_mesh(&path, 1.0).unwrap_err();
    assert!(
        err.contains("missing.bin")
            && err.contains("relative to the glTF file")
            && err.contains("does not exist"),
        "{err}"
    );
}

#[test]
fn node_transforms_compose_parent_times_child() {
    let dir = tempfile::tempdir().unwrap();
    // Parent scales by 2, child translates by (0, 1, 0): world = 2 · (p + (0, 1, 0)).
    let nodes = r#"[{"scale":[2,2,2],"children":[1]},{"translation":[0,1,0],"mesh":0}]"#;
    let path = write(dir.path(), "moved.gltf", tetra_gltf(&data_uri(), 4, nodes));
    let mesh = load_mesh(&path, 1.0).unwrap();
    let (lo, hi) = mesh.bounds_mm();
    assert_eq!(lo.to_array(), [0.0, 2.0, 0.0]);
    assert_eq!(hi.to_array(), [2.0, 4.0, 2.0]);
    assert!(mesh.signed_volume_mm3() > 0.0);
}

#[test]
fn a_mirroring_node_keeps_normals_outward() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "mirror.gltf",
        tetra_gltf(&data_uri(), 4, r#"[{"scale":[-1,1,1],"mesh":0}]"#),
    );
    let mesh = load_mesh(&path, 1.0).unwrap();
    assert_eq!(mesh.bounds_mm().0.x, -1.0);
    assert!(mesh.signed_volume_mm3() > 0.0);
}

#[test]
fn stl_round_trip_binary_and_ascii() {
    let mesh = TriMesh::uv_sphere(7.0, 10, 20);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.stl");
    write_stl(&mesh, std::fs::File::create(&path).unwrap()).unwrap();
    let back = load_mesh(&path, default_unit_mm(&path)).unwrap();
    back.check_closed().unwrap();
    assert_eq!(back.triangles.len(), mesh.triangles.len());
    assert_eq!(back.vertices.len(), mesh.vertices.len());
    assert!(
        (back.signed_volume_mm3() - mesh.signed_volume_mm3()).abs()
            < 1e-6 * mesh.signed_volume_mm3()
    );

    let mut ascii = String::from("solid tetra\n");
    for t in TETRA_IDX.chunks(3) {
        ascii += "facet normal 0 0 0\nouter loop\n";
        for &i in t {
            let p = TETRA_POS[i as usize];
            ascii += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
        }
        ascii += "endloop\nendfacet\n";
    }
    ascii += "endsolid tetra\n";
    let path = write(dir.path(), "tetra.stl", ascii);
    let tetra = load_mesh(&path, 2.0).unwrap();
    tetra.check_closed().unwrap();
    assert!((tetra.signed_volume_mm3() - 8.0 / 6.0).abs() < 1e-6);
}

#[test]
fn unsupported_inputs_are_refused_with_the_valid_choices() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "lines.gltf",
        tetra_gltf(&data_uri(), 3, r#"[{"mesh":0}]"#),
    );
    let err = load_mesh(&path, 1.0).unwrap_err();
    assert!(
        err.contains("primitive 0 of mesh `x` (node 0) uses mode LineStrip: only triangle lists"),
        "{err}"
    );

    let path = write(dir.path(), "model.obj", "v 0 0 0\n");
    let err = load_mesh(&path, 1.0).unwrap_err();
    assert!(
        err.contains("unsupported extension `.obj`: use .glb, .gltf or .stl"),
        "{err}"
    );

    let path = write(dir.path(), "broken.glb", b"glTF\x02\0\0\0");
    assert!(
        load_mesh(&path, 1000.0)
            .unwrap_err()
            .contains("not a valid glTF 2.0 file")
    );
    assert!(
        load_mesh(&dir.path().join("absent.stl"), 1.0)
            .unwrap_err()
            .contains("does not exist")
    );
    assert!(load_mesh(&path, 0.0).unwrap_err().contains("positive"));
}

/// A tetrahedron with one vertex replaced, in mm (for writers).
fn tetra_mesh_with(vertex: [f32; 3]) -> TriMesh {
    let mut vertices: Vec<[f32; 3]> = TETRA_POS.iter().map(|p| p.map(|c| c * 10.0)).collect();
    vertices[3] = vertex;
    TriMesh {
        vertices,
        triangles: TETRA_IDX
            .chunks(3)
            .map(|t| [t[0] as u32, t[1] as u32, t[2] as u32])
            .collect(),
    }
}

/// A folder `scn/` for the mesh and, beside it, `outside.bin`: a valid tetrahedron buffer whose
/// first index bytes spell `in:/` (as /etc/passwd's do), to catch any echo of its contents.
fn scenario_folder() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let scn = dir.path().join("scn");
    std::fs::create_dir(&scn).unwrap();
    let mut outside = tetra_bin();
    outside[48..52].copy_from_slice(b"in:/");
    std::fs::write(dir.path().join("outside.bin"), outside).unwrap();
    (dir, scn)
}

fn confined(scn: &Path) -> Confinement {
    Confinement::new(scn, &[]).unwrap()
}

#[test]
fn buffer_uris_outside_the_folder_are_refused_unread() {
    let (dir, scn) = scenario_folder();
    let outside = dir.path().join("outside.bin");
    for uri in [
        "../outside.bin".to_string(),
        "%2e%2e/outside.bin".to_string(),
        "..%2Foutside.bin".to_string(),
        outside.to_string_lossy().into_owned(),
        "../../../../../../../../etc/passwd".into(),
        "/etc/passwd".into(),
        "/proc/self/environ".into(),
        "/dev/zero".into(),
    ] {
        let path = write(&scn, "t.gltf", tetra_gltf(&uri, 4, r#"[{"mesh":0}]"#));
        let start = std::time::Instant::now();
        let err = load_mesh_in(&path, 1.0, &confined(&scn)).unwrap_err();
        assert!(start.elapsed().as_secs() < 5, "{uri}: slow");
        assert!(err.contains("buffer 0"), "{uri}: {err}");
        assert!(
            err.contains("outside the folders") || err.contains("system file"),
            "{uri}: {err}"
        );
        // 792358505 = the bytes `in:/` read as a little-endian u32.
        assert!(
            !err.contains("792358505") && !err.contains("in:/") && !err.contains("root:"),
            "{uri}: {err}"
        );
    }
    // The same buffer is used once its folder is allowed explicitly.
    let path = write(
        &scn,
        "t.gltf",
        tetra_gltf("../outside.bin", 4, r#"[{"mesh":0}]"#),
    );
    let allowed = Confinement::new(&scn, &[dir.path().to_path_buf()]).unwrap();
    let err = load_mesh_in(&path, 1.0, &allowed).unwrap_err();
    assert!(
        err.contains("index 0") && !err.contains("792358505"),
        "{err}"
    );
}

#[test]
fn a_mesh_file_outside_or_a_device_is_refused() {
    let (dir, scn) = scenario_folder();
    let stl = dir.path().join("out.stl");
    write_stl(
        &tetra_mesh_with([0.0, 0.0, 10.0]),
        std::fs::File::create(&stl).unwrap(),
    )
    .unwrap();
    let err = load_mesh_in(&scn.join("../out.stl"), 1.0, &confined(&scn)).unwrap_err();
    assert!(err.contains("outside the folders"), "{err}");
    std::os::unix::fs::symlink("/dev/zero", scn.join("zero.stl")).unwrap();
    let err = load_mesh_in(&scn.join("zero.stl"), 1.0, &confined(&scn)).unwrap_err();
    assert!(
        err.contains("system file") && !err.contains("does not exist"),
        "{err}"
    );
}

#[test]
fn gltf_with_an_external_bin_is_repacked_exactly_into_one_glb() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "tetra data.bin", tetra_bin());
    let nodes = r#"[{"scale":[2,2,2],"children":[1]},{"translation":[0,1,0],"mesh":0}]"#;
    let path = write(
        dir.path(),
        "t.gltf",
        tetra_gltf("tetra%20data.bin", 4, nodes),
    );
    let read = load_mesh_in(&path, 10.0, &confined(dir.path())).unwrap();
    assert_eq!(read.package.extension, "glb");
    let glb = write(dir.path(), "t.glb", &*read.package.bytes);
    std::fs::remove_file(dir.path().join("tetra data.bin")).unwrap();
    let again = load_mesh_in(&glb, 10.0, &confined(dir.path())).unwrap();
    assert_eq!(again.mesh, read.mesh);
    assert_eq!(again.package.extension, "glb");
    assert_eq!(
        *again.package.bytes, *read.package.bytes,
        "a .glb is a byte copy"
    );
    let doc = gltf::Gltf::from_slice(&read.package.bytes).unwrap();
    assert!(
        doc.document
            .buffers()
            .all(|b| matches!(b.source(), gltf::buffer::Source::Bin))
    );
}

#[test]
fn self_contained_files_are_byte_copies() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = write(
        dir.path(),
        "t.gltf",
        tetra_gltf(&data_uri(), 4, r#"[{"mesh":0}]"#),
    );
    let stl = dir.path().join("t.stl");
    write_stl(
        &tetra_mesh_with([0.0, 0.0, 10.0]),
        std::fs::File::create(&stl).unwrap(),
    )
    .unwrap();
    for (path, ext) in [(gltf, "gltf"), (stl, "stl")] {
        let read = load_mesh_in(&path, 1.0, &confined(dir.path())).unwrap();
        assert_eq!(read.package.extension, ext);
        assert_eq!(*read.package.bytes, std::fs::read(&path).unwrap());
    }
}

#[test]
fn a_nan_vertex_in_stl_or_glb_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let bad = tetra_mesh_with([f32::NAN, 0.0, 10.0]);
    let stl = dir.path().join("nan.stl");
    write_stl(&bad, std::fs::File::create(&stl).unwrap()).unwrap();
    let err = load_mesh(&stl, 1.0).unwrap_err();
    assert!(
        err.contains("of facet") && err.contains("not a finite number"),
        "{err}"
    );
    let glb = write(dir.path(), "nan.glb", glb_bytes(&bad).unwrap());
    let err = load_mesh(&glb, 1000.0).unwrap_err();
    assert!(
        err.contains("vertex 3 of POSITION accessor 0") && err.contains("not a finite number"),
        "{err}"
    );
}

#[test]
fn inconsistent_accessors_are_refused_not_panicking() {
    let dir = tempfile::tempdir().unwrap();
    let base = tetra_gltf(&data_uri(), 4, r#"[{"mesh":0}]"#);
    let pos = r#""componentType":5126,"count":4,"type":"VEC3""#;
    let cases = [
        (
            r#""byteOffset":0,"byteLength":48}"#,
            r#""byteOffset":0,"byteLength":48,"byteStride":4}"#,
            "byteStride 4, smaller than the 12-byte elements",
        ),
        (
            pos,
            r#""componentType":5126,"count":4,"type":"VEC2""#,
            "declared VEC2 of FLOAT",
        ),
        (
            pos,
            r#""componentType":5121,"count":4,"type":"VEC3""#,
            "VEC3 of UNSIGNED_BYTE",
        ),
        (
            pos,
            r#""componentType":5126,"count":40,"type":"VEC3""#,
            "runs beyond the 48 bytes",
        ),
        (
            r#""byteOffset":48,"byteLength":24}"#,
            r#""byteOffset":48,"byteLength":2400}"#,
            "runs beyond the 72 bytes of buffer 0",
        ),
        (
            r#""componentType":5123,"count":12,"type":"SCALAR"}"#,
            r#""componentType":5126,"count":12,"type":"SCALAR"}"#,
            "indices must be SCALAR of UNSIGNED_BYTE",
        ),
        (
            r#""componentType":5123,"count":12,"type":"SCALAR"}"#,
            r#""componentType":5123,"count":12,"type":"SCALAR","sparse":{"count":1,"indices":{"bufferView":1,"componentType":5123},"values":{"bufferView":1}}}"#,
            "sparse accessors are not supported",
        ),
        (r#""mode":4"#, r#""mode":5"#, "only triangle lists"),
    ];
    for (from, to, want) in cases {
        let text = base.replacen(from, to, 1);
        assert_ne!(text, base, "{to}");
        let path = write(dir.path(), "bad.gltf", text);
        let err = load_mesh(&path, 1.0).unwrap_err();
        assert!(err.contains(want), "{to}: {err}");
    }
    // An index beyond the positions: triangle 0 points at vertex 9.
    let mut bin = tetra_bin();
    bin[48..50].copy_from_slice(&9u16.to_le_bytes());
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    let path = write(
        dir.path(),
        "idx.gltf",
        tetra_gltf(&uri, 4, r#"[{"mesh":0}]"#),
    );
    let err = load_mesh(&path, 1.0).unwrap_err();
    // The message after the file's path (a temporary folder's name may hold any digit).
    let said = err
        .strip_prefix(&format!("{}: ", path.display()))
        .unwrap_or(&err);
    assert!(
        said.contains("index 0 (triangle 0) of accessor 1") && !said.contains('9'),
        "{err}"
    );
}

#[test]
fn node_cycles_and_shared_children_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for nodes in [
        r#"[{"children":[1]},{"children":[0],"mesh":0}]"#,
        r#"[{"children":[1,2]},{"children":[2]},{"mesh":0}]"#,
    ] {
        let text = tetra_gltf(&data_uri(), 4, nodes);
        let path = write(dir.path(), "cycle.gltf", text);
        match load_mesh(&path, 1.0) {
            Err(err) => assert!(
                err.contains("reached twice") || err.contains("not a valid glTF"),
                "{err}"
            ),
            Ok(_) => panic!("{nodes} was accepted"),
        }
    }
}

#[test]
fn overflowing_vertices_and_units_name_their_cause() {
    let dir = tempfile::tempdir().unwrap();
    // 3e40 m: beyond f32 in a glTF; as ASCII STL text it parses and is refused by size.
    let ascii = "solid t\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 3e40 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    let path = write(dir.path(), "far.stl", ascii);
    let err = load_mesh(&path, 1.0).unwrap_err();
    assert!(
        err.contains("vertex 1 of facet 0") && err.contains("beyond ±1e6 mm"),
        "{err}"
    );
    let path = write(
        dir.path(),
        "scaled.gltf",
        tetra_gltf(&data_uri(), 4, r#"[{"scale":[1e38,1e38,1e38],"mesh":0}]"#),
    );
    let err = load_mesh(&path, 1000.0).unwrap_err();
    assert!(
        err.contains("after the node transforms") && err.contains("beyond ±1e6 mm"),
        "{err}"
    );
    let path = write(
        dir.path(),
        "t.gltf",
        tetra_gltf(&data_uri(), 4, r#"[{"mesh":0}]"#),
    );
    let err = load_mesh(&path, 1e300).unwrap_err();
    assert!(err.contains("unit_mm = 1e300 is too large"), "{err}");
    for unit in [f64::NAN, f64::INFINITY, -1.0, 0.0] {
        assert!(
            load_mesh(&path, unit)
                .unwrap_err()
                .contains("positive, finite")
        );
    }
}

#[test]
fn an_implausible_size_warns_with_the_likely_unit() {
    let dir = tempfile::tempdir().unwrap();
    // A 70 mm knee stored in metres (0.07) but read with unit_mm = 1.
    let knee = TriMesh::uv_sphere(35.0, 6, 8);
    let glb = write(dir.path(), "knee.glb", glb_bytes(&knee).unwrap());
    let read = load_mesh_in(&glb, 1.0, &confined(dir.path())).unwrap();
    assert_eq!(read.warnings.len(), 1);
    assert!(
        read.warnings[0].contains("set unit_mm = 1000"),
        "{}",
        read.warnings[0]
    );
    let read = load_mesh_in(&glb, 1000.0, &confined(dir.path())).unwrap();
    assert!(read.warnings.is_empty(), "{:?}", read.warnings);
}

#[test]
fn broken_stl_files_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("t.stl");
    write_stl(
        &tetra_mesh_with([0.0, 0.0, 10.0]),
        std::fs::File::create(&stl).unwrap(),
    )
    .unwrap();
    let mut bytes = std::fs::read(&stl).unwrap();
    bytes[80..84].copy_from_slice(&1_000_000u32.to_le_bytes());
    let path = write(dir.path(), "count.stl", &bytes);
    let err = load_mesh(&path, 1.0).unwrap_err();
    assert!(err.contains("declares 1000000 triangles"), "{err}");
    let path = write(
        dir.path(),
        "garbage.stl",
        "solid x\nfacet normal 0 0 0\nouter loop\nvertex a b c\n",
    );
    let err = load_mesh(&path, 1.0).unwrap_err();
    assert!(err.contains("line 4: expected a number"), "{err}");
    let path = write(dir.path(), "tiny.stl", "abc");
    assert!(load_mesh(&path, 1.0).unwrap_err().contains("too short"));
}

#[test]
fn a_glb_header_with_a_short_length_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = glb_bytes(&TriMesh::uv_sphere(10.0, 4, 4)).unwrap();
    bytes[8..12].copy_from_slice(&4u32.to_le_bytes());
    let path = write(dir.path(), "short.glb", &bytes);
    let err = load_mesh(&path, 1000.0).unwrap_err();
    assert!(err.contains("GLB header declares 4 bytes"), "{err}");
}

#[test]
fn a_position_accessor_out_of_range_is_an_error_not_a_panic_in_the_gltf_crate() {
    // Found by tests/mutation.rs (mesh mutant seed 1659): gltf-json's validation indexed the
    // accessor list with POSITION unchecked.
    let dir = tempfile::tempdir().unwrap();
    let text = r#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 7}}]}], "accessors": []}"#;
    let path = write(dir.path(), "oob.gltf", text.to_string());
    let err = load_mesh(&path, 1.0).unwrap_err();
    assert!(
        err.contains("POSITION names accessor 7") && err.contains("0 accessor(s)"),
        "{err}"
    );
}
