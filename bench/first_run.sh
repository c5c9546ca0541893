#!/usr/bin/env bash
# What a first run costs on a fresh clone (docs/src/tutorial/install.md): a local clone of HEAD
# with an empty target folder and an empty crate cache (CARGO_HOME in a temporary folder), then
#   cargo fetch --locked                                  (downloads; timed, not in the table)
#   cargo build --release --locked                        (timed)
#   target/release/rsasim scenarios/biplanar.toml         (timed; the output's size)
#   cargo test --locked --no-run, then cargo test --locked (timed each)
# and the sizes of target/release, target/debug and the crate sources. It prints key=value lines;
# bench/printed.py first-run-cost runs it and writes docs/src/results/tables/first-run-cost.md.
# It needs the network (crates.io) and about 10 GB of disk; CARGO_BUILD_JOBS is left as it is.
# Usage: bench/first_run.sh
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/rsasim-first-run.XXXXXX")
trap 'rm -rf "$work"' EXIT
# mktemp makes the folder 0700; run as root, the tests' received-folder mutants run as `nobody`,
# who must be able to reach the binary (as in any checkout a fresh machine clones).
chmod 755 "$work"
git clone --quiet --no-hardlinks "$root" "$work/clone"
cd "$work/clone"
unset CARGO_TARGET_DIR
export CARGO_HOME=$work/cargo-home
[[ -d ${HOME:-/nonexistent}/.cargo/bin ]] && export PATH=$HOME/.cargo/bin:$PATH
timed() { # NAME COMMAND…: prints NAME_s=SECONDS
    local name=$1 start end
    shift
    start=$(date +%s.%N)
    "$@" >"$work/$name.log" 2>&1 || { echo "$* failed; tail of $work/$name.log:" >&2; tail -n 20 "$work/$name.log" >&2; exit 1; }
    end=$(date +%s.%N)
    echo "${name}_s=$(python3 -c "print(round($end - $start, 1))")"
}
gb() { du -sb "$1" | awk '{printf "%.2f", $1 / 1e9}'; }
echo "commit=$(git rev-parse --short=7 HEAD)"
timed fetch cargo fetch --locked
timed build_release cargo build --release --locked
timed run target/release/rsasim scenarios/biplanar.toml --out "$work/out"
echo "output_gb=$(gb "$work/out")"
rm -rf "$work/out"
echo "target_release_gb=$(gb target/release)"
echo "registry_gb=$(gb "$CARGO_HOME/registry")"
echo "version=$(target/release/rsasim --version)"
timed build_test cargo test --locked --no-run
timed test cargo test --locked
echo "target_debug_gb=$(gb target/debug)"
