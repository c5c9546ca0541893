#!/usr/bin/env bash
# Attenuation mode against its peers, in one command (see docs/src/results/peers.md):
#
#   bench/attenuation.sh [--venv DIR]
#
# 1. builds examples/attenuation_bench.rs (release) and runs it: times attenuation::render for
#    bench/attenuation/mono.toml (femoral component, CoCr F75, 60 keV), poly.toml (80 kVp,
#    2.5 mm Al), realistic_mono.toml and realistic_poly.toml (issue 11's scene: component, cortical
#    and cancellous femur, soft tissue, 6 tantalum beads, nested; biplanar_realistic's run-0
#    geometry; 60 keV / 85 kVp in 40 bins) and scenarios/biplanar_realistic.toml itself, and
#    exports the scenes (every part's surface, nesting, rsasim's path lengths per material,
#    images, spectrum TSV, μ); ATTENUATION_BENCH_ONLY=mono,poly,... picks scenes;
# 2. sets up the peers (as bench/run.sh: throwaway venv with numpy, embreex, gvxr; Debian
#    packages for gvxr when root), or uses --venv DIR where they are installed already;
# 3. bench/peers_attenuation.py gvxr, embree and summary: per-pixel transmission rsasim vs
#    gVXR (component mono and poly, realistic mono with μ net of nesting; realistic poly is
#    timed only), path lengths rsasim vs Embree (all hits), and the timing table ours / peer.
#
# Results go to bench/results/attenuation/ (ignored by git): summary.md, the JSON, the logs.
# Environment: BENCH_REPEATS (default 5), BENCH_PYTHON (default python3).
set -euo pipefail
cd "$(dirname "$0")/.."

venv=""
while (($#)); do
    case $1 in
    --venv) venv=${2:?--venv needs a folder}; shift 2 ;;
    -h | --help)
        sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'
        exit 0
        ;;
    *)
        echo "bench/attenuation.sh: unknown option $1 (see --help)" >&2
        exit 2
        ;;
    esac
done

repeats=${BENCH_REPEATS:-5}
python=${BENCH_PYTHON:-python3}
results=bench/results/attenuation
mkdir -p "$results"
work=$(mktemp -d "${TMPDIR:-/tmp}/rsasim-attenuation.XXXXXX")
trap 'rm -rf "$work"' EXIT
source bench/peers_env.sh
say() { printf '\n== %s\n' "$*"; }

load() { echo "load average ($1): $(cut -d' ' -f1-3 /proc/loadavg) (1, 5, 15 min; $(nproc) CPUs)"; }
{ machine_info; load start; } | tee "$results/machine.txt"
target_dir=$(cargo metadata --format-version 1 --no-deps |
    "$python" -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')

say "1. release build, rsasim's timings and the scene export"
cargo build --release --quiet --example attenuation_bench
scenes=$work/scenes
"$target_dir/release/examples/attenuation_bench" "$scenes" "$repeats" | tee "$results/rsasim.log"

say "2. peers"
if [[ -z $venv ]]; then
    peers_env "$work" "$python" || { echo "no peers: summary of rsasim alone"; venv=""; }
fi
py=${venv:+$venv/bin/python}
py=${py:-$python}
"$py" bench/peers_attenuation.py embree "$scenes" --repeats "$repeats" 2>&1 | tee "$results/embree.log" ||
    echo "error: the Embree peer failed (see above)"
# gvxr logs every OpenGL call to stdout; keep it in the log, show only its own lines.
if "$py" bench/peers_attenuation.py gvxr "$scenes" --repeats "$repeats" >"$results/gvxr.log" 2>&1; then
    grep -E '^(gvxr |wrote )' "$results/gvxr.log"
else
    echo "error: the gVirtualXray peer failed; the last lines of $results/gvxr.log:"
    tail -n 15 "$results/gvxr.log"
fi

load end | tee -a "$results/machine.txt"

say "3. summary"
"$py" bench/peers_attenuation.py summary "$scenes" --markdown "$results/summary.md" >/dev/null
cp "$scenes"/*.json "$results/"
cat "$results/machine.txt" "$results/summary.md"
echo
echo "results: $results/ (summary.md, *.json, *.log)"
