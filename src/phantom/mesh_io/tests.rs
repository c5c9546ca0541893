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
