#!/usr/bin/env bash
# Submits the generation as an array of N tasks (task i makes shards j with j mod N = i) and the
# merge/validate job after it; logs go to OUT/logs/.
#
#   CONFIG=scenes/paper.yaml OUT=/scratch/$USER/paper YCB_DIR=/data/ycb deploy/slurm/submit.sh 32
#   deploy/slurm/submit.sh --only 1,7 32          # resubmit tasks 1 and 7 of the 32 (and the merge)
#   deploy/slurm/submit.sh --partition gpu --account lab --throttle 8 --set seed=7 32
#
# Options: --only I,J,...  --partition P  --account A  --throttle K (at most K tasks at once)
#          --set KEY=VALUE (repeatable, passed to vtgen)  --time HH:MM:SS  --cpus C (per task)
set -euo pipefail
usage() { echo "usage: $0 [--only I,J] [--partition P] [--account A] [--throttle K] [--time T] [--cpus C] [--set KEY=VALUE]... TASKS" >&2; exit 2; }
only="" throttle="" sets=() sbatch_args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --only) only="${2:?--only needs task indices, e.g. 1,7}"; shift 2 ;;
    --partition) sbatch_args+=(--partition "${2:?}"); shift 2 ;;
    --account) sbatch_args+=(--account "${2:?}"); shift 2 ;;
    --time) sbatch_args+=(--time "${2:?}"); shift 2 ;;
    --cpus) sbatch_args+=(--cpus-per-task "${2:?}"); shift 2 ;;
    --throttle) throttle="${2:?}"; shift 2 ;;
    --set) sets+=("${2:?--set needs KEY=VALUE}"); shift 2 ;;
    -h|--help) usage ;;
    -*) echo "unknown option $1" >&2; usage ;;
    *) break ;;
  esac
done
n="${1:-}"
[[ "$n" =~ ^[1-9][0-9]*$ ]] || usage
here="$(cd "$(dirname "$0")" && pwd)"
# Absolute, so that every task and log finds it whatever directory a task starts in.
out="$(realpath -m "${OUT:-out/paper}")"
export OUT="$out" CONFIG="$(realpath -m "${CONFIG:-scenes/paper.yaml}")"
export VTGEN_SLICES="$n"
# One --set per line for the tasks (a value may hold spaces, not newlines).
VTGEN_SETS="$(printf '%s\n' "${sets[@]+"${sets[@]}"}")"
export VTGEN_SETS
mkdir -p "$out/logs"
if [ -n "$only" ]; then
  for i in ${only//,/ }; do
    [[ "$i" =~ ^[0-9]+$ ]] && [ "$i" -lt "$n" ] || { echo "--only $only: task $i is not one of 0..$((n - 1))" >&2; exit 2; }
  done
  array="$only"
else
  array="0-$((n - 1))"
fi
[ -n "$throttle" ] && array="$array%$throttle"
# --requeue: a preempted or failed node's task runs again (it resumes); --open-mode=append keeps
# the log of every attempt.
job=$(sbatch --parsable --export=ALL --requeue --open-mode=append "${sbatch_args[@]+"${sbatch_args[@]}"}" \
  --output="$out/logs/vtgen-%A_%a.log" --array="$array" "$here/generate.sbatch")
job="${job%%;*}"
# The merge runs when every task succeeded; if one fails or is cancelled, Slurm cancels the merge
# instead of leaving it pending for ever. Rerun the failed tasks with --only, which submits a new merge.
merge=$(sbatch --parsable --export=ALL --open-mode=append "${sbatch_args[@]+"${sbatch_args[@]}"}" \
  --output="$out/logs/vtgen-merge-%j.log" --dependency="afterok:$job" --kill-on-invalid-dep=yes "$here/merge.sbatch")
echo "array job $job (tasks $array of $n), merge job ${merge%%;*}; logs in $out/logs"
