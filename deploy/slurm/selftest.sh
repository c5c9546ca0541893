#!/bin/bash
# SLURM self-test: a real single-node SLURM cluster on localhost runs a 4-task array job of a
# small scenario with deploy/slurm/rsasim-shard.sbatch and the dependent merge job of
# deploy/slurm/rsasim-merge.sbatch; the merged folder must equal the single-machine run byte for
# byte (every file, manifest.json included) and verify. At the same time it runs a small sweep
# (3 points × 3 runs) as a 3-task array of deploy/slurm/rsasim-sweep-shard.sbatch, all tasks
# writing into one sweep folder, and the dependent merge-and-evaluate job of
# deploy/slurm/rsasim-sweep-merge.sbatch; the sweep folder must equal the unsharded
# `rsasim sweep --evaluate` byte for byte (every file but the shards and the lock files).
#
#   deploy/slurm/selftest.sh            (as root: installs slurm-wlm and munge when missing)
#
# Everything it starts (munged, slurmctld, slurmd) runs from a temporary folder with its own
# configuration, key, sockets and ports, and is stopped (by process id) when the script ends,
# whatever happens. RSASIM names the rsasim binary (default: target/debug/rsasim, built with
# `cargo build --locked` when missing). SELFTEST_TIMEOUT bounds the wait for the jobs (seconds,
# default 300).
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
cd "$repo"
scenario=tests/scenarios/shards.toml
sweep=tests/scenarios/sweeps/small_angle.toml
timeout=${SELFTEST_TIMEOUT:-300}

if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
    if [ "$(id -u)" -ne 0 ]; then
        echo "selftest: needs slurm-wlm and munge: run as root, or apt-get install slurm-wlm munge" >&2
        exit 1
    fi
    apt-get update
    DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends slurm-wlm munge
fi
if [ "$(id -u)" -ne 0 ]; then
    echo "selftest: run as root (slurmd starts the jobs as root here)" >&2
    exit 1
fi
rsasim=${RSASIM:-$repo/target/debug/rsasim}
if [ ! -x "$rsasim" ]; then
    cargo build --locked
fi
rsasim=$(cd "$(dirname "$rsasim")" && pwd)/$(basename "$rsasim")

work=$(mktemp -d /tmp/rsasim-slurm-selftest.XXXXXX)
chmod 755 "$work"
pids=()
cleanup() {
    local status=$?
    for pid in "${pids[@]}"; do
        kill "$pid" 2>/dev/null || true
    done
    for pid in "${pids[@]}"; do
        for _ in $(seq 50); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.1
        done
        kill -9 "$pid" 2>/dev/null || true
    done
    if [ $status -ne 0 ]; then
        echo "selftest: FAILED; the daemons' logs:" >&2
        for log in "$work"/*.log "$work"/jobs/*.log; do
            [ -f "$log" ] && { echo "--- $log" >&2; tail -n 30 "$log" >&2; }
        done
    fi
    rm -rf "$work"
    exit $status
}
trap cleanup EXIT

# Free TCP ports for slurmctld and slurmd.
free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}
ctld_port=$(free_port)
slurmd_port=$(free_port)
while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port=$(free_port); done

# munge: its own key and socket.
mkdir -p "$work/munge" "$work/state" "$work/spool" "$work/jobs"
chmod 711 "$work/munge"
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge/munge.key"
munged --foreground --force --key-file="$work/munge/munge.key" \
    --socket="$work/munge/munge.socket" --pid-file="$work/munge/munged.pid" \
    --log-file="$work/munged.log" --seed-file="$work/munge/munged.seed" \
    >"$work/munged.out.log" 2>&1 &
pids+=($!)

host=$(hostname -s)
cpus=$(nproc)
cat >"$work/slurm.conf" <<CONF
ClusterName=rsasimselftest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$work/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
ReturnToService=2
MinJobAge=600
NodeName=rsasimnode NodeAddr=127.0.0.1 NodeHostname=$host CPUs=$cpus State=UNKNOWN
PartitionName=selftest Nodes=rsasimnode Default=YES MaxTime=INFINITE State=UP
CONF
# An empty cgroup.conf keeps slurmd from looking for cgroup settings it does not use here.
: >"$work/cgroup.conf"
export SLURM_CONF=$work/slurm.conf

for _ in $(seq 50); do [ -S "$work/munge/munge.socket" ] && break; sleep 0.1; done
slurmctld -D -i -f "$SLURM_CONF" >"$work/slurmctld.out.log" 2>&1 &
pids+=($!)
slurmd -D -N rsasimnode -f "$SLURM_CONF" >"$work/slurmd.out.log" 2>&1 &
pids+=($!)

deadline=$((SECONDS + 60))
until sinfo -h -N -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; do
    if [ $SECONDS -ge $deadline ]; then
        echo "selftest: the node did not become idle within 60 s" >&2
        sinfo -N -l >&2 || true
        exit 1
    fi
    sleep 0.5
done
echo "selftest: single-node SLURM up ($(sinfo -h -N -o '%N %T %c CPUs'))"

shards=$work/shards
merged=$work/merged
export RSASIM=$rsasim
export SBATCH_CHDIR=$work/jobs
# 2 tasks at a time on this node's CPUs; each takes one CPU.
array=$(sbatch --parsable --chdir="$work/jobs" --cpus-per-task=1 --array=0-3 \
    --output="$work/jobs/shard-%a.log" \
    deploy/slurm/rsasim-shard.sbatch "$repo/$scenario" "$shards" --allow-dir "$repo/scenarios/models")
array=${array%%;*}
merge=$(sbatch --parsable --chdir="$work/jobs" --cpus-per-task=1 --dependency=afterok:"$array" \
    --output="$work/jobs/merge.log" deploy/slurm/rsasim-merge.sbatch "$shards" 4 "$merged")
merge=${merge%%;*}
echo "selftest: submitted array job $array (4 tasks) and merge job $merge"
swept=$work/sweep
sweep_array=$(sbatch --parsable --chdir="$work/jobs" --cpus-per-task=1 --array=0-2 \
    --output="$work/jobs/sweep-shard-%a.log" \
    deploy/slurm/rsasim-sweep-shard.sbatch "$repo/$sweep" "$swept")
sweep_array=${sweep_array%%;*}
sweep_merge=$(sbatch --parsable --chdir="$work/jobs" --cpus-per-task=1 --dependency=afterok:"$sweep_array" \
    --output="$work/jobs/sweep-merge.log" deploy/slurm/rsasim-sweep-merge.sbatch "$repo/$sweep" "$swept" 3)
sweep_merge=${sweep_merge%%;*}
echo "selftest: submitted sweep array job $sweep_array (3 tasks) and merge-and-evaluate job $sweep_merge"

deadline=$((SECONDS + timeout))
while [ -n "$(squeue -h -j "$array,$merge,$sweep_array,$sweep_merge" -o '%i' 2>/dev/null)" ]; do
    if [ $SECONDS -ge $deadline ]; then
        echo "selftest: the jobs did not finish within $timeout s" >&2
        squeue -l >&2 || true
        exit 1
    fi
    sleep 1
done
states=$(scontrol -o show job "$array" | grep -o 'JobState=[A-Z_]*' | sort | uniq -c | tr -s ' ')
merge_state=$(scontrol -o show job "$merge" | grep -o 'JobState=[A-Z_]*')
echo "selftest: array tasks:$states; merge: $merge_state"
if [ "$merge_state" != "JobState=COMPLETED" ]; then
    echo "selftest: the merge job did not complete" >&2
    cat "$work"/jobs/*.log >&2 || true
    exit 1
fi
grep -h "rsasim merge:" "$work/jobs/merge.log"
sweep_states=$(scontrol -o show job "$sweep_array" | grep -o 'JobState=[A-Z_]*' | sort | uniq -c | tr -s ' ')
sweep_merge_state=$(scontrol -o show job "$sweep_merge" | grep -o 'JobState=[A-Z_]*')
echo "selftest: sweep array tasks:$sweep_states; sweep merge: $sweep_merge_state"
if [ "$sweep_merge_state" != "JobState=COMPLETED" ]; then
    echo "selftest: the sweep's merge job did not complete" >&2
    cat "$work"/jobs/sweep-*.log >&2 || true
    exit 1
fi
grep -h "rsasim evaluate: sweep" "$work/jobs/sweep-merge.log"

# The single-machine run, then byte for byte.
"$rsasim" "$scenario" --out "$work/single" --allow-dir scenarios/models 2>&1 | tail -n 1
ls "$shards"
diff -r "$work/single" "$merged"
"$rsasim" verify "$merged" | tail -n 1
echo "selftest: PASSED: 4 SLURM array tasks + merge job = the single run, byte for byte ($(find "$merged" -type f | wc -l) files)"

# The unsharded sweep, evaluated, then byte for byte (the shards and the lock files, which hold
# process ids, aside).
"$rsasim" sweep "$sweep" --out "$work/sweep-single" --evaluate 2>&1 | tail -n 1
ls "$swept/shards"/*
diff -r -x shards -x '*.rsasim-lock' "$work/sweep-single" "$swept"
echo "selftest: PASSED: 3 SLURM sweep tasks + merge-and-evaluate job = the unsharded sweep, byte for byte ($(find "$swept" -path "$swept/shards" -prune -o -type f ! -name '*.rsasim-lock' -print | wc -l) files)"
