#!/usr/bin/env bash
# Time of `rsasim evaluate` on the shipped clinical study (scenarios/tka_migration.toml: 20
# patients × 5 exams), every table and plot of the report: the median of REPEATS runs (default
# 5), after simulating and reconstructing the study once.
# Usage: bench/study.sh [OUT]   (OUT: an already reconstructed output of tka_migration.toml)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
bin=./target/release/rsasim
repeats=${REPEATS:-5}
out=${1:-}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if [[ -z "$out" ]]; then
    out=$tmp/tka
    "$bin" scenarios/tka_migration.toml --out "$out" >/dev/null 2>&1
    "$bin" reconstruct "$out" >/dev/null 2>&1
fi
measured=$(cd "$out/runs" && ls -1 "$(ls -1 | head -1)" | grep -m1 '^measured.*\.json$')
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs); $out, $measured"
times=()
for i in $(seq 1 "$repeats"); do
    start=$(date +%s.%N)
    "$bin" evaluate "$out" --measured "$measured" --report "$tmp/report-$i" >/dev/null 2>&1
    end=$(date +%s.%N)
    times+=("$(awk -v s="$start" -v e="$end" 'BEGIN { printf "%.3f", e - s }')")
done
printf '%s\n' "${times[@]}" | sort -n | awk -v n="$repeats" '
    { t[NR] = $1 } END { printf "evaluate on the study: median %.3f s over %d runs (min %.3f s, max %.3f s)\n", t[int((n + 1) / 2)], n, t[1], t[n] }'
