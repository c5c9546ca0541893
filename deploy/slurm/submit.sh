#!/bin/bash
# Submits a scenario as an array of N shard tasks and the merge job that runs when all succeeded.
#
#   deploy/slurm/submit.sh SCENARIO N SHARDS_DIR OUT [RSASIM ARGS...]
#
# e.g. deploy/slurm/submit.sh scenarios/biplanar.toml 8 /scratch/biplanar-shards /scratch/biplanar
# Prints the two job ids. Extra sbatch options go in SBATCH_* variables (e.g.
# SBATCH_PARTITION=short), which sbatch reads itself.
set -euo pipefail
if [ $# -lt 4 ]; then
    echo "usage: $0 SCENARIO N SHARDS_DIR OUT [RSASIM ARGS...]" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
scenario=$1
count=$2
shards=$3
out=$4
shift 4
case $count in
    '' | *[!0-9]* | 0) echo "N must be a whole number of shards, at least 1 (got '$count')" >&2; exit 2 ;;
esac
array=$(sbatch --parsable --array=0-$((count - 1)) "$here/rsasim-shard.sbatch" "$scenario" "$shards" "$@")
array=${array%%;*}
merge=$(sbatch --parsable --dependency=afterok:"$array" "$here/rsasim-merge.sbatch" "$shards" "$count" "$out")
merge=${merge%%;*}
echo "array job $array ($count shard tasks), merge job $merge -> $out"
