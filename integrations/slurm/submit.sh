#!/bin/bash
# Bakes a job on a Slurm farm without probebake-server (docs/cluster.md): the grid in SHARDS
# shards as one array (probebake-shard.sbatch), then their merge (probebake-merge.sbatch) once
# every shard succeeded.
#
#   integrations/slurm/submit.sh JOB.json SHARDS OUT_DIR [sbatch options...]
#
# JOB.json (with its mesh and map files beside it) and OUT_DIR must be in the shared folder, at the
# same path on every node. The volume is OUT_DIR/result.vdb; the parts, progress files and logs
# stay in OUT_DIR. sbatch options (a partition, --cpus-per-task, --time...) go to both jobs.
# PROBEBAKE names the CLI on the nodes (default: probebake in their $PATH). Prints the array's and
# the merge's job ids.
set -euo pipefail
if (($# < 3)); then
  echo "usage: $0 JOB.json SHARDS OUT_DIR [sbatch options...]" >&2
  exit 2
fi
job=$(realpath "$1")
shards=$2
out=$(realpath -m "$3")
shift 3
[[ $shards =~ ^[1-9][0-9]*$ ]] || { echo "submit: SHARDS must be a positive integer" >&2; exit 2; }
here=$(dirname "$(realpath "$0")")
mkdir -p "$out/logs"
export JOB=$job SHARDS=$shards OUT=$out RESULT=$out/result.vdb PROBEBAKE=${PROBEBAKE:-probebake}
array=$(sbatch --parsable --job-name=probebake-shards --array=0-$((shards - 1)) \
  --output="$out/logs/shard-%a.log" --export=ALL "$@" "$here/probebake-shard.sbatch")
array=${array%%;*}
merge=$(sbatch --parsable --job-name=probebake-merge --dependency=afterok:"$array" \
  --kill-on-invalid-dep=yes --output="$out/logs/merge.log" --export=ALL "$@" \
  "$here/probebake-merge.sbatch")
merge=${merge%%;*}
echo "array $array ($shards shards), merge $merge: $RESULT"
