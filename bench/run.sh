#!/usr/bin/env bash
# rsasim's benchmark suite, peers included, in one command (see docs/src/development/benchmarks.md):
#
#   bench/run.sh [--no-criterion] [--no-protocol] [--no-peers] [--venv DIR]
#
# 1. builds the release binary;
# 2. runs the criterion benches (`cargo bench --bench projector`) and the per-stage image bench
#    (`cargo bench --bench images`);
# 3. runs the full scenarios/biplanar.toml protocol under /usr/bin/time (bench/protocol.sh);
# 4. installs the peers into a throwaway virtual environment (PyPI: numpy, embreex, gvxr; Debian:
#    the Mesa EGL and libxcb packages gvxr needs, when run as root), or uses --venv DIR where
#    they are installed already, exports the scenes (examples/bench_scene.rs) and measures the
#    peers (bench/peers.py);
# 5. prints the table of medians and ratios ours / peer.
#
# Results go to bench/results/ (ignored by git): summary.md and summary.json, the peers' JSON,
# the logs. `bench/printed.py binary-peers` runs this and writes the book's tables from them.
# Environment: BENCH_REPEATS (peers' repeats, default 7), BENCH_PYTHON (default python3).
set -euo pipefail
cd "$(dirname "$0")/.."

criterion=1 protocol=1 peers=1 venv=""
while (($#)); do
    arg=$1
    shift
    case $arg in
    --no-criterion) criterion=0 ;;
    --no-protocol) protocol=0 ;;
    --no-peers) peers=0 ;;
    --venv)
        venv=${1:?--venv needs a folder}
        shift
        [[ -x $venv/bin/python ]] || {
            echo "bench/run.sh: --venv $venv has no bin/python" >&2
            exit 2
        }
        ;;
    -h | --help)
        sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'
        exit 0
        ;;
    *)
        echo "bench/run.sh: unknown option $arg (see --help)" >&2
        exit 2
        ;;
    esac
done

repeats=${BENCH_REPEATS:-7}
python=${BENCH_PYTHON:-python3}
results=bench/results
mkdir -p "$results"
work=$(mktemp -d "${TMPDIR:-/tmp}/rsasim-bench.XXXXXX")
trap 'rm -rf "$work"' EXIT
source bench/peers_env.sh
say() { printf '\n== %s\n' "$*"; }

target_dir=$(cargo metadata --format-version 1 --no-deps |
    "$python" -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
machine_info | tee "$results/machine.txt"

say "1. release build"
cargo build --release --quiet --bin rsasim --example bench_scene

if ((criterion)); then
    say "2. criterion benches (cargo bench --bench projector), then the per-stage image bench"
    cargo bench --bench projector 2>&1 | tee "$results/projector.log"
    cargo bench --quiet --bench images 2>&1 | tee "$results/images.log"
fi

if ((protocol)); then
    say "3. full protocol: scenarios/biplanar.toml under /usr/bin/time"
    if [[ -x /usr/bin/time ]]; then
        PROTOCOL_JSON="$results/protocol.json" PROTOCOL_SKIP_IMAGES=1 bench/protocol.sh 2>&1 |
            tee "$results/protocol.log"
    else
        echo "skipped: /usr/bin/time is missing (Debian package 'time')"
    fi
fi

scenes=$work/scenes
if ((peers)); then
    say "4. peers: scene export, throwaway venv, Embree (embreex) and gVirtualXray (gvxr)"
    "$target_dir/release/examples/bench_scene" "$scenes"
    if [[ -z $venv ]]; then
        peers_env "$work" "$python" || peers=0
    fi
fi
if ((peers)); then
    "$venv/bin/python" bench/peers.py embree "$scenes" --repeats "$repeats" 2>&1 | tee "$results/embree.log" ||
        echo "error: the Embree peer failed (see above)"
    # gvxr logs every OpenGL call to stdout; keep it in the log, show only its own lines.
    if "$venv/bin/python" bench/peers.py gvxr "$scenes" --repeats "$repeats" >"$results/gvxr.log" 2>&1; then
        grep -E '^(gvxr |wrote )' "$results/gvxr.log"
    else
        echo "error: the gVirtualXray peer failed; the last lines of $results/gvxr.log:"
        tail -n 15 "$results/gvxr.log"
    fi
    cp "$scenes"/*.json "$results/" 2>/dev/null || true
fi

say "5. summary (ours / peer; criterion medians, peers' medians of $repeats)"
mkdir -p "$scenes"
cp "$results"/{embree,gvxr}.json "$scenes/" 2>/dev/null || true
protocol_arg=()
[[ -f $results/protocol.json ]] && protocol_arg=(--protocol "$results/protocol.json")
"$python" bench/peers.py summary "$scenes" --criterion "$target_dir/criterion" \
    "${protocol_arg[@]}" --markdown "$results/summary.md" >/dev/null
cp "$scenes/summary.json" "$results/"
cat "$results/machine.txt" "$results/summary.md"
echo
echo "results: $results/ (summary.md, *.json, *.log)"
