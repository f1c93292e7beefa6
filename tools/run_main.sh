#!/usr/bin/env bash
# The main job: the appliance as a customer runs it. mocapd with no configuration (the cameras
# it finds; the built-in simulator board when none is attached) streaming skeletons, read back
# by `mocap stream`; then, with the shared data, a real recording through the whole path
# (decode -> GPU CNN -> association -> fitting -> stream) and the association engine's Shelf
# benchmark score.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DATA="${MOCAP_DATA_DIR:-$ROOT/../shared/data}"
BIN="$ROOT/build/bin"
PORT="${MOCAPD_STREAM_PORT:-9870}"

# Runs mocapd with the given arguments and prints N stream messages through `mocap stream`.
run_daemon() {
  local n=$1
  shift
  "$BIN/mocapd" "$@" &
  local pid=$!
  trap 'kill $pid 2>/dev/null || true' EXIT
  local rc=0
  "$BIN/mocap" stream --port "$PORT" --messages "$n" --timeout-s 120 || rc=$?
  wait "$pid" || rc=$?
  trap - EXIT
  return "$rc"
}

printf '\n== Main job: mocapd (no configuration) for 150 frames, read by mocap stream\n'
run_daemon 5 --frames 150 --status-log-interval-s 2

if [ -d "$DATA/pose2sim_multi/videos" ]; then
  printf '\n== mocapd --recording %s (10 frames: videos -> GPU MoveNet -> 4D association -> stream)\n' \
    "$DATA/pose2sim_multi"
  run_daemon 10 --recording "$DATA/pose2sim_multi" --frames 10
fi
if [ -f "$DATA/shelf/calibration.json" ]; then
  printf '\n== mocap eval shelf --data %s\n' "$DATA/shelf"
  "$BIN/mocap" eval shelf --data "$DATA/shelf"
else
  printf '\n== no shared data at %s (set MOCAP_DATA_DIR): skipped the recording and Shelf\n' "$DATA"
fi
