#!/usr/bin/env bash
# The touch experiments, one command each. Every step resumes: rerun the same command after an
# interruption. Reports land in out/experiments/<name>/eval*/report.md with their pictures.
#
#   experiments/touch/run.sh cpu           --ycb-dir DIR   # Tactile-Channel vs vision only, 2 CPU cores (~1 h)
#   experiments/touch/run.sh pairs         --ycb-dir DIR   # cpu on three object pairs, and the three pooled
#   experiments/touch/run.sh orientation   --ycb-dir DIR   # + rot6d and a cosine schedule, + a rotation loss term
#   experiments/touch/run.sh cross-gripper --ycb-dir DIR   # Allegro <-> Robotiq 2F-85, each network on both
#   experiments/touch/run.sh paper         --ycb-dir DIR --device cuda --jobs 16   # the paper's size, for a GPU box
#
# Every experiment trains the vision-only network beside the tactile ones; the reports' touch
# control puts it beside another grasp's touch and no touch, paired per grasp.
#
# Options: --ycb-dir DIR (or $YCB_DIR; required: the real meshes), --robot-assets DIR (the real
# robot meshes, as scripts/robot-assets prints; default: the robots' URDF shapes), --objects A,B
# (cpu, orientation: other YCB objects, in out/experiments/touch-cpu-A+B), --jobs N (generator
# workers, default: the number of cores), --device D (vtpose device, default cpu).
set -euo pipefail
usage() { sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
[ $# -ge 1 ] || usage
experiment=$1; shift
ycb="${YCB_DIR:-}"
jobs="$(nproc)"
device=cpu
objects=""
robot_assets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --ycb-dir) ycb="$2"; shift 2 ;;
    --robot-assets) robot_assets=(--robot-assets "$2"); shift 2 ;;
    --objects) objects="$2"; shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --device) device="$2"; shift 2 ;;
    *) echo "run.sh: unknown option $1" >&2; usage ;;
  esac
done
cd "$(dirname "$0")/../.."
case "$experiment" in
  cpu | pairs | orientation | cross-gripper | paper) ;;
  *) echo "run.sh: the experiment must be cpu, pairs, orientation, cross-gripper or paper, got '$experiment'" >&2; usage ;;
esac
[ -n "$ycb" ] && [ -d "$ycb" ] || { echo "run.sh: the experiment needs the real YCB meshes: --ycb-dir DIR (or YCB_DIR)" >&2; exit 2; }

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/vtgen/target}"
scripts/system-deps
features=()
case "$device" in cuda*) features=(--features cuda) ;; esac
cargo build --release -p vtgen
cargo build --release -p vt-trainer "${features[@]}"
bin="$CARGO_TARGET_DIR/release"
log() { echo "== $(date +%H:%M:%S) $*"; }

# generate SCENE OUT [--set KEY=VALUE...]: the dataset, resumed, and its summary.
generate() {
  local scene=$1 out=$2; shift 2
  log "generate $scene -> $out"
  "$bin/vtgen" generate "$scene" --out "$out" --ycb-dir "$ycb" "${robot_assets[@]}" --jobs "$jobs" --resume "$@"
  "$bin/vtgen" inspect "$out" > "$out.inspect.txt"
}
# train CONFIG DATA RUN [VARIANT]: one network, resumed.
train() {
  local variant=()
  [ $# -ge 4 ] && variant=(--variant "$4")
  log "train $3"
  "$bin/vtpose" train "$1" --dataset "$2" "${variant[@]}" --out "$3" --resume --device "$device"
}
# evaluate OUT RUN... [-- EVAL OPTIONS]: the runs side by side on the test split, one report.
evaluate() {
  local out=$1; shift
  local runs=()
  while [ $# -gt 0 ] && [ "$1" != -- ]; do runs+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  log "evaluate -> $out/report.md"
  "$bin/vtpose" eval "${runs[@]}" --out "$out" --device "$device" --quiet "$@" > /dev/null
}

cpu_train=experiments/touch/train-cpu.yaml
# use_objects A,B: the CPU experiment's folder and object override for that pair (none: cpu.yaml's).
use_objects() {
  cpu_out=out/experiments/touch-cpu
  object_set=()
  if [ -n "$1" ]; then
    cpu_out="$cpu_out-${1//,/+}"
    object_set=(--set "objects=[${1//,/, }]")
  fi
}
use_objects "$objects"
# The CPU-size Allegro dataset, its Tactile-Channel network and the vision-only baseline trained
# on the same data: every CPU experiment starts here, so each has its trained baseline.
cpu_base() {
  generate experiments/touch/cpu.yaml "$cpu_out/data" "${object_set[@]}"
  train "$cpu_train" "$cpu_out/data" "$cpu_out/runs/tactile_channel" tactile_channel
  train "$cpu_train" "$cpu_out/data" "$cpu_out/runs/vision_only" vision_only
}

case "$experiment" in
  cpu)
    cpu_base
    evaluate "$cpu_out/eval" "$cpu_out/runs/tactile_channel" "$cpu_out/runs/vision_only"
    evaluate "$cpu_out/eval-train" "$cpu_out/runs/tactile_channel" "$cpu_out/runs/vision_only" -- --split train --max-samples 400 --no-sweep
    log "report: $cpu_out/eval/report.md (training split: $cpu_out/eval-train/report.md)"
    ;;
  pairs)
    # Three pairs of different shapes (flat tools, a box and a can, a bottle and a tin), each with
    # the cpu protocol, then their test grasps pooled (experiments/touch/README.md).
    evals=()
    for pair in 042_adjustable_wrench,037_scissors 004_sugar_box,005_tomato_soup_can 006_mustard_bottle,010_potted_meat_can; do
      use_objects "$pair"
      cpu_base
      evaluate "$cpu_out/eval" "$cpu_out/runs/tactile_channel" "$cpu_out/runs/vision_only"
      evals+=("$cpu_out/eval")
    done
    python3 experiments/touch/pooled.py "${evals[@]}" | tee out/experiments/touch-pairs-pooled.md
    log "reports: each pair's eval/report.md; pooled: out/experiments/touch-pairs-pooled.md"
    ;;
  orientation)
    cpu_base
    train experiments/touch/train-cpu-orientation.yaml "$cpu_out/data" "$cpu_out/runs/orientation"
    train experiments/touch/train-cpu-rotation-loss.yaml "$cpu_out/data" "$cpu_out/runs/rotation_loss"
    runs=("$cpu_out/runs/tactile_channel" "$cpu_out/runs/orientation" "$cpu_out/runs/rotation_loss")
    evaluate "$cpu_out/eval-orientation" "${runs[@]}" -- --no-sweep --no-touch-control
    evaluate "$cpu_out/eval-orientation-train" "${runs[@]}" -- --split train --max-samples 400 --no-sweep --no-touch-control
    log "report: $cpu_out/eval-orientation/report.md (learning curves: learning-angle.svg)"
    ;;
  cross-gripper)
    cpu_base
    gripper_out=out/experiments/touch-gripper
    generate experiments/touch/gripper.yaml "$gripper_out/data"
    # Named by gripper: the reports name each network by its run directory.
    train "$cpu_train" "$gripper_out/data" "$gripper_out/runs/tactile_channel_2f85" tactile_channel
    train "$cpu_train" "$gripper_out/data" "$gripper_out/runs/vision_only_2f85" vision_only
    # Both tactile networks on each gripper's test grasps (with the touch control), beside the
    # vision-only network trained on that gripper's data: the diagonal is each network at home.
    for home in touch-cpu:"$cpu_out" touch-gripper:"$gripper_out"; do
      dir="${home#*:}"
      vision="$dir/runs/vision_only"
      [ "${home%%:*}" = touch-gripper ] && vision="$dir/runs/vision_only_2f85"
      evaluate "out/experiments/cross-gripper/on-${home%%:*}" "$cpu_out/runs/tactile_channel" "$gripper_out/runs/tactile_channel_2f85" \
        "$vision" -- --dataset "$dir/data" --no-sweep
    done
    log "reports: out/experiments/cross-gripper/on-touch-cpu/report.md (Allegro test grasps), on-touch-gripper/report.md (2F-85)"
    ;;
  paper)
    out=out/experiments/touch-paper
    train=trainer/configs/paper.yaml
    generate scenes/paper.yaml "$out/data"
    train "$train" "$out/data" "$out/runs/tactile_channel" tactile_channel
    train "$train" "$out/data" "$out/runs/vision_only" vision_only
    evaluate "$out/eval" "$out/runs/tactile_channel" "$out/runs/vision_only"
    evaluate "$out/eval-train" "$out/runs/tactile_channel" "$out/runs/vision_only" -- --split train --max-samples 400 --no-sweep
    log "tactile-point sweep: one network per count"
    "$bin/vtpose" sweep "$train" --dataset "$out/data" --baseline "$out/runs/vision_only" --out "$out/sweep" --device "$device"
    log "report: $out/eval/report.md (training split: $out/eval-train/report.md, sweep: $out/sweep)"
    ;;
esac
