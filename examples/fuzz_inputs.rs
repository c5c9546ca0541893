//! The long mutation run over received folders: N seeded mutants per reading command (default
//! 20,000), each run through the real binary on its own copy of a folder built once, two at a
//! time. The contract and the mutations are those of `tests/mutation.rs` (`received_folders`),
//! from the shared harness in `tests/common/mutate.rs`.
//!
//! ```sh
//! cargo build --release --bin rsasim
//! cargo run --release --example fuzz_inputs -- received 20000 --tsv received-20000.tsv
//! ```
//!
//! It prints its progress every 1,000 mutants and the time each command took; on a small machine
//! the whole run takes hours, so it can also be run one command at a time (`--only`), each with
//! its own `--tsv`.
//!
//! Arguments: `received [N] [--seed FIRST] [--threads T] [--limit SECONDS] [--keep K]
//! [--only KIND,KIND…] [--tsv FILE]`. Seeds run from FIRST (default 0) to FIRST + N − 1 for every command, so a
//! failure is replayed by its seed alone: `received 1 --seed 4711 --only merge --keep 1` keeps the
//! mutant's folder in `$TMPDIR/rsasim-mutant-merge-4711`. The kinds are export-xmalab,
//! export-autoscoper, evaluate, evaluate-study, reconstruct, verify, merge, sweep-merge,
//! evaluate-sweep and reconstruct-sweep. `--limit` is the time after which a process counts as
//! hung and is killed (default 20 s); `--keep` the number of failing mutants kept (default 20);
//! `--tsv FILE` also writes every failure as a tab-separated row (command, seed, file, mutation,
//! exit, reason, first line of stderr).
//!
//! The binary is `$RSASIM_BIN`, else `rsasim` in the profile folder this example was built into
//! (`target/release/rsasim` for `--release`): `cargo run --example` does not build it, so build it
//! first. Run as root, the mutants run as `nobody`.
//!
//! At the end it prints a table (command, mutants, exit 0, exit 1, exit 2, failures, elapsed)
//! and the failures grouped by reason, each as (seed, file mutated, how, exit code, first line of
//! stderr); it exits 1 if any mutant failed. A seed names the same mutant on any build whose output
//! bytes are the same (see `tests/mutation.rs`), so `RSASIM_MUTATION_SEED=<seed>
//! RSASIM_MUTATION_CASES=1 cargo test --test integration mutation::received_folders::<test>` replays it too.

#[path = "../tests/common/mutate.rs"]
mod mutate;

#[cfg(unix)]
fn main() {
    use mutate::received::{Harness, Kind};
    use std::path::PathBuf;
    use std::sync::Mutex;
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::time::{Duration, Instant};

    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: fuzz_inputs received [N] [--seed FIRST] [--threads T] [--limit SECONDS] \
                 [--keep K] [--only KIND,KIND…] [--tsv FILE]";
    if args.first().map(String::as_str) != Some("received") {
        eprintln!("{usage}");
        std::process::exit(2);
    }
    let mut n: u64 = 20_000;
    let mut first: u64 = 0;
    let mut threads = 2usize;
    let mut limit = 20u64;
    let mut keep = 20usize;
    let mut kinds: Vec<Kind> = Kind::ALL.to_vec();
    let mut tsv: Option<std::path::PathBuf> = None;
    let mut it = args[1..].iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .unwrap_or_else(|| panic!("{name} needs a value; {usage}"))
                .clone()
        };
        match a.as_str() {
            "--seed" => first = value("--seed").parse().expect("--seed: a number"),
            "--threads" => threads = value("--threads").parse().expect("--threads: a number"),
            "--limit" => limit = value("--limit").parse().expect("--limit: seconds"),
            "--keep" => keep = value("--keep").parse().expect("--keep: a number"),
            "--tsv" => tsv = Some(value("--tsv").into()),
            "--only" => {
                kinds = value("--only")
                    .split(',')
                    .map(|k| Kind::from_name(k).unwrap_or_else(|| panic!("no kind {k:?}")))
                    .collect()
            }
            number => n = number.parse().unwrap_or_else(|_| panic!("{usage}")),
        }
    }
    let bin = std::env::var_os("RSASIM_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            // target/<profile>/examples/fuzz_inputs -> target/<profile>/rsasim
            let exe = std::env::current_exe().unwrap();
            exe.parent().unwrap().parent().unwrap().join("rsasim")
        });
    // The mutants run in their own folders: the binary's path must not be relative.
    let bin = std::fs::canonicalize(&bin).unwrap_or(bin);
    if !bin.is_file() {
        eprintln!(
            "no binary at {}: run `cargo build --release --bin rsasim` first, or set RSASIM_BIN",
            bin.display()
        );
        std::process::exit(2);
    }
    let age = std::fs::metadata(&bin)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .map_or("?".into(), |d| format!("{} min", d.as_secs() / 60));
    eprintln!(
        "fuzz_inputs: {} (built {age} ago), {n} mutants per command, seeds {first}..{}, {threads} \
         threads, hang limit {limit} s",
        bin.display(),
        first + n
    );
    let mut harness = Harness::new(bin, Duration::from_secs(limit));
    harness.keep = keep;

    struct Row {
        kind: Kind,
        mutants: u64,
        codes: [u64; 3],
        failures: Vec<mutate::received::Failure>,
        elapsed: Duration,
    }
    let mut rows: Vec<Row> = Vec::new();
    let total = Instant::now();
    for kind in kinds {
        let start = Instant::now();
        let fixture = harness.fixture(kind.fixture());
        let clean = harness.check(kind, &fixture, None);
        if !matches!(clean, Ok(0)) {
            drop(fixture);
            match clean {
                Ok(code) => eprintln!("{}: the unmutated folder gave exit {code}", kind.name()),
                Err(f) => eprintln!("{}: the unmutated folder is not read: {f}", kind.name()),
            }
            std::process::exit(1);
        }
        let next = AtomicU64::new(0);
        let codes = Mutex::new([0u64; 3]);
        let failures = Mutex::new(Vec::new());
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| {
                    loop {
                        let k = next.fetch_add(1, Ordering::Relaxed);
                        if k >= n {
                            break;
                        }
                        let seed = first.wrapping_add(k);
                        match harness.check(kind, &fixture, Some(seed)) {
                            Ok(code) => codes.lock().unwrap()[code.clamp(0, 2) as usize] += 1,
                            Err(f) => failures.lock().unwrap().push(*f),
                        }
                        if (k + 1).is_multiple_of(1000) {
                            eprintln!(
                                "  {}: {} of {n} in {:.0} s, {} failure(s)",
                                kind.name(),
                                k + 1,
                                start.elapsed().as_secs_f64(),
                                failures.lock().unwrap().len()
                            );
                        }
                    }
                });
            }
        });
        let mut failures = failures.into_inner().unwrap();
        failures.sort_by_key(|f| f.seed);
        let row = Row {
            kind,
            mutants: n,
            codes: codes.into_inner().unwrap(),
            failures,
            elapsed: start.elapsed(),
        };
        eprintln!(
            "{}: {} mutants, {} failure(s) in {:.0} s",
            kind.name(),
            row.mutants,
            row.failures.len(),
            row.elapsed.as_secs_f64()
        );
        rows.push(row);
    }

    println!(
        "\n## Received folders: {n} mutants per command (seeds {first}..{})\n",
        first + n
    );
    println!("| command | mutants | exit 0 | exit 1 | exit 2 | failures | elapsed |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for r in &rows {
        println!(
            "| {} | {} | {} | {} | {} | {} | {:.0} s |",
            r.kind.name(),
            r.mutants,
            r.codes[0],
            r.codes[1],
            r.codes[2],
            r.failures.len(),
            r.elapsed.as_secs_f64()
        );
    }
    println!(
        "\nTotal {:.0} s. Exit 1 is an answer only for reconstruct (nothing could be \
         reconstructed); everywhere else it is a failure.",
        total.elapsed().as_secs_f64()
    );
    for r in rows.iter().filter(|r| !r.failures.is_empty()) {
        println!("\n### {}: {} failure(s)\n", r.kind.name(), r.failures.len());
        // Grouped by what went wrong (the reason without its details) and the file's group.
        let mut groups: std::collections::BTreeMap<String, Vec<&mutate::received::Failure>> =
            Default::default();
        for f in &r.failures {
            let why: String = f.why.split(':').next().unwrap_or("").to_string();
            groups.entry(why).or_default().push(f);
        }
        for (why, fs) in groups {
            let seeds: Vec<String> = fs
                .iter()
                .filter_map(|f| f.seed)
                .map(|s| s.to_string())
                .collect();
            println!(
                "- **{why}** ({}): seeds {}{}",
                fs.len(),
                seeds
                    .iter()
                    .take(40)
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", "),
                if seeds.len() > 40 { ", …" } else { "" }
            );
            for f in fs.iter().take(8) {
                println!(
                    "  - seed {} `{}` [{}]: exit {}{}: {}; `{}`",
                    f.seed.unwrap_or(0),
                    f.file,
                    f.mutation,
                    f.code.map_or("signal".to_string(), |c| c.to_string()),
                    if f.timed_out { " (killed)" } else { "" },
                    f.why,
                    f.first_line
                );
            }
        }
    }
    if let Some(file) = tsv {
        let clean = |s: &str| s.replace(['\t', '\n', '\r'], " ");
        let mut text = String::from("command\tseed\tfile\tmutation\texit\treason\tfirst line\n");
        for f in rows.iter().flat_map(|r| &r.failures) {
            text += &format!(
                "{}\t{}\t{}\t{}\t{}\t{}\t{}\n",
                f.kind,
                f.seed.unwrap_or(0),
                clean(&f.file),
                clean(&f.mutation),
                if f.timed_out {
                    "killed (hang)".to_string()
                } else {
                    f.code.map_or("signal".to_string(), |c| c.to_string())
                },
                clean(&f.why),
                clean(&f.first_line)
            );
        }
        std::fs::write(&file, text).expect("the TSV file is written");
    }
    let failed = rows.iter().any(|r| !r.failures.is_empty());
    std::process::exit(i32::from(failed));
}

#[cfg(not(unix))]
fn main() {
    eprintln!("fuzz_inputs needs a Unix system (FIFOs, links, running as nobody)");
    std::process::exit(2);
}
