//! Plausible magnitudes: every length (`*_mm`) and angle (`*_deg`) in a scenario must be finite
//! and at most [`MAX_ABS`] in size. An RSA room is a few metres across; a value like `1e308` or
//! `1e40` is a typo or a hostile file, and would only overflow later (a ray from a source at
//! −1e308 mm has no finite direction). One rule over the whole document, keyed by the unit in the
//! field's name, so a new field is covered without code.
//! `mesh.unit_mm` is a scale, not a length: the mesh reader judges it by the vertices it scales.

use serde_json::Value;

use super::Scenario;
use crate::diagnostic::{Diagnostic, KeyPath, Locator};

/// The largest magnitude of a length in mm (1 km) or an angle in degrees in a scenario. The
/// same bound holds for mesh vertices and for measured results (`evaluate`).
pub const MAX_ABS: f64 = 1e6;

/// An error for every `*_mm` or `*_deg` number of `scenario` that is not finite or larger than
/// [`MAX_ABS`], located at its key.
pub fn check_magnitudes(scenario: &Scenario, loc: &Locator) -> Vec<Diagnostic> {
    let Ok(value) = serde_json::to_value(scenario) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    walk(&value, &KeyPath::root(), None, loc, &mut out);
    out
}

/// `unit`: the unit of the innermost field name ending in `_mm` or `_deg` above this value.
fn walk(
    value: &Value,
    path: &KeyPath,
    unit: Option<&str>,
    loc: &Locator,
    out: &mut Vec<Diagnostic>,
) {
    match value {
        Value::Object(map) => {
            for (key, v) in map {
                // `unit_mm` is a scale (mm per mesh-file unit), judged with the mesh it scales.
                let unit = if key == "unit_mm" {
                    None
                } else if key.ends_with("_mm") {
                    Some("mm")
                } else if key.ends_with("_deg") {
                    Some("degrees")
                } else {
                    unit
                };
                walk(v, &path.key(key), unit, loc, out);
            }
        }
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                walk(v, &path.index(i), unit, loc, out);
            }
        }
        Value::Number(n) => {
            if let (Some(unit), Some(x)) = (unit, n.as_f64())
                && !(x.is_finite() && x.abs() <= MAX_ABS)
            {
                out.push(
                    loc.error(
                        path.clone(),
                        format!("{x:e} {unit} is not a plausible value"),
                    )
                    .with_help(format!(
                        "lengths and angles must lie within ±{MAX_ABS:e} (1 km, or thousands of turns); check for a typo"
                    )),
                );
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn huge_lengths_and_angles_are_errors_at_their_key() {
        let base = std::fs::read_to_string(
            std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
                .join("tests/mutation/base.toml"),
        )
        .unwrap();
        let text = base
            .replacen(
                "position_mm = [342.0, 0.0, 939.7]",
                "position_mm = [-1e308, 0.0, 939.7]",
                1,
            )
            .replacen(
                "center_mm = [0.0, 0.0, 150.0]",
                "center_mm = [1e40, 0.0, 150.0]",
                1,
            );
        assert_ne!(text, base);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, &text).unwrap();
        let errors = match crate::scenario::load(&path) {
            Err(e) => e,
            Ok(_) => panic!("accepted"),
        };
        let said: Vec<String> = errors.iter().map(|e| e.to_string()).collect();
        assert!(
            said.iter()
                .any(|e| e.contains("sources[1].position_mm[0]") && e.contains("-1e308 mm")),
            "{said:?}"
        );
        assert!(
            said.iter()
                .any(|e| e.contains("center_mm[0]") && e.contains("1e40 mm")),
            "{said:?}"
        );
        // The shipped scenarios stay valid.
        assert!(crate::scenario::load(&dir.path().join("missing.toml")).is_err());
        std::fs::write(&path, &base).unwrap();
        assert!(crate::scenario::load(&path).is_ok());
    }
}
