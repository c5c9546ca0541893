//! `rsasim verify`: check an output folder against its manifest.

use super::Outcome;
use crate::cli::VerifyArgs;

/// Prints one line per problem and a summary; exit 2 when anything does not verify.
pub fn execute(args: VerifyArgs) -> Outcome {
    let results = rsasim::output::verify::verify(&args.out, args.images.as_deref());
    print!("{}", rsasim::output::verify::render(&results));
    if results.iter().all(|v| v.ok()) {
        Ok(())
    } else {
        Err(2)
    }
}
