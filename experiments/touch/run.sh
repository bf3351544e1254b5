#!/usr/bin/env bash
# The touch experiment: generate a dataset with the real YCB meshes, train the Tactile-Channel
# network and the vision-only baseline with identical settings, evaluate both on the test split
# (trajectories never seen in training) and on part of the training split, and write a report.
#
#   experiments/touch/run.sh cpu   --ycb-dir DIR   # ~1 h on 2 CPU cores (see README.md here)
#   experiments/touch/run.sh paper --ycb-dir DIR --device cuda --jobs 16   # the paper's size, for a GPU box
#
# Options: --ycb-dir DIR (or $YCB_DIR; required: the real meshes), --jobs N (generator workers,
# default: the number of cores), --device D (vtpose device, default cpu). Every step resumes:
# rerun the same command after an interruption.
set -euo pipefail
usage() { sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
[ $# -ge 1 ] || usage
size=$1; shift
ycb="${YCB_DIR:-}"
jobs="$(nproc)"
device=cpu
while [ $# -gt 0 ]; do
  case "$1" in
    --ycb-dir) ycb="$2"; shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --device) device="$2"; shift 2 ;;
    *) echo "run.sh: unknown option $1" >&2; usage ;;
  esac
done
cd "$(dirname "$0")/../.."
case "$size" in
  cpu) scene=experiments/touch/cpu.yaml; train=experiments/touch/train-cpu.yaml; out=out/experiments/touch-cpu; sweep=0 ;;
  paper) scene=scenes/paper.yaml; train=trainer/configs/paper.yaml; out=out/experiments/touch-paper; sweep=1 ;;
  *) echo "run.sh: size must be cpu or paper, got '$size'" >&2; usage ;;
esac
[ -n "$ycb" ] && [ -d "$ycb" ] || { echo "run.sh: the experiment needs the real YCB meshes: --ycb-dir DIR (or YCB_DIR)" >&2; exit 2; }

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/vtgen/target}"
scripts/system-deps
features=()
case "$device" in cuda*) features=(--features cuda) ;; esac
cargo build --release -p vtgen -p vt-trainer "${features[@]}"
bin="$CARGO_TARGET_DIR/release"
log() { echo "== $(date +%H:%M:%S) $*"; }

log "generate $scene -> $out/data"
"$bin/vtgen" generate "$scene" --out "$out/data" --ycb-dir "$ycb" --jobs "$jobs" --resume
"$bin/vtgen" inspect "$out/data" | tee "$out/inspect.txt"

for variant in tactile_channel vision_only; do
  log "train $variant"
  "$bin/vtpose" train "$train" --dataset "$out/data" --variant "$variant" --out "$out/runs/$variant" --resume --device "$device"
done

log "evaluate on the test split (unseen trajectories)"
"$bin/vtpose" eval "$out/runs/tactile_channel" "$out/runs/vision_only" --out "$out/eval" --device "$device" --quiet > /dev/null
log "evaluate on the training split (what the networks fit)"
"$bin/vtpose" eval "$out/runs/tactile_channel" "$out/runs/vision_only" --split train --max-samples 400 --no-sweep \
  --out "$out/eval-train" --device "$device" --quiet > /dev/null
if [ "$sweep" = 1 ]; then
  log "tactile-point sweep: one network per count"
  "$bin/vtpose" sweep "$train" --dataset "$out/data" --baseline "$out/runs/vision_only" --out "$out/sweep" --device "$device"
fi
log "report: $out/eval/report.md (pictures: $out/eval/*.svg); training split: $out/eval-train/report.md"
