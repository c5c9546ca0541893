//! The manual's reference pages that are generated, not typed: the command line as the argument
//! parser prints it (`docs/src/reference/cli-help.md`). A changed flag or help text fails this test
//! until the page is regenerated with `RSASIM_BLESS=1 cargo test --test integration manual::`.

use crate::common;

use common::{root, rsasim};

const CLI_PAGE: &str = "docs/src/reference/cli-help.md";

/// `rsasim <args> --help` as the parser prints it.
fn help(args: &[&str]) -> String {
    let mut all = args.to_vec();
    all.push("--help");
    let o = rsasim(&all, &[("COLUMNS", "100")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

/// The commands `rsasim --help` lists (but `help`).
fn commands(top: &str) -> Vec<String> {
    top.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_string)
        .collect()
}

/// The page: the top-level help, then every command's, each in a fenced block.
fn cli_page() -> String {
    let top = help(&[]);
    let mut page = String::from(
        "# Every option, as the program prints it\n\n\
         <!-- made by: RSASIM_BLESS=1 cargo test --test integration manual:: (from `rsasim --help` and `rsasim <command> --help`; do not edit) -->\n\n\
         The overview is [The command line](cli.md). What follows is the argument parser's own help,\n\
         generated from it, so it cannot drift from the program.\n\n## `rsasim`\n\n```text\n",
    );
    page.push_str(top.trim_end());
    page.push_str("\n```\n");
    for c in commands(&top) {
        page.push_str(&format!("\n## `rsasim {c}`\n\n```text\n"));
        page.push_str(help(&[&c]).trim_end());
        page.push_str("\n```\n");
    }
    page
}

#[test]
fn the_command_line_reference_is_the_parser_s_own_help() {
    let page = cli_page();
    assert!(
        commands(&help(&[])).len() >= 13,
        "the command list was not found in `rsasim --help`"
    );
    same_as_committed(CLI_PAGE, &page);
}

/// Fails unless the committed page `rel` is `page`; with `RSASIM_BLESS` set, writes it first.
fn same_as_committed(rel: &str, page: &str) {
    let path = root().join(rel);
    if std::env::var_os("RSASIM_BLESS").is_some() {
        std::fs::write(&path, page).unwrap();
    }
    let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        on_disk == page,
        "{rel} is not what the program gives: regenerate it with `RSASIM_BLESS=1 cargo test --test integration manual::` and commit it"
    );
}

const KEYS_PAGE: &str = "docs/src/reference/scenario-keys.md";

/// What a property of the schema holds: its type in words, and the definition it opens (an
/// object of its own, reached by `$ref` directly, in an array or in an `anyOf` with null).
fn kind(p: &serde_json::Value, defs: &serde_json::Value) -> (String, Option<(String, bool)>) {
    let reference = |v: &serde_json::Value| {
        v.get("$ref")
            .and_then(|r| r.as_str())
            .and_then(|r| r.strip_prefix("#/$defs/"))
            .map(str::to_string)
    };
    let simple = |v: &serde_json::Value| match v.get("type") {
        Some(serde_json::Value::String(t)) => t.clone(),
        Some(serde_json::Value::Array(ts)) => ts
            .iter()
            .filter_map(|t| t.as_str())
            .filter(|t| *t != "null")
            .collect::<Vec<_>>()
            .join(" or "),
        _ => String::from("value"),
    };
    let named = |name: &str| -> (String, Option<(String, bool)>) {
        let d = &defs[name];
        let values: Vec<String> = d
            .get("oneOf")
            .or_else(|| d.get("anyOf"))
            .and_then(|v| v.as_array())
            .map(|alts| {
                alts.iter()
                    .filter_map(|a| {
                        a.get("const")
                            .or_else(|| a.get("enum").and_then(|e| e.get(0)))
                            .map(|c| c.to_string())
                    })
                    .collect()
            })
            .or_else(|| {
                d.get("enum")
                    .and_then(|e| e.as_array())
                    .map(|e| e.iter().map(|c| c.to_string()).collect())
            })
            .unwrap_or_default();
        if d.get("properties").is_some() {
            ("table, below".to_string(), Some((name.to_string(), false)))
        } else if !values.is_empty() {
            (values.join(" \\| "), None)
        } else {
            (simple(d), None)
        }
    };
    if let Some(r) = reference(p) {
        return named(&r);
    }
    if let Some(alts) = p.get("anyOf").and_then(|a| a.as_array()) {
        if let Some(r) = alts.iter().find_map(reference) {
            return named(&r);
        }
    }
    if p.get("type").and_then(|t| t.as_str()) == Some("array") {
        if let Some(r) = p.get("items").and_then(reference) {
            let (what, table) = named(&r);
            return (
                if table.is_some() {
                    "array of tables, below".to_string()
                } else {
                    format!("array of {what}")
                },
                table.map(|(name, _)| (name, true)),
            );
        }
        let items = p.get("items").map(simple).unwrap_or_default();
        return (format!("array of {items}"), None);
    }
    (simple(p), None)
}

/// One section per table of the scenario file, in the order a reader meets them.
fn keys_page() -> String {
    let text = std::fs::read_to_string(root().join("schemas/scenario.schema.json")).unwrap();
    let schema: serde_json::Value = serde_json::from_str(&text).unwrap();
    let defs = &schema["$defs"];
    let mut page = String::from(
        "# Every scenario key, from the schema\n\n\
         <!-- made by: RSASIM_BLESS=1 cargo test --test integration manual:: (from schemas/scenario.schema.json; do not edit) -->\n\n\
         Generated from `schemas/scenario.schema.json`, which the program generates from its own\n\
         records (`rsasim schema`), so it cannot drift. The guided tour is\n\
         [A scenario, key by key](scenario.md).\n",
    );
    let mut queue: Vec<(String, serde_json::Value)> = vec![(String::new(), schema.clone())];
    let mut seen = std::collections::BTreeSet::new();
    while !queue.is_empty() {
        let (path, def) = queue.remove(0);
        let title = if path.is_empty() {
            "The top level".to_string()
        } else {
            format!("`{path}`")
        };
        page.push_str(&format!("\n## {title}\n\n"));
        if let Some(d) = def.get("description").and_then(|d| d.as_str()) {
            page.push_str(&d.replace('\n', " "));
            page.push_str("\n\n");
        }
        page.push_str("| key | type | required | meaning |\n|---|---|---|---|\n");
        let required: Vec<&str> = def
            .get("required")
            .and_then(|r| r.as_array())
            .map(|r| r.iter().filter_map(|x| x.as_str()).collect())
            .unwrap_or_default();
        let props = def["properties"].as_object().unwrap();
        for (key, p) in props {
            let (what, table) = kind(p, defs);
            let meaning = p
                .get("description")
                .and_then(|d| d.as_str())
                .unwrap_or("")
                .replace('\n', " ")
                .replace('|', "\\|");
            page.push_str(&format!(
                "| `{key}` | {what} | {} | {meaning} |\n",
                if required.contains(&key.as_str()) {
                    "yes"
                } else {
                    "no"
                }
            ));
            if let Some((name, array)) = table {
                // The dotted name of the table, then its header: `[a.b]`, or `[[a.b]]` for
                // an array of tables.
                let bare = path.trim_matches(|c| c == '[' || c == ']');
                let name_of = if bare.is_empty() {
                    key.clone()
                } else {
                    format!("{bare}.{key}")
                };
                let child = if array {
                    format!("[[{name_of}]]")
                } else {
                    format!("[{name_of}]")
                };
                if seen.insert(child.clone()) {
                    queue.push((child, defs[&name].clone()));
                }
            }
        }
    }
    page
}

#[test]
fn the_scenario_key_reference_is_the_schema_s_own() {
    let page = keys_page();
    for table in [
        "[sequence]",
        "[[sequence.joints]]",
        "[[phantoms]]",
        "[imaging]",
    ] {
        assert!(
            page.contains(&format!("## `{table}`")),
            "no section {table}"
        );
    }
    // A doc comment's intra-doc link (`[`path`]` with no target) means nothing to a reader of
    // the manual: the keys' descriptions must point at pages, not at code.
    let dangling: Vec<&str> = page
        .match_indices("`]")
        .filter(|(i, _)| !page[i + 2..].starts_with('('))
        .map(|(i, _)| &page[page[..i].rfind('[').unwrap_or(0)..i + 2])
        .collect();
    assert!(
        dangling.is_empty(),
        "rustdoc links in the keys: {dangling:?}"
    );
    same_as_committed(KEYS_PAGE, &page);
}

/// The pages whose shell examples marked `<!-- runnable -->` are run.
const RUNNABLE_PAGES: [&str; 3] = [
    "README.md",
    "docs/src/tutorial/index.md",
    "docs/src/guide/dynamic-exams.md",
];

/// The command lines of the fenced blocks just after a `<!-- runnable -->` line, in page order:
/// each without its trailing `# comment`.
fn runnable_commands(page: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut lines = page.lines();
    while let Some(line) = lines.next() {
        if line.trim() != "<!-- runnable -->" {
            continue;
        }
        assert!(
            lines.next().is_some_and(|l| l.trim() == "```sh"),
            "a runnable mark stands before something else than a ```sh block"
        );
        for l in lines.by_ref() {
            if l.trim() == "```" {
                break;
            }
            let command = l.split("  #").next().unwrap_or("").trim();
            if !command.is_empty() {
                out.push(command.to_string());
            }
        }
    }
    out
}

#[test]
fn the_manual_s_runnable_examples_run() {
    // Each page runs in a folder of its own that holds copies of the checkout's scenarios, models
    // and test scenarios, except that `scenarios/biplanar.toml` is a small stand-in of the same name (the
    // paper's protocol takes a minute and 2.9 GB): scenarios/golden/small_biplanar.toml, named
    // `biplanar`. Every command must succeed; `rsasim` and `cargo run --release --` both run the
    // binary under test.
    let small = std::fs::read_to_string(root().join("scenarios/golden/small_biplanar.toml"))
        .unwrap()
        .replace("name = \"small_biplanar\"", "name = \"biplanar\"");
    assert!(small.contains("name = \"biplanar\"") && small.contains("\"models/"));
    let mut ran = 0;
    for rel in RUNNABLE_PAGES {
        let commands = runnable_commands(&std::fs::read_to_string(root().join(rel)).unwrap());
        assert!(!commands.is_empty(), "{rel} has no runnable example");
        let tmp = tempfile::tempdir().unwrap();
        // Copies, not links: a scenario may read meshes only from folders it is allowed.
        let copy_dir = |from: &str, to: &std::path::Path, only_toml: bool| {
            std::fs::create_dir_all(to).unwrap();
            for e in std::fs::read_dir(root().join(from)).unwrap() {
                let p = e.unwrap().path();
                let toml = p.extension().is_some_and(|x| x == "toml");
                if p.is_file() && (toml || !only_toml) {
                    std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
                }
            }
        };
        let scenarios = tmp.path().join("scenarios");
        copy_dir("scenarios", &scenarios, true);
        copy_dir("scenarios/models", &scenarios.join("models"), false);
        copy_dir("tests/scenarios", &tmp.path().join("tests/scenarios"), true);
        std::fs::write(scenarios.join("biplanar.toml"), &small).unwrap();
        for command in &commands {
            let words: Vec<&str> = command.split_whitespace().collect();
            let args: &[&str] = match words.as_slice() {
                ["rsasim", rest @ ..] => rest,
                ["cargo", "run", "--release", "--", rest @ ..] => rest,
                _ => panic!(
                    "{rel}: `{command}` is marked runnable but runs neither rsasim nor cargo run"
                ),
            };
            let o = std::process::Command::new(env!("CARGO_BIN_EXE_rsasim"))
                .args(args)
                .current_dir(tmp.path())
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{rel}: `{command}` failed:\n{}",
                String::from_utf8_lossy(&o.stderr)
            );
            ran += 1;
        }
    }
    assert!(ran >= 11, "{ran} commands");
}
