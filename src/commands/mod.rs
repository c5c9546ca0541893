//! One module per subcommand, each with an `execute` that takes the command's arguments
//! ([`crate::cli`]) and returns `Err(exit code)` on failure: 2 for bad input (nothing was
//! written), 1 for a failure while writing. Every message is printed where it arises.

pub mod camera;
pub mod evaluate;
pub mod expand;
pub mod export;
pub mod material;
pub mod merge;
pub mod reconstruct;
pub mod run;
pub mod scene;
pub mod schema;
mod shared;
pub mod spectrum;
pub mod sweep;
pub mod validate;
pub mod verify;

/// What a command returns: `Err` holds the exit code, its messages already printed.
pub type Outcome = Result<(), u8>;
