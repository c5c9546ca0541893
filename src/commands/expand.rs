//! `rsasim expand`: print every concrete run as JSON.

use std::io::Write;

use super::Outcome;
use super::shared::check;
use crate::cli::ExpandArgs;

/// Checks the scenario (errors: exit 2), then prints every run as one pretty JSON array, run by
/// run (the same bytes as printing the whole array at once, without holding it): memory stays
/// flat with the run count.
pub fn execute(args: ExpandArgs) -> Outcome {
    let checked = check(&args.scenario, &args.allow.into())?;
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let mut write = || -> std::io::Result<()> {
        let mut first = true;
        out.write_all(b"[")?;
        for run in rsasim::expand::runs(&checked.loaded.scenario, &checked.models) {
            let text = serde_json::to_string_pretty(&run).map_err(std::io::Error::other)?;
            out.write_all(if first { b"\n" } else { b",\n" })?;
            first = false;
            for (i, line) in text.lines().enumerate() {
                if i > 0 {
                    out.write_all(b"\n")?;
                }
                out.write_all(b"  ")?;
                out.write_all(line.as_bytes())?;
            }
        }
        out.write_all(if first { b"]\n" } else { b"\n]\n" })?;
        out.flush()
    };
    write().map_err(|e| {
        eprintln!("error: writing the runs to standard output failed: {e}");
        1
    })
}
