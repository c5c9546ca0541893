#!/bin/bash
# Submits a sweep as an array of N tasks (each one shard of every point) and the job that merges
# and evaluates it when all succeeded.
#
#   deploy/slurm/submit-sweep.sh SWEEP N SWEEP_DIR [RSASIM ARGS...]
#
# e.g. deploy/slurm/submit-sweep.sh scenarios/sweeps/tube_angle.toml 8 /scratch/tube_angle
# Prints the two job ids. Extra sbatch options go in SBATCH_* variables (e.g.
# SBATCH_PARTITION=short), which sbatch reads itself.
set -euo pipefail
if [ $# -lt 3 ]; then
    echo "usage: $0 SWEEP N SWEEP_DIR [RSASIM ARGS...]" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
sweep=$1
count=$2
dir=$3
shift 3
case $count in
    '' | *[!0-9]* | 0) echo "N must be a whole number of tasks, at least 1 (got '$count')" >&2; exit 2 ;;
esac
array=$(sbatch --parsable --array=0-$((count - 1)) "$here/rsasim-sweep-shard.sbatch" "$sweep" "$dir" "$@")
array=${array%%;*}
merge=$(sbatch --parsable --dependency=afterok:"$array" "$here/rsasim-sweep-merge.sbatch" "$sweep" "$dir" "$count" "$@")
merge=${merge%%;*}
echo "array job $array ($count sweep tasks), merge and evaluate job $merge -> $dir"
