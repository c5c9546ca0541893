//! Expansion of a sweep into points: which value of every parameter each point takes (grid or
//! zip, in a stable order), the point ids, and setting a value at a key path of a scenario.

use crate::diagnostic::KeyPath;

use super::file::{Combine, SweepRecord};

/// For every point, the index of the value each parameter takes, in the documented order:
/// grid: the cartesian product with the first parameter varying slowest (like nested loops in
/// the order the parameters are written); zip: the i-th value of every parameter (a parameter
/// with one value takes it at every point).
pub fn choices(record: &SweepRecord) -> Vec<Vec<usize>> {
    let lengths: Vec<usize> = record.parameters.iter().map(|p| p.values.len()).collect();
    if lengths.contains(&0) {
        return Vec::new();
    }
    match record.combine {
        Combine::Grid => {
            let count: usize = lengths.iter().product();
            (0..count)
                .map(|mut n| {
                    let mut choice = vec![0; lengths.len()];
                    for (c, &len) in choice.iter_mut().zip(&lengths).rev() {
                        *c = n % len;
                        n /= len;
                    }
                    choice
                })
                .collect()
        }
        Combine::Zip => {
            let count = lengths.iter().copied().max().unwrap_or(0);
            (0..count)
                .map(|i| {
                    lengths
                        .iter()
                        .map(|&len| if len == 1 { 0 } else { i })
                        .collect()
                })
                .collect()
        }
    }
}

/// The id of point `index` of `count`: `p` and the index, zero-padded to at least two digits so
/// that ids sort in point order (`p00` … `p04`, `p000` … `p119`).
pub fn point_id(index: usize, count: usize) -> String {
    let width = count.saturating_sub(1).to_string().len().max(2);
    format!("p{index:0width$}")
}

/// Sets `value` at the dotted `key` of the scenario table `doc`: tables are entered by key
/// (missing ones are created, so a key the base scenario leaves at its default can be swept),
/// an array of tables by the `id` of one of its tables. Returns the key path of the value in
/// the scenario (array indices, as the scenario's diagnostics name them), or what is wrong.
pub fn set_at(doc: &mut toml::Table, key: &str, value: toml::Value) -> Result<KeyPath, String> {
    let segments: Vec<&str> = key.split('.').collect();
    let mut path = KeyPath::root();
    let mut table = doc;
    let mut i = 0;
    while i + 1 < segments.len() {
        let seg = segments[i];
        path = path.key(seg);
        let shown = segments[..=i].join(".");
        let entry = table
            .entry(seg.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let kind = entry.type_str();
        let of_tables = entry
            .as_array()
            .is_some_and(|a| a.iter().all(toml::Value::is_table));
        table = match entry {
            toml::Value::Table(t) => t,
            toml::Value::Array(items) if of_tables => {
                let id = segments[i + 1];
                let ids: Vec<String> = items
                    .iter()
                    .filter_map(|t| t.get("id").and_then(toml::Value::as_str))
                    .map(|s| format!("`{s}`"))
                    .collect();
                let at = items
                    .iter()
                    .position(|t| t.get("id").and_then(toml::Value::as_str) == Some(id))
                    .ok_or_else(|| {
                        format!(
                            "`{shown}` has no table with id `{id}`; its ids are {}",
                            if ids.is_empty() {
                                "none".to_string()
                            } else {
                                ids.join(", ")
                            }
                        )
                    })?;
                path = path.index(at);
                i += 1;
                if i + 1 == segments.len() {
                    return Err(format!(
                        "`{key}` names a whole table of `{shown}`; name one of its keys, e.g. `{key}.position_mm`"
                    ));
                }
                match items.get_mut(at) {
                    Some(toml::Value::Table(t)) => t,
                    _ => return Err(format!("`{shown}` is not an array of tables")),
                }
            }
            _ => {
                return Err(format!(
                    "`{shown}` is a value ({kind}), not a table: sweep `{shown}` itself"
                ));
            }
        };
        i += 1;
    }
    let last = segments[segments.len() - 1];
    table.insert(last.to_string(), value);
    Ok(path.key(last))
}

/// A value as compact TOML text, e.g. `[1300.0, 0.0, 0.0]` or `"deflate"`.
pub fn value_text(value: &toml::Value) -> String {
    value.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::file::ParameterRecord;

    fn record(combine: Combine, lengths: &[usize]) -> SweepRecord {
        SweepRecord {
            name: None,
            scenario: "s.toml".into(),
            combine,
            parameters: lengths
                .iter()
                .enumerate()
                .map(|(i, &n)| ParameterRecord {
                    key: format!("k{i}"),
                    values: (0..n as i64).map(toml::Value::Integer).collect(),
                    name: None,
                    axis: None,
                })
                .collect(),
        }
    }

    #[test]
    fn a_grid_varies_the_first_parameter_slowest() {
        let c = choices(&record(Combine::Grid, &[2, 3]));
        assert_eq!(
            c,
            [[0, 0], [0, 1], [0, 2], [1, 0], [1, 1], [1, 2]].map(|a| a.to_vec())
        );
    }

    #[test]
    fn zip_pairs_values_and_repeats_a_fixed_one() {
        let c = choices(&record(Combine::Zip, &[3, 1, 3]));
        assert_eq!(c, [[0, 0, 0], [1, 0, 1], [2, 0, 2]].map(|a| a.to_vec()));
    }

    #[test]
    fn ids_sort_in_point_order() {
        assert_eq!(point_id(4, 5), "p04");
        assert_eq!(point_id(7, 120), "p007");
        assert_eq!(point_id(0, 1), "p00");
    }

    fn doc() -> toml::Table {
        r#"
seed = 1
[protocol]
runs_per_level = 3
[[sources]]
id = "tube1"
position_mm = [0.0, 0.0, 1300.0]
[[sources]]
id = "tube2"
position_mm = [1300.0, 0.0, 0.0]
[[phantoms]]
id = "box"
[[phantoms.calibration_box.plates]]
id = "F1"
grid = [9, 9]
"#
        .parse()
        .unwrap()
    }

    #[test]
    fn arrays_of_tables_are_entered_by_id() {
        let mut d = doc();
        let path = set_at(
            &mut d,
            "phantoms.box.calibration_box.plates.F1.grid",
            toml::Value::Array(vec![toml::Value::Integer(5), toml::Value::Integer(5)]),
        )
        .unwrap();
        assert_eq!(
            path.to_string(),
            "phantoms[0].calibration_box.plates[0].grid"
        );
        let p = set_at(&mut d, "sources.tube2.position_mm", toml::Value::Integer(7)).unwrap();
        assert_eq!(p.to_string(), "sources[1].position_mm");
        assert_eq!(d["sources"][1]["position_mm"].as_integer(), Some(7));
        assert_eq!(
            d["phantoms"][0]["calibration_box"]["plates"][0]["grid"].to_string(),
            "[5, 5]"
        );
    }

    #[test]
    fn a_missing_table_is_created_and_a_missing_id_listed() {
        let mut d = doc();
        set_at(&mut d, "imaging.focal_spot_mm", toml::Value::Float(0.3)).unwrap();
        assert_eq!(d["imaging"]["focal_spot_mm"].as_float(), Some(0.3));
        let e = set_at(&mut d, "sources.tube3.position_mm", toml::Value::Integer(1)).unwrap_err();
        assert_eq!(
            e,
            "`sources` has no table with id `tube3`; its ids are `tube1`, `tube2`"
        );
        let e = set_at(&mut d, "seed.x", toml::Value::Integer(1)).unwrap_err();
        assert!(e.contains("`seed` is a value (integer)"), "{e}");
        let e = set_at(&mut d, "sources.tube1", toml::Value::Integer(1)).unwrap_err();
        assert!(e.contains("names a whole table"), "{e}");
    }
}
