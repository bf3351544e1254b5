#!/usr/bin/env bash
# What the touch's geometry buys: the geometric pose refiner (`vtpose refine`, docs/refine.md) on
# held-out grasps, with the depth alone, with touch, and with another grasp's touch (the control).
# Every step resumes: rerun the same command after an interruption. Reports land in
# out/experiments/refine/<name>/refine.md (tracking: tracking.md) with their pictures.
#
#   experiments/refine/run.sh pairs    --ycb-dir DIR   # the refiner alone on the three object pairs' test grasps, each and pooled
#   experiments/refine/run.sh networks --ycb-dir DIR   # + the touch experiment's networks per pair, refined from their estimates (trains them)
#   experiments/refine/run.sh tracking --ycb-dir DIR   # tracking with the refiner on pivoting (2F-85), finger-roll, finger-gaiting and pinch-pivoting (Allegro) episodes
#   experiments/refine/run.sh paper    --ycb-dir DIR --device cuda --jobs 16   # the paper's dataset and networks, refined
#
# The pairs are the touch experiment's (experiments/touch/run.sh pairs): its datasets
# (out/experiments/touch-cpu-<pair>/data, experiments/touch/cpu.yaml) and, for `networks`, its
# trained Tactile-Channel and vision-only networks, generated and trained here when missing.
#
# Options: --ycb-dir DIR (or $YCB_DIR; required: the real meshes), --robot-assets DIR (the real
# robot meshes; default: the robots' URDF shapes), --jobs N (generator workers, default: the
# number of cores), --device D (vtpose device, default cpu), --max-samples N (per pair, 0: all).
set -euo pipefail
usage() { sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
[ $# -ge 1 ] || usage
experiment=$1; shift
ycb="${YCB_DIR:-}"
jobs="$(nproc)"
device=cpu
max_samples=0
robot_assets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --ycb-dir) ycb="$2"; shift 2 ;;
    --robot-assets) robot_assets=(--robot-assets "$2"); shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --device) device="$2"; shift 2 ;;
    --max-samples) max_samples="$2"; shift 2 ;;
    *) echo "run.sh: unknown option $1" >&2; usage ;;
  esac
done
cd "$(dirname "$0")/../.."
case "$experiment" in
  pairs | networks | tracking | paper) ;;
  *) echo "run.sh: the experiment must be pairs, networks, tracking or paper, got '$experiment'" >&2; usage ;;
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

# generate SCENE OUT [--set KEY=VALUE...]: the dataset, resumed.
generate() {
  local scene=$1 out=$2; shift 2
  log "generate $scene -> $out"
  "$bin/vtgen" generate "$scene" --out "$out" --ycb-dir "$ycb" "${robot_assets[@]}" --jobs "$jobs" --resume "$@"
}
# train CONFIG DATA RUN VARIANT: one network, resumed.
train() {
  log "train $3"
  "$bin/vtpose" train "$1" --dataset "$2" --variant "$4" --out "$3" --resume --device "$device"
}
# refine OUT DATA [RUN...]: the refiner's report for one dataset.
refine() {
  local out=$1 data=$2; shift 2
  log "refine $data -> $out/refine.md"
  "$bin/vtpose" refine "$@" --dataset "$data" --out "$out" --max-samples "$max_samples" --device "$device" --quiet > /dev/null
}

pairs=(042_adjustable_wrench,037_scissors 004_sugar_box,005_tomato_soup_can 006_mustard_bottle,010_potted_meat_can)
out=out/experiments/refine
case "$experiment" in
  pairs | networks)
    reports=()
    for pair in "${pairs[@]}"; do
      data="out/experiments/touch-cpu-${pair//,/+}/data"
      generate experiments/touch/cpu.yaml "$data" --set "objects=[${pair//,/, }]"
      runs=()
      if [ "$experiment" = networks ]; then
        runs_dir="out/experiments/touch-cpu-${pair//,/+}/runs"
        train experiments/touch/train-cpu.yaml "$data" "$runs_dir/tactile_channel" tactile_channel
        train experiments/touch/train-cpu.yaml "$data" "$runs_dir/vision_only" vision_only
        runs=("$runs_dir/tactile_channel" "$runs_dir/vision_only")
      fi
      refine "$out/$experiment-${pair//,/+}" "$data" "${runs[@]}"
      reports+=("$out/$experiment-${pair//,/+}")
    done
    log "pool -> $out/$experiment-pooled/refine.md"
    "$bin/vtpose" refine --pool "${reports[@]}" --out "$out/$experiment-pooled" --quiet > /dev/null
    log "reports: $out/$experiment-<pair>/refine.md (picture sheets: sheet.png); pooled: $out/$experiment-pooled/refine.md"
    ;;
  tracking)
    for scene in pivot roll gait pinch; do
      data="$out/tracking-$scene/data"
      generate "experiments/refine/tracking-$scene.yaml" "$data"
      log "track $data -> $out/tracking-$scene/track/tracking.md"
      "$bin/vtpose" track --refine --dataset "$data" --out "$out/tracking-$scene/track" --no-touch-control --quiet > /dev/null
    done
    log "reports: $out/tracking-{pivot,roll,gait,pinch}/track/tracking.md (error-time.svg)"
    ;;
  paper)
    data=out/experiments/touch-paper/data
    runs_dir=out/experiments/touch-paper/runs
    generate scenes/paper.yaml "$data"
    train trainer/configs/paper.yaml "$data" "$runs_dir/tactile_channel" tactile_channel
    train trainer/configs/paper.yaml "$data" "$runs_dir/vision_only" vision_only
    refine "$out/paper" "$data" "$runs_dir/tactile_channel" "$runs_dir/vision_only"
    log "report: $out/paper/refine.md"
    ;;
esac
