//! `rsasim schema`: print a JSON Schema, or write them all.

use super::Outcome;
use crate::cli::SchemaArgs;

/// Prints the schema named (or, with `--write-dir`, writes every schema; a failure: exit 1).
pub fn execute(args: SchemaArgs) -> Outcome {
    let schemas = rsasim::output::schemas();
    match args.write_dir {
        Some(dir) => {
            for (n, s) in &schemas {
                let path = dir.join(format!("{n}.schema.json"));
                let text = serde_json::to_string_pretty(s).expect("schema serialises") + "\n";
                rsasim::output::atomic::write_atomic(&path, text.as_bytes()).map_err(|e| {
                    eprintln!("error: cannot write {}: {e}", path.display());
                    1
                })?;
                eprintln!("wrote {}", path.display());
            }
        }
        None => {
            let name = args.name.name();
            let (_, s) = schemas
                .iter()
                .find(|(n, _)| *n == name)
                .expect("every schema name is a schema");
            println!(
                "{}",
                serde_json::to_string_pretty(s).expect("schema serialises")
            );
        }
    }
    Ok(())
}
