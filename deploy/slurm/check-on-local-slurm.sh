#!/usr/bin/env bash
# The Slurm path on a real one-node Slurm (local-cluster.sh): submit.sh's dataset equals a local
# run byte for byte; a cancelled task cancels the merge and `submit.sh --only` recovers; the same
# index submitted twice at once leaves one writer per shard (the other refused) and the dataset
# intact. Needs root and slurm-wlm + munge (scripts/system-deps --slurm). VTGEN: the binary.
#   VTGEN=target/debug/vtgen deploy/slurm/check-on-local-slurm.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
vtgen="$(realpath "${VTGEN:?VTGEN: the vtgen binary to test}")"
work="$(mktemp -d /tmp/vtgen-slurm-check.XXXXXX)"
cluster="$work/cluster"
cleanup() { deploy/slurm/local-cluster.sh stop "$cluster" >/dev/null 2>&1 || true; }
trap cleanup EXIT
eval "$(deploy/slurm/local-cluster.sh start "$cluster")"
export VTGEN="$vtgen" CONFIG="$PWD/scenes/tiny.yaml"
# The procedural meshes, for the local run and the tasks alike (CI exports a YCB download).
unset YCB_DIR ROBOT_ASSETS VTGEN_SETS
mkdir -p "$work/submit-from"
chmod 555 "$work/submit-from"   # a read-only submit directory: logs must not go there

# Waits until none of the given jobs is pending or running.
wait_jobs() {
  for _ in $(seq 600); do
    [ -z "$(squeue -h -j "$1" 2>/dev/null)" ] && return 0
    sleep 1
  done
  echo "jobs $1 did not finish" >&2; squeue >&2; return 1
}
job_state() { scontrol show job "$1" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' | head -1; }
# The dataset's files (without the logs) equal the local run's.
same_as_local() {
  local diffs
  diffs=$(diff -rq --exclude=logs "$work/local" "$1" || true)
  [ -z "$diffs" ] || { echo "$1 differs from the local run:" >&2; echo "$diffs" >&2; return 1; }
  echo "  $(find "$1" -name '*.mcap' | wc -l) shards byte-identical to the local run (manifest, config, models included)"
}
ids() { sed -n 's/^array job \([0-9]*\) .*merge job \([0-9]*\).*/\1 \2/p'; }

echo "== a local run"
"$vtgen" generate "$CONFIG" --out "$work/local" --quiet --set output.samples_per_shard=4 >/dev/null
sets=(--set output.samples_per_shard=4)

echo "== submit.sh 3 (from a read-only directory)"
read -r array merge < <(cd "$work/submit-from" && OUT="$work/a" "$OLDPWD/deploy/slurm/submit.sh" --cpus 1 "${sets[@]}" 3 | tee /dev/stderr | ids)
wait_jobs "$array,$merge"
echo "  merge job $merge: $(job_state "$merge")"
[ "$(job_state "$merge")" = COMPLETED ] || { cat "$work"/a/logs/* >&2; exit 1; }
grep -h "valid" "$work/a/logs/vtgen-merge-$merge.log" | head -1 | sed 's/^/  /'
same_as_local "$work/a"

echo "== a cancelled task, then recovery with --only"
read -r array merge < <(OUT="$work/b" deploy/slurm/submit.sh --cpus 1 --throttle 1 "${sets[@]}" 3 | ids)
scancel "${array}_2"
wait_jobs "$array,$merge"
echo "  scancel ${array}_2; merge job $merge: $(job_state "$merge") (no merge left pending)"
[ "$(job_state "$merge")" = CANCELLED ] || { echo "the merge was not cancelled" >&2; exit 1; }
read -r array merge < <(OUT="$work/b" deploy/slurm/submit.sh --cpus 1 --only 2 "${sets[@]}" 3 | tee /dev/stderr | ids)
wait_jobs "$array,$merge"
echo "  rerun of task 2 and its merge: $(job_state "${array}_2"), $(job_state "$merge")"
[ "$(job_state "$merge")" = COMPLETED ] || { cat "$work"/b/logs/* >&2; exit 1; }
same_as_local "$work/b"

echo "== the same index submitted twice at once"
first=$(OUT="$work/c" deploy/slurm/submit.sh --cpus 1 "${sets[@]}" 1 | ids)
second=$(OUT="$work/c" deploy/slurm/submit.sh --cpus 1 "${sets[@]}" 1 | ids)
read -r a1 m1 <<< "$first"
read -r a2 m2 <<< "$second"
wait_jobs "$a1,$m1,$a2,$m2"
echo "  tasks: $(job_state "${a1}_0"), $(job_state "${a2}_0"); merges: $(job_state "$m1"), $(job_state "$m2")"
refusals=$(grep -l "is being written by another vtgen process" "$work"/c/logs/vtgen-*_0.log || true)
if [ -n "$refusals" ]; then
  grep -h "is being written by another vtgen process" $refusals | head -1 | sed 's/^/  refused: /'
else
  echo "  (the two tasks did not overlap: the second resumed a finished dataset)"
fi
# The dataset is intact whichever way they interleaved: a clean merge and validate, then the bytes.
OUT="$work/c" VTGEN_SETS="output.samples_per_shard=4" bash deploy/slurm/merge.sbatch > "$work/c-merge.log" 2>&1 || { cat "$work/c-merge.log" >&2; exit 1; }
grep -h "valid" "$work/c-merge.log" | head -1 | sed 's/^/  /'
same_as_local "$work/c"
echo "== Slurm checks passed"
cleanup
rm -rf "$work"
