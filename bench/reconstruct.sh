#!/usr/bin/env bash
# Time per run of the reference RSA program on one core: calibration + marker-based RSA, and
# calibration + model-based (silhouette) RSA, over every run of an output folder.
# Usage: bench/reconstruct.sh [OUT]   (default: simulate scenarios/biplanar.toml into a temp folder)
# The binary is $RSASIM_BIN, else the release build in cargo's target folder (built first).
# bench/printed.py reconstruct-speed runs it and writes docs/src/results/tables/reconstruct-speed.md.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${RSASIM_BIN:-}
if [[ -z $bin ]]; then
    cargo build --release --locked --quiet --bin rsasim
    bin=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')/release/rsasim
fi
out=${1:-}
if [[ -z "$out" ]]; then
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    out=$tmp/biplanar
    "$bin" scenarios/biplanar.toml --out "$out" >/dev/null 2>&1
fi
runs=$(find "$out/runs" -mindepth 1 -maxdepth 1 -type d | wc -l)
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs); $runs runs; one thread"
for method in markers silhouette; do
    start=$(date +%s.%N)
    RAYON_NUM_THREADS=1 /usr/bin/time -f "  peak RSS %M kB" "$bin" reconstruct "$out" --model-method "$method" 2>&1 \
        | grep -v "^rsasim reconstruct" || true
    end=$(date +%s.%N)
    awk -v s="$start" -v e="$end" -v n="$runs" -v m="$method" \
        'BEGIN { printf "%-10s %.1f s for %d runs: %.3f s per run on one core\n", m, e - s, n, (e - s) / n }'
done
