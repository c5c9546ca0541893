# Sourced by bench/run.sh and bench/attenuation.sh: the peers' environment.
#
#   peers_env WORK PYTHON   -> sets $venv (WORK/venv) with numpy, embreex and gvxr, and installs
#                              the Debian packages gvxr needs when run as root; returns 1 (with
#                              a message) when there is no usable virtual environment.
#   machine_info            -> prints the commit, date, CPU, memory and rustc of this run.

machine_info() {
    local commit
    commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
    git diff --quiet HEAD 2>/dev/null || commit="$commit (+ local changes)"
    echo "commit: $commit"
    echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) logical CPUs"
    echo "memory: $(awk '/MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo)"
    echo "rustc: $(rustc --version)"
}

peers_env() {
    local work=$1 python=$2
    # gvxr's wheel bundles libEGL (glvnd) but needs Mesa's EGL vendor and llvmpipe, and a few
    # libxcb libraries it links against.
    local apt_packages=(libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 libgl1
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
        return 1
    fi
    "$venv/bin/pip" install -q --upgrade pip >/dev/null 2>&1 || true
    if ! "$venv/bin/pip" install -q numpy >"$work/pip-numpy.log" 2>&1; then
        echo "error: pip install numpy failed; no peers:"
        tail -n 5 "$work/pip-numpy.log"
        return 1
    fi
    local peer
    for peer in embreex gvxr; do
        if "$venv/bin/pip" install -q "$peer" >"$work/pip-$peer.log" 2>&1; then
            echo "installed $("$venv/bin/pip" show "$peer" | awk '/^Version/ {print $2}' | sed "s/^/$peer /")"
        else
            echo "error: pip install $peer failed (tail of the log):"
            tail -n 5 "$work/pip-$peer.log"
        fi
    done
}
