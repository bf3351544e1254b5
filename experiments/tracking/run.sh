#!/usr/bin/env bash
# The tracking benchmark, one command per size. Every step resumes: rerun the same command after an
# interruption. The report lands in out/experiments/tracking-<size>/track/tracking.md with its
# charts (error-time.svg, occlusion-time.svg).
#
#   experiments/tracking/run.sh cpu   --ycb-dir DIR                  # 2 CPU cores, ~30 min
#   experiments/tracking/run.sh cpu-pinch --ycb-dir DIR              # the same on objects the hand turns, ~15 min
#   experiments/tracking/run.sh gpu   --ycb-dir DIR --device cuda --jobs 16   # 5x the grasps at 30 Hz, the paper's networks
#
# Each size generates an episode dataset (the touch experiment's scene recorded as episodes),
# trains the Tactile-Channel network and the vision-only baseline on the frames of its train
# episodes, and tracks its test episodes with both: per frame, with the constant-velocity filter,
# and (tactile network) with another episode's touch (docs/tracking.md). cpu-pinch tracks the
# objects while the hand turns them by pinch pivoting, and adds the geometric refiner alone and
# warm-started from each network's estimates (docs/refine.md).
#
# Options: --ycb-dir DIR (or $YCB_DIR; required: the real meshes), --robot-assets DIR (the real
# robot meshes, as scripts/robot-assets prints; default: the robots' URDF shapes), --jobs N
# (generator workers, default: the number of cores), --device D (vtpose device, default cpu),
# --profile P (cargo profile of the binaries: release, the default, or dev), --epochs N (the
# gpu size's training epochs, default 200).
set -euo pipefail
usage() { sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
[ $# -ge 1 ] || usage
size=$1; shift
ycb="${YCB_DIR:-}"
jobs="$(nproc)"
device=cpu
profile=release
gpu_epochs=200
robot_assets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --ycb-dir) ycb="$2"; shift 2 ;;
    --robot-assets) robot_assets=(--robot-assets "$2"); shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --device) device="$2"; shift 2 ;;
    --profile) profile="$2"; shift 2 ;;
    --epochs) gpu_epochs="$2"; shift 2 ;;
    *) echo "run.sh: unknown option $1" >&2; usage ;;
  esac
done
cd "$(dirname "$0")/../.."
case "$size" in
  cpu | cpu-pinch | gpu) ;;
  *) echo "run.sh: the size must be cpu, cpu-pinch or gpu, got '$size'" >&2; usage ;;
esac
[ -n "$ycb" ] && [ -d "$ycb" ] || { echo "run.sh: the benchmark needs the real YCB meshes: --ycb-dir DIR (or YCB_DIR)" >&2; exit 2; }

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/vtgen/target}"
scripts/system-deps
features=()
case "$device" in cuda*) features=(--features cuda) ;; esac
cargo build --profile "$profile" -p vtgen
cargo build --profile "$profile" -p vt-trainer "${features[@]}"
bin="$CARGO_TARGET_DIR/$([ "$profile" = dev ] && echo debug || echo "$profile")"
log() { echo "== $(date +%H:%M:%S) $*"; }

out=out/experiments/tracking-$size
scene=experiments/tracking/cpu.yaml
train_config=experiments/tracking/train-cpu.yaml
scene_set=()
train_set=()
track_set=()
if [ "$size" = cpu-pinch ]; then
  scene=experiments/tracking/cpu-pinch.yaml
  track_set=(--refine)
fi
if [ "$size" = gpu ]; then
  # 5x the grasps (200 per object, as the touch experiment: 160 train and 40 test episodes each) at
  # the camera's and the touch's usual 30 and 60 Hz (58 frames an episode, 23 200 frames, about
  # 10 GB), the touch experiment's 640 x 480 camera, and the paper's networks and learning rate
  # (trainer/configs/paper.yaml) for --epochs epochs.
  scene_set=(--set sampling.trajectories_per_object=200 --set "sampling.record={camera_hz: 30, tactile_hz: 60, state_hz: 60}"
    --set camera.width=640 --set camera.height=480 --set "camera.intrinsics={fx: 615.0, fy: 615.0, cx: 319.5, cy: 239.5}")
  train_config=trainer/configs/paper.yaml
  train_set=(--epochs "$gpu_epochs")
fi

log "generate $scene -> $out/data"
"$bin/vtgen" generate "$scene" --out "$out/data" --ycb-dir "$ycb" "${robot_assets[@]}" --jobs "$jobs" --resume "${scene_set[@]}"
"$bin/vtgen" inspect "$out/data" > "$out/data.inspect.txt"
for variant in tactile_channel vision_only; do
  log "train $out/runs/$variant"
  "$bin/vtpose" train "$train_config" --dataset "$out/data" --variant "$variant" --out "$out/runs/$variant" --resume --device "$device" "${train_set[@]}"
done
log "track -> $out/track/tracking.md"
"$bin/vtpose" track "$out/runs/tactile_channel" "$out/runs/vision_only" --out "$out/track" --device "$device" "${track_set[@]}" --quiet > /dev/null
log "report: $out/track/tracking.md (error-time.svg, occlusion-time.svg)"
