//! `--shard auto`: the shard index and count from the environment a cluster engine gives each
//! task, as a pure function of the variables (so every path is unit-tested).
//!
//! - SLURM array jobs: `SLURM_ARRAY_TASK_ID` with `SLURM_ARRAY_TASK_MIN` and
//!   `SLURM_ARRAY_TASK_COUNT` or `SLURM_ARRAY_TASK_MAX`. Array indices are the user's
//!   (`--array=1-8` as well as `--array=0-7`): shard K = ID − MIN, N = COUNT = MAX − MIN + 1.
//!   An array with a step or a list (`--array=0-6:2`, `--array=1,4,9`) has gaps, which would
//!   leave runs unwritten: refused.
//! - Kubernetes Indexed Jobs: `JOB_COMPLETION_INDEX` (0-based) is K; Kubernetes does not export
//!   `.spec.completions`, so N comes from `--shard-count`.

use std::collections::HashMap;

use super::ShardSpec;

/// What `--shard` asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShardRequest {
    /// `--shard K/N`.
    Fixed(ShardSpec),
    /// `--shard auto`: from the environment.
    Auto,
}

impl ShardRequest {
    /// Parses the value of `--shard`: `auto` or `K/N`.
    pub fn parse(text: &str) -> Result<ShardRequest, String> {
        if text == "auto" {
            Ok(ShardRequest::Auto)
        } else {
            super::parse_spec(text).map(ShardRequest::Fixed)
        }
    }
}

/// Why the shard could not be decided (exit 2, before anything is written).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EnvError {
    /// What is wrong.
    pub message: String,
    /// What would be valid.
    pub help: String,
}

fn error(message: impl Into<String>, help: impl Into<String>) -> EnvError {
    EnvError {
        message: message.into(),
        help: help.into(),
    }
}

/// The Kubernetes variable.
pub const K8S_INDEX: &str = "JOB_COMPLETION_INDEX";
/// The SLURM variables.
pub const SLURM_ID: &str = "SLURM_ARRAY_TASK_ID";
/// See [`SLURM_ID`].
pub const SLURM_MIN: &str = "SLURM_ARRAY_TASK_MIN";
/// See [`SLURM_ID`].
pub const SLURM_MAX: &str = "SLURM_ARRAY_TASK_MAX";
/// See [`SLURM_ID`].
pub const SLURM_COUNT: &str = "SLURM_ARRAY_TASK_COUNT";

/// The shard to write and where it came from (for the user): `request` as given, checked against
/// `shard_count` (`--shard-count`) when both are there; `auto` from `vars` (the process
/// environment; see the module documentation).
pub fn resolve(
    request: ShardRequest,
    shard_count: Option<usize>,
    vars: &HashMap<String, String>,
) -> Result<(ShardSpec, String), EnvError> {
    let spec_and_source = match request {
        ShardRequest::Fixed(spec) => (spec, "--shard".to_string()),
        ShardRequest::Auto => from_env(shard_count, vars)?,
    };
    let (spec, source) = &spec_and_source;
    if let Some(n) = shard_count
        && n != spec.count
    {
        return Err(error(
            format!(
                "--shard-count {n} disagrees with the {} shards of {source}",
                spec.count
            ),
            "give the same number of shards everywhere (or leave --shard-count out)",
        ));
    }
    Ok(spec_and_source)
}

/// `--shard auto`: K and N from SLURM's or Kubernetes' variables.
pub fn from_env(
    shard_count: Option<usize>,
    vars: &HashMap<String, String>,
) -> Result<(ShardSpec, String), EnvError> {
    let get = |name: &str| vars.get(name).map(|v| v.trim()).filter(|v| !v.is_empty());
    match (get(K8S_INDEX), get(SLURM_ID)) {
        (Some(_), Some(_)) => Err(error(
            format!("--shard auto: both {K8S_INDEX} (Kubernetes) and {SLURM_ID} (SLURM) are set"),
            "a task runs under one engine: unset the other variable, or give --shard K/N",
        )),
        (Some(index), None) => kubernetes(index, shard_count),
        (None, Some(id)) => slurm(id, &get),
        (None, None) => Err(error(
            format!(
                "--shard auto: neither {SLURM_ID} (a SLURM array task) nor {K8S_INDEX} (a Kubernetes Indexed Job) is set"
            ),
            "run it as an array task (sbatch --array=0-3) or an Indexed Job pod, or give --shard K/N (K from 0 to N − 1)",
        )),
    }
}

fn number(name: &str, value: &str) -> Result<usize, EnvError> {
    value.parse().map_err(|_| {
        error(
            format!("{name}={value:?} is not a non-negative whole number"),
            "it is set by the cluster engine; check the job script does not overwrite it",
        )
    })
}

fn kubernetes(index: &str, shard_count: Option<usize>) -> Result<(ShardSpec, String), EnvError> {
    let k = number(K8S_INDEX, index)?;
    let Some(n) = shard_count else {
        return Err(error(
            format!(
                "--shard auto with {K8S_INDEX}={k}: Kubernetes does not tell the number of completions"
            ),
            "pass --shard-count N with N equal to the Job's .spec.completions",
        ));
    };
    let spec = ShardSpec::new(k, n).ok_or_else(|| {
        error(
            format!("{K8S_INDEX}={k} is not below --shard-count {n}"),
            "set --shard-count to the Job's .spec.completions (indices run from 0 to completions − 1)",
        )
    })?;
    Ok((spec, format!("{K8S_INDEX}={k} and --shard-count {n}")))
}

fn slurm<'a>(
    id: &str,
    get: &dyn Fn(&str) -> Option<&'a str>,
) -> Result<(ShardSpec, String), EnvError> {
    let id = number(SLURM_ID, id)?;
    let Some(min) = get(SLURM_MIN) else {
        return Err(error(
            format!("--shard auto with {SLURM_ID}={id}: {SLURM_MIN} is not set"),
            "SLURM sets it in every array task; run the script with sbatch --array, or give --shard K/N",
        ));
    };
    let min = number(SLURM_MIN, min)?;
    let max = get(SLURM_MAX).map(|v| number(SLURM_MAX, v)).transpose()?;
    let count = get(SLURM_COUNT)
        .map(|v| number(SLURM_COUNT, v))
        .transpose()?;
    let span = max.map(|max| max.checked_sub(min).map(|d| d + 1));
    let n = match (count, span) {
        (_, Some(None)) => {
            return Err(error(
                format!("{SLURM_MAX} is below {SLURM_MIN}={min}"),
                "the variables are set by SLURM; check the job script does not overwrite them",
            ));
        }
        (Some(count), Some(Some(span))) if count != span => {
            return Err(error(
                format!(
                    "the SLURM array has gaps: {SLURM_COUNT}={count} tasks, but indices {min} to {} span {span}",
                    max.unwrap_or(min)
                ),
                "submit a contiguous array without a step, e.g. sbatch --array=0-3 (a throttle like %2 is fine)",
            ));
        }
        (Some(count), _) => count,
        (None, Some(Some(span))) => span,
        (None, None) => {
            return Err(error(
                format!(
                    "--shard auto with {SLURM_ID}={id}: neither {SLURM_COUNT} nor {SLURM_MAX} is set"
                ),
                "SLURM sets them in every array task; run the script with sbatch --array, or give --shard K/N",
            ));
        }
    };
    let spec = id
        .checked_sub(min)
        .and_then(|k| ShardSpec::new(k, n))
        .ok_or_else(|| {
            error(
                format!(
                    "{SLURM_ID}={id} is outside the array {min} to {}",
                    min + n.max(1) - 1
                ),
                "the variables are set by SLURM; check the job script does not overwrite them",
            )
        })?;
    Ok((spec, format!("{SLURM_ID}={id} of {n} task(s) from {min}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vars(pairs: &[(&str, &str)]) -> HashMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    fn spec(k: usize, n: usize) -> ShardSpec {
        ShardSpec::new(k, n).unwrap()
    }

    fn auto(count: Option<usize>, pairs: &[(&str, &str)]) -> Result<ShardSpec, EnvError> {
        resolve(ShardRequest::Auto, count, &vars(pairs)).map(|(s, _)| s)
    }

    #[test]
    fn kubernetes_index_with_the_count_from_the_command_line() {
        assert_eq!(auto(Some(4), &[(K8S_INDEX, "0")]), Ok(spec(0, 4)));
        assert_eq!(auto(Some(4), &[(K8S_INDEX, "3")]), Ok(spec(3, 4)));
        let e = auto(None, &[(K8S_INDEX, "2")]).unwrap_err();
        assert!(e.help.contains("--shard-count"), "{e:?}");
        let e = auto(Some(4), &[(K8S_INDEX, "4")]).unwrap_err();
        assert!(e.message.contains("not below --shard-count 4"), "{e:?}");
        let e = auto(Some(4), &[(K8S_INDEX, "-1")]).unwrap_err();
        assert!(
            e.message.contains("not a non-negative whole number"),
            "{e:?}"
        );
    }

    #[test]
    fn slurm_arrays_of_any_first_index() {
        let task = |id: &str, min: &str, max: &str, count: &str| {
            vec![
                (SLURM_ID, id.to_string()),
                (SLURM_MIN, min.to_string()),
                (SLURM_MAX, max.to_string()),
                (SLURM_COUNT, count.to_string()),
            ]
        };
        let run = |p: Vec<(&str, String)>, count: Option<usize>| {
            let pairs: Vec<(&str, &str)> = p.iter().map(|(k, v)| (*k, v.as_str())).collect();
            auto(count, &pairs)
        };
        // --array=0-3 and --array=1-4 give the same shards.
        assert_eq!(run(task("0", "0", "3", "4"), None), Ok(spec(0, 4)));
        assert_eq!(run(task("3", "0", "3", "4"), None), Ok(spec(3, 4)));
        assert_eq!(run(task("1", "1", "4", "4"), None), Ok(spec(0, 4)));
        assert_eq!(run(task("4", "1", "4", "4"), Some(4)), Ok(spec(3, 4)));
        // COUNT or MAX alone is enough.
        assert_eq!(
            auto(
                None,
                &[(SLURM_ID, "12"), (SLURM_MIN, "10"), (SLURM_MAX, "13")]
            ),
            Ok(spec(2, 4))
        );
        assert_eq!(
            auto(
                None,
                &[(SLURM_ID, "12"), (SLURM_MIN, "10"), (SLURM_COUNT, "3")]
            ),
            Ok(spec(2, 3))
        );
        // A step leaves gaps (--array=0-6:2: ids 0, 2, 4, 6).
        let e = run(task("2", "0", "6", "4"), None).unwrap_err();
        assert!(e.message.contains("gaps"), "{e:?}");
        // Inconsistent or missing variables.
        let e = run(task("9", "0", "3", "4"), None).unwrap_err();
        assert!(e.message.contains("outside the array 0 to 3"), "{e:?}");
        let e = auto(None, &[(SLURM_ID, "1"), (SLURM_COUNT, "4")]).unwrap_err();
        assert!(
            e.message.contains("SLURM_ARRAY_TASK_MIN is not set"),
            "{e:?}"
        );
        let e = auto(None, &[(SLURM_ID, "1"), (SLURM_MIN, "0")]).unwrap_err();
        assert!(
            e.message.contains("neither SLURM_ARRAY_TASK_COUNT"),
            "{e:?}"
        );
        let e = run(task("1", "0", "3", "4"), Some(5)).unwrap_err();
        assert!(e.message.contains("--shard-count 5 disagrees"), "{e:?}");
        let e = run(task("1", "3", "0", "4"), None).unwrap_err();
        assert!(e.message.contains("below"), "{e:?}");
    }

    #[test]
    fn no_engine_or_two_engines_are_errors_and_fixed_specs_pass_through() {
        let e = auto(Some(4), &[]).unwrap_err();
        assert!(e.message.contains("neither SLURM_ARRAY_TASK_ID"), "{e:?}");
        let e = auto(Some(4), &[(K8S_INDEX, "0"), (SLURM_ID, "0")]).unwrap_err();
        assert!(e.message.contains("both"), "{e:?}");
        let fixed = ShardRequest::parse("1/3").unwrap();
        assert_eq!(
            resolve(fixed, None, &vars(&[(K8S_INDEX, "0")])).map(|(s, _)| s),
            Ok(spec(1, 3))
        );
        assert!(resolve(fixed, Some(2), &vars(&[])).is_err());
        assert_eq!(ShardRequest::parse("auto"), Ok(ShardRequest::Auto));
    }
}
