//! The checked-in JSON Schemas are the ones the code generates; regenerate them with
//! `cargo run -- schema --write-dir schemas` after changing a record.

use crate::common;

use common::{root, rsasim};

#[test]
fn checked_in_schemas_are_current() {
    for (name, schema) in rsasim::output::schemas() {
        let path = root().join("schemas").join(format!("{name}.schema.json"));
        let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
        let current = serde_json::to_string_pretty(&schema).unwrap() + "\n";
        assert!(
            on_disk == current,
            "{} is stale: run `cargo run -- schema --write-dir schemas` and commit it",
            path.display()
        );
    }
}

#[test]
fn the_scenario_schema_rejects_unknown_keys_and_documents_defaults() {
    let schema = rsasim::scenario::json_schema();
    assert_eq!(schema["additionalProperties"], false);
    let protocol = &schema["$defs"]["Protocol"]["properties"];
    assert_eq!(protocol["runs_per_level"]["default"], 20);
    assert!(
        protocol["noise_levels"]["description"]
            .as_str()
            .unwrap()
            .contains("0.225")
    );
}

#[test]
fn shipped_scenarios_point_editors_at_the_schema() {
    for file in ["scenarios/biplanar.toml", "scenarios/uniplanar.toml"] {
        let text = std::fs::read_to_string(root().join(file)).unwrap();
        assert!(
            text.starts_with("#:schema ../schemas/scenario.schema.json"),
            "{file}"
        );
    }
}

#[test]
fn schema_and_expand_commands_print_json() {
    let o = rsasim(&["schema", "truth"], &[]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["properties"]["images"].is_object());
    let o = rsasim(
        &[
            "expand",
            "scenarios/golden/small_biplanar.toml",
            "--allow-dir",
            "scenarios/models",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let runs: Vec<rsasim::expand::Run> = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(runs.len(), 4);
    assert_eq!(runs[3].id, "n1-r01");
    assert_eq!(runs[3].geometry_stream, "rsasim/geometry/v1/42/1/1");
}
