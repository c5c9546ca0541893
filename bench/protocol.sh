#!/usr/bin/env bash
# Wall time and peak memory of the full biplanar protocol (100 runs × 4 images, TIFF + EXR),
# then the per-image cost by stage. Usage: bench/protocol.sh [scenario.toml]
set -euo pipefail
cd "$(dirname "$0")/.."
scenario=${1:-scenarios/biplanar.toml}
out=$(mktemp -d)/protocol
cargo build --release --quiet
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
/usr/bin/time -f "wall %e s, peak RSS %M kB, CPU %P" ./target/release/rsasim "$scenario" --out "$out"
du -sh "$out"
rm -rf "$(dirname "$out")"
cargo bench --quiet --bench images 2>/dev/null
