#!/usr/bin/env bash
# Wall time and peak memory of the full biplanar protocol (100 runs × 4 images, TIFF + EXR),
# then the per-image cost by stage. Usage: bench/protocol.sh [scenario.toml]
# With PROTOCOL_JSON=FILE it also writes {"wall_s", "peak_rss_kb", "cpu_percent", "bytes"} there
# (bench/run.sh uses that); with PROTOCOL_SKIP_IMAGES=1 it skips the per-image bench.
#
# A/B against an older build: PROTOCOL_BASELINE=/path/to/old/rsasim bench/protocol.sh runs the
# old binary (A) and this build (B) alternately, A B A B …, PROTOCOL_REPEATS pairs (default 3),
# output in /dev/shm when it exists (else the temporary folder); it prints each run's wall time,
# CPU time (user + system), peak RSS and size, each pair's ratios A/B of wall and CPU time and
# their medians, then stops. Alternating keeps the two under the same load on a shared machine;
# under heavy load the CPU time is the steadier figure. Keep the old binary first, e.g. build
# at the older commit and `cp target/release/rsasim /tmp/rsasim-old`.
set -euo pipefail
cd "$(dirname "$0")/.."
scenario=${1:-scenarios/biplanar.toml}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
out=$tmp/protocol
cargo build --release --quiet
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
if [[ -n ${PROTOCOL_BASELINE:-} ]]; then
    ab_root=$tmp
    [[ -d /dev/shm ]] && ab_root=$(mktemp -d /dev/shm/rsasim-ab.XXXXXX)
    trap 'rm -rf "$tmp" "$ab_root"' EXIT
    new_bin="$target_dir/release/rsasim"
    echo "A: $PROTOCOL_BASELINE ($("$PROTOCOL_BASELINE" --version))"
    echo "B: $new_bin ($("$new_bin" --version))"
    wall_ratios=() cpu_ratios=()
    for ((i = 1; i <= ${PROTOCOL_REPEATS:-3}; i++)); do
        for side in A B; do
            bin=$new_bin
            [[ $side == A ]] && bin=$PROTOCOL_BASELINE
            rm -rf "$ab_root/out"
            /usr/bin/time -o "$tmp/time" -f "%e %U %S %M" "$bin" "$scenario" --out "$ab_root/out" >/dev/null
            read -r w user sys rss <"$tmp/time"
            cpu=$(python3 -c "print(round($user + $sys, 2))")
            echo "pair $i $side: wall $w s, CPU $cpu s, peak RSS $rss kB, $(du -sb "$ab_root/out" | cut -f1) bytes"
            if [[ $side == A ]]; then a_wall=$w a_cpu=$cpu; else b_wall=$w b_cpu=$cpu; fi
        done
        wall_ratios+=("$(python3 -c "print(f'{$a_wall / $b_wall:.3f}')")")
        cpu_ratios+=("$(python3 -c "print(f'{$a_cpu / $b_cpu:.3f}')")")
        echo "pair $i: A/B wall ${wall_ratios[-1]}, CPU ${cpu_ratios[-1]}"
    done
    rm -rf "$ab_root/out"
    median() { printf '%s\n' "$@" | python3 -c 'import statistics, sys; print(round(statistics.median(float(x) for x in sys.stdin), 3))'; }
    echo "median A/B over ${#wall_ratios[@]} pairs: wall $(median "${wall_ratios[@]}"), CPU $(median "${cpu_ratios[@]}")"
    exit 0
fi
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
