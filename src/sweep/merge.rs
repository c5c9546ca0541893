//! Merging a sharded sweep (`rsasim sweep FILE --out DIR --merge`): the shards of every point
//! (`DIR/shards/<id>/shard-K-of-N/`, written by the tasks of `rsasim sweep FILE --shard K/N`)
//! checked by [`crate::output::merge::check`], each error naming its point, before anything is
//! written; then each point's shards joined into `DIR/<id>/` as `rsasim merge` joins them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::folder::SweepFolder;
use super::prepare::Sweep;
use crate::diagnostic::Diagnostic;
use crate::output::merge::{self, Shards};
use crate::shard::ShardSpec;

/// One point to merge: its id and its checked shards.
pub struct PointShards {
    /// `p00`, `p01`, …
    pub id: String,
    /// The point's output folder, `DIR/<id>`.
    pub out: PathBuf,
    /// The checked shards.
    pub shards: Shards,
}

/// The shard folders in `holder` (a point's `shards/<id>/`) grouped by their number of shards N,
/// in shard order; hidden entries (locks, staging folders) and other names are not shards.
fn shard_folders(holder: &Path) -> std::io::Result<BTreeMap<usize, Vec<PathBuf>>> {
    let mut by_count: BTreeMap<usize, Vec<(usize, PathBuf)>> = BTreeMap::new();
    for entry in std::fs::read_dir(holder)? {
        let entry = entry?;
        let name = entry.file_name();
        if let Some(spec) = name.to_str().and_then(ShardSpec::from_folder_name) {
            by_count
                .entry(spec.count)
                .or_default()
                .push((spec.index, entry.path()));
        }
    }
    Ok(by_count
        .into_iter()
        .map(|(n, mut dirs)| {
            dirs.sort();
            (n, dirs.into_iter().map(|(_, d)| d).collect())
        })
        .collect())
}

/// A diagnostic said of point `index` (`point p01 (key = value): …`), its help (written for
/// `rsasim merge`) naming the point's scenario and shard folder.
fn of_point(sweep: &Sweep, folder: &SweepFolder, index: usize, d: Diagnostic) -> Diagnostic {
    let point = &sweep.points[index];
    let help = d.help.map(|h| {
        format!(
            "{h} (SCENARIO is {}, the shards' --out {}; or rerun the sweep's tasks: a finished one writes nothing)",
            folder.point_scenario(&point.id).display(),
            folder.point_shards(&point.id).display()
        )
    });
    Diagnostic {
        message: format!(
            "point {} ({}): {}",
            point.id,
            sweep.assignments(point),
            d.message
        ),
        help,
        ..d
    }
}

/// Finds and checks the shards of every point of `folder` not already complete there: the split
/// into `count` shards (`--shard-count`), or the only split found in the point's shard folder.
/// All points are checked, and every problem is returned (with the point it concerns): a point
/// without shards, two splits without `--shard-count`, and every check of `rsasim merge` (a
/// missing shard names the point and its runs), and shards of another scenario than the point's.
pub fn check(
    sweep: &Sweep,
    folder: &SweepFolder,
    count: Option<usize>,
) -> Result<Vec<PointShards>, Vec<Diagnostic>> {
    let mut errors = Vec::new();
    let mut points = Vec::new();
    let run_help = "run every task of the sharded sweep first (rsasim sweep FILE --out DIR --shard K/N, K = 0 … N − 1), then merge";
    for (i, (point, done)) in sweep.points.iter().zip(&folder.done).enumerate() {
        if *done {
            continue;
        }
        let holder = folder.point_shards(&point.id);
        let fail = |message: String, help: &str| Diagnostic {
            help: Some(help.to_string()),
            ..of_point(sweep, folder, i, Diagnostic::file_error(&holder, message))
        };
        let found = match shard_folders(&holder) {
            Ok(found) => found,
            Err(e) => {
                let why = if e.kind() == std::io::ErrorKind::NotFound {
                    "the folder does not exist".to_string()
                } else {
                    format!("the folder cannot be read: {e}")
                };
                errors.push(fail(format!("no shards to merge: {why}"), run_help));
                continue;
            }
        };
        let dirs = match (count, found.len()) {
            (Some(n), _) => match found.get(&n) {
                Some(dirs) => dirs.clone(),
                None => {
                    errors.push(fail(
                        format!("no shard folder shard-K-of-{n} (--shard-count {n})"),
                        run_help,
                    ));
                    continue;
                }
            },
            (None, 0) => {
                errors.push(fail("no shard folder shard-K-of-N".into(), run_help));
                continue;
            }
            (None, 1) => found.into_values().next().unwrap_or_default(),
            (None, _) => {
                let splits: Vec<String> = found.keys().map(|n| format!("N = {n}")).collect();
                errors.push(fail(
                    format!(
                        "it holds the shards of {} splits ({})",
                        splits.len(),
                        splits.join(", ")
                    ),
                    "say which to merge with --shard-count N",
                ));
                continue;
            }
        };
        match merge::check(&dirs) {
            Ok(shards) if shards.scenario_sha256() != Some(point.sha256.as_str()) => {
                errors.push(fail(
                    format!(
                        "the shards were written from another scenario (SHA-256 {}) than points/{}.toml ({})",
                        shards.scenario_sha256().unwrap_or("none"),
                        point.id,
                        point.sha256
                    ),
                    "rerun the sharded sweep's tasks into this folder with this sweep file",
                ));
            }
            Ok(shards) => points.push(PointShards {
                id: point.id.clone(),
                out: folder.point_out(&point.id),
                shards,
            }),
            Err(e) => errors.extend(e.into_iter().map(|d| of_point(sweep, folder, i, d))),
        }
    }
    if errors.is_empty() {
        Ok(points)
    } else {
        Err(errors)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_folders_are_found_by_split_in_shard_order() {
        let tmp = tempfile::tempdir().unwrap();
        for name in [
            "shard-1-of-2",
            "shard-0-of-2",
            "shard-10-of-12",
            "shard-02-of-12",
            ".shard-0-of-2.rsasim-lock",
            "shard-2-of-12",
            "notes",
        ] {
            std::fs::create_dir(tmp.path().join(name)).unwrap();
        }
        let found = shard_folders(tmp.path()).unwrap();
        let names = |n: usize| -> Vec<String> {
            found[&n]
                .iter()
                .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
                .collect()
        };
        assert_eq!(found.len(), 2);
        assert_eq!(names(2), ["shard-0-of-2", "shard-1-of-2"]);
        assert_eq!(names(12), ["shard-02-of-12", "shard-10-of-12"]);
    }
}
