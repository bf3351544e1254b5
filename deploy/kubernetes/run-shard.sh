#!/usr/bin/env bash
# Entry point of an Indexed Job pod: pod k of N generates the shards j with j mod N = k
# (`vtgen generate --shard k/N --resume`). A restarted pod resumes; the union of all pods equals
# a single-process run byte for byte; a second pod on the same index (a retried pod whose first
# attempt still runs) is refused for the shards the first is writing. With MODE=merge it rebuilds
# the manifest from the shards on disk, generating nothing (a missing shard fails it, named), and
# validates. Logs go to stdout (`kubectl logs`).
# Environment: JOB_COMPLETION_INDEX (set by Kubernetes), SHARD_COUNT (= the Job's completions),
# CONFIG, OUT, YCB_DIR, JOBS, VTGEN, VTGEN_SETS (one KEY=VALUE per line).
set -euo pipefail
mkdir -p "${XDG_RUNTIME_DIR:-/tmp/vtgen-xdg-runtime}"
config="${CONFIG:-scenes/paper.yaml}"
out="${OUT:-/data/out/paper}"
vtgen="${VTGEN:-vtgen}"
extra=()
[ -n "${YCB_DIR:-}" ] && extra+=(--ycb-dir "$YCB_DIR")
while IFS= read -r s; do [ -n "$s" ] && extra+=(--set "$s"); done <<< "${VTGEN_SETS:-}"
if [ "${MODE:-shard}" = merge ]; then
  "$vtgen" generate "$config" --out "$out" --manifest-only --quiet "${extra[@]}"
  "$vtgen" validate "$out"
  exec "$vtgen" inspect "$out"
fi
index="${JOB_COMPLETION_INDEX:?JOB_COMPLETION_INDEX is not set: run in an Indexed Job (completionMode: Indexed)}"
count="${SHARD_COUNT:?SHARD_COUNT is not set: set it to the completions of the Job}"
echo "vtgen pod ${index}/${count}: $config -> $out"
exec "$vtgen" generate "$config" --out "$out" --shard "${index}/${count}" --resume --jobs "${JOBS:-1}" "${extra[@]}"
