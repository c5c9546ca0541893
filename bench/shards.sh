#!/usr/bin/env bash
# Sharding overhead on one machine: the whole protocol as one run against N shards written one
# after the other plus `rsasim merge`, back to back, REPEATS times alternating (default 3), with
# the merged folder checked byte for byte against the single run. Prints every wall time and the
# medians. Usage: bench/shards.sh [scenario.toml] [N]   (default scenarios/biplanar.toml, 2)
# RSASIM=BINARY measures that binary instead of building target/release/rsasim.
set -euo pipefail
cd "$(dirname "$0")/.."
scenario=${1:-scenarios/biplanar.toml}
count=${2:-2}
repeats=${REPEATS:-3}
if [[ -n ${RSASIM:-} ]]; then
    rsasim=$RSASIM
else
    cargo build --release --locked --quiet
    target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
    rsasim=$target_dir/release/rsasim
fi
echo "$("$rsasim" --version)"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs); load $(cut -d' ' -f1-3 /proc/loadavg)"
now() { date +%s.%N; }
singles=()
sharded=()
for i in $(seq "$repeats"); do
    t0=$(now)
    "$rsasim" "$scenario" --out "$tmp/single" 2>/dev/null
    t1=$(now)
    for k in $(seq 0 $((count - 1))); do
        "$rsasim" "$scenario" --shard "$k/$count" --out "$tmp/shards" 2>/dev/null
    done
    t2=$(now)
    "$rsasim" merge "$tmp"/shards/shard-* --out "$tmp/merged" 2>/dev/null
    t3=$(now)
    diff -r "$tmp/single" "$tmp/merged" >/dev/null
    single=$(echo "$t1 - $t0" | bc)
    shards=$(echo "$t2 - $t1" | bc)
    merge=$(echo "$t3 - $t2" | bc)
    total=$(echo "$t3 - $t1" | bc)
    printf 'repeat %d: single %.2f s; %d shards %.2f s + merge %.2f s = %.2f s (%+.1f %%); merged = single, byte for byte\n' \
        "$i" "$single" "$count" "$shards" "$merge" "$total" "$(echo "($total / $single - 1) * 100" | bc -l)"
    singles+=("$single")
    sharded+=("$total")
    rm -rf "$tmp/single" "$tmp/shards" "$tmp/merged"
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
ms=$(median "${singles[@]}")
mt=$(median "${sharded[@]}")
printf 'median: single %.2f s; %d sequential shards + merge %.2f s (%+.1f %%)\n' \
    "$ms" "$count" "$mt" "$(echo "($mt / $ms - 1) * 100" | bc -l)"
