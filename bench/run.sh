#!/usr/bin/env bash
# rsasim's benchmark suite, peers included, in one command (see BENCHMARKS.md):
#
#   bench/run.sh [--no-criterion] [--no-protocol] [--no-peers]
#
# 1. builds the release binary;
# 2. runs the criterion benches (`cargo bench --bench projector`) and the per-stage image bench
#    (`cargo bench --bench images`);
# 3. runs the full scenarios/biplanar.toml protocol under /usr/bin/time (bench/protocol.sh);
# 4. installs the peers into a throwaway virtual environment (PyPI: numpy, embreex, gvxr; Debian:
#    the Mesa EGL and libxcb packages gvxr needs, when run as root), exports the scenes
#    (examples/bench_scene.rs) and measures the peers (bench/peers.py);
# 5. prints the table of medians and ratios ours / peer.
#
# Results go to bench/results/ (ignored by git): summary.md, the peers' JSON, the logs.
# Environment: BENCH_REPEATS (peers' repeats, default 7), BENCH_PYTHON (default python3).
set -euo pipefail
cd "$(dirname "$0")/.."

criterion=1 protocol=1 peers=1
for arg in "$@"; do
    case $arg in
    --no-criterion) criterion=0 ;;
    --no-protocol) protocol=0 ;;
    --no-peers) peers=0 ;;
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
say() { printf '\n== %s\n' "$*"; }

target_dir=$(cargo metadata --format-version 1 --no-deps |
    "$python" -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
git diff --quiet HEAD 2>/dev/null || commit="$commit (+ local changes)"
{
    echo "commit: $commit"
    echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) logical CPUs"
    echo "memory: $(awk '/MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo)"
    echo "rustc: $(rustc --version)"
} | tee "$results/machine.txt"

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
    # gvxr's wheel bundles libEGL (glvnd) but needs Mesa's EGL vendor and llvmpipe, and a few
    # libxcb libraries it links against.
    apt_packages=(libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 libgl1
        libxcb-composite0 libxcb-ewmh2 libxcb-icccm4 libxcb-keysyms1 libxcb-res0 libxcb-xinerama0)
    if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
        echo "installing Debian packages for gvxr: ${apt_packages[*]}"
        if ! DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${apt_packages[@]}" >"$work/apt.log" 2>&1; then
            apt-get update -q >>"$work/apt.log" 2>&1 || true
            DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${apt_packages[@]}" >>"$work/apt.log" 2>&1 || {
                echo "warning: apt-get install failed; gvxr may not start. Tail of the log:"
                tail -n 5 "$work/apt.log"
            }
        fi
    else
        echo "not root (or no apt-get): not installing ${apt_packages[*]}; gvxr needs them"
    fi
    venv=$work/venv
    if ! "$python" -m venv "$venv" >"$work/venv.log" 2>&1; then
        echo "error: cannot create a virtual environment with $python (Debian: python3-venv); no peers:"
        tail -n 5 "$work/venv.log"
        peers=0
    fi
fi
if ((peers)); then
    "$venv/bin/pip" install -q --upgrade pip >/dev/null 2>&1 || true
    "$venv/bin/pip" install -q numpy >"$work/pip-numpy.log" 2>&1 ||
        { echo "error: pip install numpy failed; no peers:"; tail -n 5 "$work/pip-numpy.log"; peers=0; }
fi
if ((peers)); then
    for peer in embreex gvxr; do
        if "$venv/bin/pip" install -q "$peer" >"$work/pip-$peer.log" 2>&1; then
            echo "installed $("$venv/bin/pip" show "$peer" | awk '/^Version/ {print $2}' | sed "s/^/$peer /")"
        else
            echo "error: pip install $peer failed (tail of the log):"
            tail -n 5 "$work/pip-$peer.log"
        fi
    done
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
cat "$results/machine.txt" "$results/summary.md"
echo
echo "results: $results/ (summary.md, *.json, *.log)"
