#!/usr/bin/env bash
# Submits the generation as an array of N tasks and the merge/validate job after it.
#   CONFIG=scenes/paper.yaml OUT=/scratch/$USER/paper YCB_DIR=/data/ycb deploy/slurm/submit.sh 32
set -euo pipefail
n="${1:?usage: $0 TASKS   (e.g. 32; at most the number of shards, see vtgen plan)}"
here="$(cd "$(dirname "$0")" && pwd)"
array=$(sbatch --parsable --export=ALL --array="0-$((n - 1))" "$here/generate.sbatch")
merge=$(sbatch --parsable --export=ALL --dependency="afterok:${array%%;*}" "$here/merge.sbatch")
echo "array job $array ($n tasks), merge job $merge"
