//! `rsasim validate`: check a scenario and write nothing.

use super::Outcome;
use super::shared::check;
use crate::cli::ValidateArgs;

/// Checks the scenario (errors: exit 2) and prints what it would cost.
pub fn execute(args: ValidateArgs) -> Outcome {
    let checked = check(&args.scenario, &args.allow.into())?;
    let spectrum = checked.setup.as_ref().map_or(String::new(), |setup| {
        format!(
            "; spectrum traced in {} bins, within {:.3} % for a layer of one material (`rsasim spectrum` shows each)",
            setup.energies_kev.len(),
            setup.spectral_tolerance * 100.0
        )
    });
    eprintln!(
        "{}: valid: {}{spectrum}",
        args.scenario.display(),
        checked.cost.summary()
    );
    Ok(())
}
