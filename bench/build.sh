#!/usr/bin/env bash
# How long the first `cargo test` builds, before and after a change, on this machine:
#
#   bench/build.sh [BEFORE [AFTER]]     (default: 8da942f, the 0.6.0 release, and HEAD)
#
# For each commit, a fresh worktree and an empty target folder; dependencies are fetched first
# (`cargo fetch --locked`), so downloads are not timed. Then, timed: `cargo test --no-run
# --locked`, the build every fresh clone does before its first test. The two commits alternate
# REPEATS times (default 1: one build takes minutes), the order swapped every repeat. Then, in
# AFTER's worktree, a report module (EVALUATE_FILE) is touched and the test build run again: the
# crates it recompiles are listed, and the script fails if the core or the files crate is among
# them. Prints the machine, its load before each build, every wall time and the ratio
# AFTER / BEFORE of the medians; writes the same to bench/results/build.md (ignored by git).
set -euo pipefail
cd "$(dirname "$0")/.."
before=${1:-8da942f}
after=${2:-HEAD}
repeats=${REPEATS:-1}
touched=${EVALUATE_FILE:-crates/evaluate/src/report/markdown.rs}
results=bench/results
mkdir -p "$results"
out=$results/build.md
work=$(mktemp -d "${TMPDIR:-/tmp}/rsasim-build.XXXXXX")
cleanup() {
    git worktree remove --force "$work/before" 2>/dev/null || true
    git worktree remove --force "$work/after" 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT
before_sha=$(git rev-parse --short "$before")
after_sha=$(git rev-parse --short "$after")
git worktree add --quiet --detach "$work/before" "$before_sha"
git worktree add --quiet --detach "$work/after" "$after_sha"
{
    echo "# First \`cargo test --no-run --locked\`: $before_sha against $after_sha"
    echo
    echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(free -g | awk '/Mem:/ {print $2}') GiB; $(rustc --version); $(date -u +%Y-%m-%dT%H:%MZ)"
    echo
} | tee "$out"
(cd "$work/before" && cargo fetch --locked --quiet)
(cd "$work/after" && cargo fetch --locked --quiet)

now() { date +%s.%N; }
build() { # build NAME: one timed first test build in NAME's worktree, from an empty target
    local name=$1 t0 t1
    rm -rf "$work/target-$name"
    echo "load before $name: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$out" >&2
    t0=$(now)
    (cd "$work/$name" && CARGO_TARGET_DIR="$work/target-$name" cargo test --no-run --locked --quiet) \
        >"$work/$name.log" 2>&1 || {
        cat "$work/$name.log"
        echo "bench/build.sh: the test build of $name failed" >&2
        exit 1
    }
    t1=$(now)
    echo "$t1 - $t0" | bc
}
befores=()
afters=()
for i in $(seq "$repeats"); do
    if ((i % 2)); then order=(before after); else order=(after before); fi
    for name in "${order[@]}"; do
        s=$(build "$name")
        printf '| repeat %d | %s (%s) | %.0f s |\n' "$i" "$name" \
            "$([[ $name == before ]] && echo "$before_sha" || echo "$after_sha")" "$s" | tee -a "$out"
        if [[ $name == before ]]; then befores+=("$s"); else afters+=("$s"); fi
    done
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
mb=$(median "${befores[@]}")
ma=$(median "${afters[@]}")
printf '\nmedian: %s %.0f s, %s %.0f s; ratio %s / %s = %.2f\n' \
    "$before_sha" "$mb" "$after_sha" "$ma" "$after_sha" "$before_sha" "$(echo "$ma / $mb" | bc -l)" | tee -a "$out"

# What touching a report module recompiles (AFTER only: BEFORE is one crate).
if [[ -f $work/after/$touched ]]; then
    touch "$work/after/$touched"
    (cd "$work/after" && CARGO_TARGET_DIR="$work/target-after" cargo test --no-run --locked) \
        >"$work/touch.log" 2>&1
    recompiled=$(grep -o 'Compiling [a-z_-]*' "$work/touch.log" | cut -d' ' -f2 | sort -u | xargs)
    printf '\nafter touching %s: recompiled %s\n' "$touched" "${recompiled:-nothing}" | tee -a "$out"
    for wall in rsasim-core rsasim-files; do
        if grep -qw "$wall" <<<"$recompiled"; then
            echo "bench/build.sh: touching $touched recompiled $wall" >&2
            exit 1
        fi
    done
fi
echo "written: $out"
