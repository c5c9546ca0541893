//! Shards: one scenario's run list split over several machines (SLURM array tasks, Kubernetes
//! Indexed Job pods), each writing only its runs into its own folder, merged afterwards
//! (`rsasim::output::merge`, in the crate above) into the folder one machine would have written.
//!
//! # The split
//!
//! Shards are numbered from 0 to N − 1, as Kubernetes' `JOB_COMPLETION_INDEX` and
//! `sbatch --array=0-(N−1)` number them. The runs of the protocol are taken in the order of
//! [`crate::expand::expand`] (level by level, run by run; position p = 0, 1, …) and dealt out
//! like cards: shard K holds the runs at positions K, K + N, K + 2N, …. Every shard gets
//! ⌊R/N⌋ or ⌈R/N⌉ of the R runs, and since dealing mixes the noise levels, a level that costs
//! more (a higher exposure in attenuation mode) is spread over all shards rather than given to
//! one. With N > R the shards K ≥ R hold no run: they still write their folder (the shared files
//! and a manifest listing no run), so a fixed-size array job needs no special case.

pub mod env;

use std::fmt;

pub use env::{EnvError, ShardRequest};

/// Shard `index` of `count` (0 ≤ index < count).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ShardSpec {
    /// 0-based index K.
    pub index: usize,
    /// Number of shards N (at least 1).
    pub count: usize,
}

impl ShardSpec {
    /// `K/N` with 0 ≤ K < N, else `None`.
    pub fn new(index: usize, count: usize) -> Option<ShardSpec> {
        (count >= 1 && index < count).then_some(ShardSpec { index, count })
    }

    /// The positions in the protocol's run list (0-based) of the runs this shard holds, ascending
    /// (see the module documentation).
    pub fn runs(self, run_count: usize) -> Vec<usize> {
        runs_of_shard(run_count, self)
    }

    /// The name of the shard's folder: `shard-K-of-N`, K padded with zeros to the width of N − 1
    /// so that the folders sort in shard order (`shard-03-of-12`).
    pub fn folder_name(self) -> String {
        let width = (self.count - 1).to_string().len();
        format!("shard-{:0width$}-of-{}", self.index, self.count)
    }
}

impl ShardSpec {
    /// The shard a folder name `shard-K-of-N` names, exactly as [`ShardSpec::folder_name`] writes
    /// it (K padded to the width of N − 1); `None` for any other name.
    pub fn from_folder_name(name: &str) -> Option<ShardSpec> {
        let (k, n) = name.strip_prefix("shard-")?.split_once("-of-")?;
        let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
        if !digits(k) || !digits(n) {
            return None;
        }
        let spec = ShardSpec::new(k.parse().ok()?, n.parse().ok()?)?;
        (spec.folder_name() == name).then_some(spec)
    }
}

impl fmt::Display for ShardSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The positions (0-based, ascending) in a protocol of `run_count` runs of the runs shard `spec`
/// holds: `spec.index`, `spec.index + spec.count`, …; empty when `spec.index ≥ run_count`.
pub fn runs_of_shard(run_count: usize, spec: ShardSpec) -> Vec<usize> {
    (spec.index..run_count).step_by(spec.count.max(1)).collect()
}

/// Most shards a protocol is split into without `--allow-large` (as many as
/// [`crate::cost::MAX_RUNS`]); beyond it, with `--allow-large`, at most one shard per run.
pub const MAX_SHARDS: usize = 100_000;

/// Checks the number of shards against the caps (see [`MAX_SHARDS`]) for a protocol of
/// `run_count` runs, so that nothing proportional to the count is ever allocated beyond what the
/// runs already take. The error names the cap and `--allow-large`.
pub fn check_count(count: usize, run_count: usize, allow_large: bool) -> Result<(), String> {
    if count <= MAX_SHARDS {
        return Ok(());
    }
    if !allow_large {
        return Err(format!(
            "{count} shards are more than the {MAX_SHARDS} allowed (this protocol has {run_count} run(s)); with {} a protocol may be split into at most one shard per run",
            crate::cost::OVERRIDE_FLAG
        ));
    }
    if count > run_count {
        return Err(format!(
            "{count} shards for {run_count} run(s): beyond {MAX_SHARDS} shards, even with {}, a protocol is split into at most one shard per run",
            crate::cost::OVERRIDE_FLAG
        ));
    }
    Ok(())
}

/// Parses `K/N` (0 ≤ K < N): the value of `--shard`.
pub fn parse_spec(text: &str) -> Result<ShardSpec, String> {
    let bad = || {
        format!(
            "{text:?} is not K/N with shard index K from 0 to N − 1 (e.g. 0/4 … 3/4), nor `auto`"
        )
    };
    let (k, n) = text.split_once('/').ok_or_else(bad)?;
    let k: usize = k.trim().parse().map_err(|_| bad())?;
    let n: usize = n.trim().parse().map_err(|_| bad())?;
    if n == 0 {
        return Err(format!(
            "{text:?}: the number of shards N must be at least 1"
        ));
    }
    ShardSpec::new(k, n).ok_or_else(|| {
        format!(
            "{text:?}: shard index {k} is not below the number of shards {n} (shards count from 0: 0/{n} … {}/{n})",
            n - 1
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(k: usize, n: usize) -> ShardSpec {
        ShardSpec::new(k, n).unwrap()
    }

    #[test]
    fn runs_are_dealt_round_robin_and_every_run_lands_in_exactly_one_shard() {
        assert_eq!(runs_of_shard(10, spec(0, 3)), [0, 3, 6, 9]);
        assert_eq!(runs_of_shard(10, spec(1, 3)), [1, 4, 7]);
        assert_eq!(runs_of_shard(10, spec(2, 3)), [2, 5, 8]);
        assert_eq!(runs_of_shard(3, spec(5, 7)), Vec::<usize>::new());
        assert_eq!(runs_of_shard(5, spec(0, 1)), [0, 1, 2, 3, 4]);
        for r in [0, 1, 7, 40, 41] {
            for n in [1, 2, 3, 7, 50] {
                let mut seen = vec![0; r];
                for k in 0..n {
                    let runs = runs_of_shard(r, spec(k, n));
                    // Balanced: ⌊R/N⌋ or ⌈R/N⌉ runs per shard.
                    assert!(runs.len() == r / n || runs.len() == r.div_ceil(n));
                    runs.iter().for_each(|&p| seen[p] += 1);
                }
                assert!(seen.iter().all(|&c| c == 1), "R = {r}, N = {n}");
            }
        }
    }

    #[test]
    fn specs_parse_and_name_their_folders() {
        assert_eq!(parse_spec("0/4"), Ok(spec(0, 4)));
        assert_eq!(parse_spec("3/4"), Ok(spec(3, 4)));
        for bad in ["4/4", "1/0", "-1/4", "a/4", "3", "", "1/2/3"] {
            assert!(parse_spec(bad).is_err(), "{bad}");
        }
        assert!(parse_spec("4/4").unwrap_err().contains("count from 0"));
        assert_eq!(spec(3, 4).folder_name(), "shard-3-of-4");
        assert_eq!(spec(3, 12).folder_name(), "shard-03-of-12");
        assert_eq!(spec(0, 1).folder_name(), "shard-0-of-1");
        assert_eq!(spec(7, 101).folder_name(), "shard-007-of-101");
        assert_eq!(spec(2, 7).to_string(), "2/7");
        for (k, n) in [(0, 1), (3, 4), (3, 12), (11, 12), (7, 101)] {
            let name = spec(k, n).folder_name();
            assert_eq!(
                ShardSpec::from_folder_name(&name),
                Some(spec(k, n)),
                "{name}"
            );
        }
        for other in [
            "shard-3-of-12",
            "shard-003-of-12",
            "shard-4-of-4",
            "shard-0-of-0",
            "shard--1-of-4",
            "shard-+1-of-4",
            "shard-1-of-4x",
            "shard-1-of-",
            ".shard-1-of-4",
            "p00",
        ] {
            assert_eq!(ShardSpec::from_folder_name(other), None, "{other}");
        }
    }
}
