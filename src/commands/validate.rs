//! `rsasim validate`: check a scenario and write nothing.

use super::Outcome;
use super::shared::check;
use crate::cli::ValidateArgs;

/// Checks the scenario (errors: exit 2) and prints what it would cost.
pub fn execute(args: ValidateArgs) -> Outcome {
    let checked = check(&args.scenario, &args.allow.into())?;
    eprintln!(
        "{}: valid: {}",
        args.scenario.display(),
        checked.cost.summary()
    );
    Ok(())
}
