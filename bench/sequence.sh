#!/usr/bin/env bash
# The cost of a dynamic exam against static exams of the same size (issue 31): one sequence of
# 100 frames of scenarios/dynamic_knee.toml (binary mode, 1024², both beamlines, 1 ms pulses of 5
# poses) against the same scenario as 100 static exams (no [sequence], no motion, 100 runs): the
# same number of images of the same size. The two run alternately, A B A B …, BENCH_REPEATS pairs
# (default 3), output on /dev/shm when it exists; it prints each run's wall and CPU time (user +
# system, from /usr/bin/time) and each pair's ratio A/B, then the medians.
#
# With SEQUENCE_TABLE=FILE it also writes the result as a Markdown table there, stamped by
# bench/stamp.py (docs/src/results/tables/sequence-speed.md is made so).
# Usage: bench/sequence.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --locked --quiet
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
bin="$target_dir/release/rsasim"
root=$(mktemp -d "${TMPDIR:-/tmp}/rsasim-seq.XXXXXX")
[[ -d /dev/shm ]] && root=$(mktemp -d /dev/shm/rsasim-seq.XXXXXX)
trap 'rm -rf "$root"' EXIT
# Both scenarios beside the shipped one, so that its model paths resolve.
seq_toml=scenarios/.bench-sequence.toml
static_toml=scenarios/.bench-static.toml
trap 'rm -rf "$root" "$seq_toml" "$static_toml"' EXIT
python3 - "$seq_toml" "$static_toml" <<'EOF'
import re, sys
text = open("scenarios/dynamic_knee.toml").read()
one = text.replace("runs_per_level = 5", "runs_per_level = 1")
assert one != text, "dynamic_knee.toml: runs_per_level = 5 not found"
open(sys.argv[1], "w").write(one)
static = re.sub(r"\n\[sequence\]\n(?:[a-z_]+ = [^\n]*\n)+", "\n", one)
static = re.sub(r"\n\[\[sequence\.joints\]\]\n(?:[a-z_]+ = [^\n]*\n)+", "\n", static)
static = re.sub(r"\n\[phantoms\.motion\]\nkeyframes = \[\n(?:[^\n]*\n)*?\]\n", "\n", static)
static = static.replace("runs_per_level = 1", "runs_per_level = 100")
assert "[sequence" not in static and "keyframes = [" not in static
open(sys.argv[2], "w").write(static)
EOF
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
echo "A: one sequence of 100 frames; B: 100 static exams; $("$bin" --version)"
load_start=$(python3 bench/stamp.py load)
wall_ratios=() cpu_ratios=() a_walls=() b_walls=()
for ((i = 1; i <= ${BENCH_REPEATS:-3}; i++)); do
    for side in A B; do
        toml=$seq_toml
        [[ $side == B ]] && toml=$static_toml
        rm -rf "$root/out"
        /usr/bin/time -o "$root/time" -f "%e %U %S" "$bin" "$toml" --out "$root/out" >/dev/null 2>&1
        read -r w user sys <"$root/time"
        cpu=$(python3 -c "print(round($user + $sys, 2))")
        echo "pair $i $side: wall $w s, CPU $cpu s, $(find "$root/out/runs" -name '*.tiff' | wc -l) images"
        if [[ $side == A ]]; then a_wall=$w a_cpu=$cpu; else b_wall=$w b_cpu=$cpu; fi
    done
    a_walls+=("$a_wall") b_walls+=("$b_wall")
    wall_ratios+=("$(python3 -c "print(f'{$a_wall / $b_wall:.3f}')")")
    cpu_ratios+=("$(python3 -c "print(f'{$a_cpu / $b_cpu:.3f}')")")
    echo "pair $i: A/B wall ${wall_ratios[-1]}, CPU ${cpu_ratios[-1]}"
done
median() { printf '%s\n' "$@" | python3 -c 'import statistics, sys; print(round(statistics.median(float(x) for x in sys.stdin), 3))'; }
wall=$(median "${wall_ratios[@]}") cpu=$(median "${cpu_ratios[@]}")
echo "median A/B over ${#wall_ratios[@]} pairs: wall $wall, CPU $cpu"
if [[ -n ${SEQUENCE_TABLE:-} ]]; then
    {
        python3 bench/stamp.py line --command "SEQUENCE_TABLE=$SEQUENCE_TABLE bench/sequence.sh" --bin "$bin" --load-start "$load_start"
        echo
        echo "| | median wall (s) | A/B wall (median of ${#wall_ratios[@]} pairs) | A/B CPU |"
        echo "|---|---:|---:|---:|"
        echo "| A: one sequence of 100 frames, 1 ms pulses | $(median "${a_walls[@]}") | $wall | $cpu |"
        echo "| B: 100 static exams | $(median "${b_walls[@]}") | 1 | 1 |"
    } >"$SEQUENCE_TABLE"
fi
