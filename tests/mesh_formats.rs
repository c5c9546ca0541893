//! Every shipped mesh format runs the whole chain: simulate → validate the output's own
//! scenario.toml → reconstruct → evaluate. The output stands alone: every file of `phantoms/`
//! is in the manifest, the mesh of a glTF that references files is repacked as one `.glb`, and
//! evaluate's tables include the model.

use crate::common;

use std::path::Path;

use base64::Engine as _;
use common::{hashes, root, rsasim};

/// The femoral component in every format, written into `dir`; returns (file name, the name of
/// its copy in the output's phantoms/).
fn write_formats(dir: &Path) -> Vec<(&'static str, &'static str)> {
    let glb_path = root().join("scenarios/models/femoral_component.glb");
    let glb = std::fs::read(&glb_path).unwrap();
    std::fs::write(dir.join("femur.glb"), &glb).unwrap();
    let parsed = gltf::binary::Glb::from_slice(&glb).unwrap();
    let bin = parsed.bin.unwrap().into_owned();
    let mut json: serde_json::Value = serde_json::from_slice(&parsed.json).unwrap();
    json["buffers"][0]["uri"] = serde_json::json!("femur%20data.bin");
    std::fs::write(
        dir.join("separate.gltf"),
        serde_json::to_vec(&json).unwrap(),
    )
    .unwrap();
    std::fs::write(dir.join("femur data.bin"), &bin).unwrap();
    json["buffers"][0]["uri"] = serde_json::json!(format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    ));
    std::fs::write(
        dir.join("embedded.gltf"),
        serde_json::to_vec(&json).unwrap(),
    )
    .unwrap();

    let mesh = rsasim::phantom::mesh_io::load_mesh(&glb_path, 1000.0).unwrap();
    rsasim::phantom::mesh_io::write_stl(
        &mesh,
        std::fs::File::create(dir.join("binary.stl")).unwrap(),
    )
    .unwrap();
    let mut ascii = String::from("solid femur\n");
    for t in &mesh.triangles {
        ascii += "facet normal 0 0 0\nouter loop\n";
        for &i in t {
            let [x, y, z] = mesh.vertices[i as usize];
            ascii += &format!("vertex {x} {y} {z}\n");
        }
        ascii += "endloop\nendfacet\n";
    }
    ascii += "endsolid femur\n";
    std::fs::write(dir.join("ascii.stl"), ascii).unwrap();
    vec![
        ("femur.glb", "femur.glb"),
        ("embedded.gltf", "femur.gltf"),
        ("separate.gltf", "femur.glb"),
        ("binary.stl", "femur.stl"),
        ("ascii.stl", "femur.stl"),
    ]
}

/// tests/scenarios/reconstruct.toml with one noise level, two runs and the given mesh file.
fn scenario(mesh: &str) -> String {
    let text = std::fs::read_to_string(root().join("tests/scenarios/reconstruct.toml")).unwrap();
    let unit = if mesh.ends_with(".stl") {
        "\nunit_mm = 1.0"
    } else {
        ""
    };
    let out = text
        .replace("noise_levels = [0.0, 0.9]", "noise_levels = [0.0]")
        .replace("runs_per_level = 3", "runs_per_level = 2")
        .replace(
            r#"file = "../../scenarios/models/femoral_component.glb""#,
            &format!("file = \"models/{mesh}\"{unit}"),
        );
    assert!(out.contains(mesh) && out.contains("runs_per_level = 2"));
    out
}

#[test]
fn every_mesh_format_runs_simulate_validate_reconstruct_evaluate() {
    let tmp = tempfile::tempdir().unwrap();
    let models = tmp.path().join("models");
    std::fs::create_dir(&models).unwrap();
    for (file, copied) in write_formats(&models) {
        let scn = tmp.path().join(format!("{file}.toml"));
        std::fs::write(&scn, scenario(file)).unwrap();
        let out = tmp.path().join(format!("out-{file}"));
        let o = rsasim(
            &[scn.to_str().unwrap(), "--out", out.to_str().unwrap()],
            &[],
        );
        assert!(
            o.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&o.stderr)
        );

        // The manifest lists every file of phantoms/, and phantoms/ holds one mesh file.
        let manifest: rsasim::output::Manifest =
            serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
        let on_disk: Vec<(String, String)> = hashes(&out)
            .into_iter()
            .filter(|(p, _)| p.starts_with("phantoms/"))
            .collect();
        for (path, sha) in &on_disk {
            assert!(
                manifest
                    .files
                    .iter()
                    .any(|f| &f.path == path && &f.sha256 == sha),
                "{file}: {path} is not in the manifest"
            );
        }
        let meshes: Vec<&String> = on_disk
            .iter()
            .map(|(p, _)| p)
            .filter(|p| !p.ends_with(".csv"))
            .collect();
        assert_eq!(meshes, [&format!("phantoms/{copied}")], "{file}");
        if file == "femur.glb" {
            assert_eq!(
                std::fs::read(out.join("phantoms/femur.glb")).unwrap(),
                std::fs::read(models.join(file)).unwrap(),
                "a .glb is copied byte for byte"
            );
        }

        // The output stands alone: its scenario validates with nothing allowed beyond it.
        let own = out.join("scenario.toml");
        let o = rsasim(&["validate", own.to_str().unwrap()], &[]);
        assert!(
            o.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&o.stderr)
        );

        let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
        assert!(
            o.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let o = rsasim(
            &["evaluate", out.to_str().unwrap(), "--format", "md,csv"],
            &[],
        );
        assert!(
            o.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let report = std::fs::read_to_string(common::report_dir(&out).join("report.md")).unwrap();
        assert!(
            report.contains("femur"),
            "{file}: the model is missing from the report"
        );
        assert!(report.contains("MTPM"), "{file}: no MTPM table");
    }
}
