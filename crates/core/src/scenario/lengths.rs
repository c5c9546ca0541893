//! Strict vector lengths: every array whose length the scenario schema fixes (`position_mm`
//! has 3 numbers, `pixels` 2, …) must have exactly that many elements.
//!
//! serde fills a `[f64; 3]` from the first three elements of a longer array and drops the rest,
//! so `position_mm = [0, 0, 1300, 5]` would silently lose the 5. This check walks the parsed
//! document next to the JSON Schema generated from the records ([`super::json_schema`]), so every
//! fixed-length field — present and future — is covered by the same rule, and each error points
//! at the offending value's line and column.

use serde_json::Value as Schema;
use toml::de::{DeTable, DeValue};

use crate::diagnostic::{Diagnostic, KeyPath, Locator};

/// An error for every array in the document whose length differs from the schema's.
pub fn check_lengths(loc: &Locator) -> Vec<Diagnostic> {
    let Some(doc) = loc.document() else {
        return Vec::new();
    };
    let schema = super::json_schema();
    let mut out = Vec::new();
    walk_table(loc, &schema, doc, &schema, &KeyPath::root(), &mut out);
    out.sort_by_key(|d| d.line_col);
    out
}

/// The schema `s` with `$ref`s followed and an optional value's `anyOf: [X, null]` reduced to X.
fn resolve<'a>(root: &'a Schema, s: &'a Schema) -> &'a Schema {
    if let Some(name) = s
        .get("$ref")
        .and_then(Schema::as_str)
        .and_then(|r| r.strip_prefix("#/$defs/"))
        && let Some(def) = root.get("$defs").and_then(|d| d.get(name))
    {
        return resolve(root, def);
    }
    for key in ["anyOf", "oneOf"] {
        if let Some(alternatives) = s.get(key).and_then(Schema::as_array)
            && let Some(a) = alternatives
                .iter()
                .find(|a| a.get("type").and_then(Schema::as_str) != Some("null"))
        {
            return resolve(root, a);
        }
    }
    s
}

fn walk_table(
    loc: &Locator,
    root: &Schema,
    table: &DeTable,
    schema: &Schema,
    path: &KeyPath,
    out: &mut Vec<Diagnostic>,
) {
    let schema = resolve(root, schema);
    let Some(props) = schema.get("properties") else {
        return;
    };
    for (key, value) in table {
        if let Some(field) = props.get(key.get_ref().as_ref()) {
            walk(
                loc,
                root,
                value.get_ref(),
                field,
                &path.key(key.get_ref()),
                out,
            );
        }
    }
}

fn walk(
    loc: &Locator,
    root: &Schema,
    value: &DeValue,
    schema: &Schema,
    path: &KeyPath,
    out: &mut Vec<Diagnostic>,
) {
    let schema = resolve(root, schema);
    match value {
        DeValue::Table(t) => walk_table(loc, root, t, schema, path, out),
        DeValue::Array(items) => {
            let min = schema.get("minItems").and_then(Schema::as_u64);
            let max = schema.get("maxItems").and_then(Schema::as_u64);
            let n = items.len() as u64;
            if let (Some(min), Some(max)) = (min, max)
                && min == max
                && n != min
            {
                let what = element_words(root, schema);
                out.push(
                    loc.error(
                        path.clone(),
                        format!("expected exactly {min} {what}, got {n}"),
                    )
                    .with_help(format!(
                        "`{}` takes {min} {what}, e.g. {}",
                        last_key(path),
                        example(min)
                    )),
                );
            }
            if let Some(item_schema) = schema.get("items") {
                for (i, item) in items.iter().enumerate() {
                    walk(loc, root, item.get_ref(), item_schema, &path.index(i), out);
                }
            }
        }
        _ => {}
    }
}

/// "numbers" for numeric elements, "elements" otherwise.
fn element_words(root: &Schema, array: &Schema) -> &'static str {
    let item = array.get("items").map(|i| resolve(root, i));
    match item.and_then(|i| i.get("type")).and_then(Schema::as_str) {
        Some("number" | "integer") => "numbers",
        _ => "elements",
    }
}

fn last_key(path: &KeyPath) -> String {
    use crate::diagnostic::Segment;
    match path.0.iter().rev().find(|s| matches!(s, Segment::Key(_))) {
        Some(Segment::Key(k)) => k.clone(),
        _ => path.to_string(),
    }
}

fn example(n: u64) -> &'static str {
    match n {
        2 => "[x, y]",
        3 => "[x, y, z]",
        _ => "[…]",
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn errors(text: &str) -> Vec<String> {
        let loc = Locator::new(Path::new("s.toml"), text);
        check_lengths(&loc).iter().map(|d| d.to_string()).collect()
    }

    #[test]
    fn every_fixed_length_vector_rejects_extra_and_missing_numbers() {
        let text = r#"name = "x"
[[sources]]
id = "s"
position_mm = [0, 0, 1300, 5]
randomize.position_mm = [1, 2]
[[detectors]]
id = "d"
pixels = [10, 10, 10]
size_mm = [1, 2]
[[phantoms]]
id = "p"
[[phantoms.calibration_box.plates]]
omit = [[0, 1], [2, 3, 4]]
grid = [1]
"#;
        let e = errors(text);
        assert_eq!(e.len(), 5, "{e:#?}");
        assert!(
            e[0].contains(
                "s.toml:4:15: `sources[0].position_mm`: expected exactly 3 numbers, got 4"
            ),
            "{}",
            e[0]
        );
        assert!(
            e[1].contains("`sources[0].randomize.position_mm`: expected exactly 3 numbers, got 2"),
            "{}",
            e[1]
        );
        assert!(
            e[2].contains("`detectors[0].pixels`: expected exactly 2 numbers, got 3"),
            "{}",
            e[2]
        );
        assert!(
            e[3].contains(
                "`phantoms[0].calibration_box.plates[0].omit[1]`: expected exactly 2 numbers, got 3"
            ),
            "{}",
            e[3]
        );
        assert!(
            e[4].contains(
                "`phantoms[0].calibration_box.plates[0].grid`: expected exactly 2 numbers, got 1"
            ),
            "{}",
            e[4]
        );
        assert!(e.iter().all(|x| x.contains("help: `")), "{e:#?}");
    }

    #[test]
    fn variable_length_lists_are_not_restricted() {
        assert!(errors("noise = 1\n[protocol]\nnoise_levels = [0.1, 0.2, 0.3, 0.4]\n").is_empty());
    }
}
