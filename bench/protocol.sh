#!/usr/bin/env bash
# Wall time and peak memory of the full biplanar protocol (100 runs × 4 images, TIFF + EXR),
# then the per-image cost by stage. Usage: bench/protocol.sh [scenario.toml]
# With PROTOCOL_JSON=FILE it also writes {"wall_s", "peak_rss_kb", "cpu_percent", "bytes"} there
# (bench/run.sh uses that); with PROTOCOL_SKIP_IMAGES=1 it skips the per-image bench.
set -euo pipefail
cd "$(dirname "$0")/.."
scenario=${1:-scenarios/biplanar.toml}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
out=$tmp/protocol
cargo build --release --quiet
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
/usr/bin/time -o "$tmp/time" -f "wall %e s, peak RSS %M kB, CPU %P" \
    "$target_dir/release/rsasim" "$scenario" --out "$out"
cat "$tmp/time"
bytes=$(du -sb "$out" | cut -f1)
du -sh "$out"
if [[ -n ${PROTOCOL_JSON:-} ]]; then
    read -r _ wall _ _ _ rss _ _ cpu < <(tail -n1 "$tmp/time")
    printf '{"scenario": "%s", "wall_s": %s, "peak_rss_kb": %s, "cpu_percent": "%s", "bytes": %s}\n' \
        "$scenario" "$wall" "$rss" "$cpu" "$bytes" >"$PROTOCOL_JSON"
fi
rm -rf "$out"
if [[ -z ${PROTOCOL_SKIP_IMAGES:-} ]]; then
    cargo bench --quiet --bench images 2>/dev/null
fi
