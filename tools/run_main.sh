#!/usr/bin/env bash
# The main job: today's best end-to-end demo. Updated as the pipeline grows.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DATA="${MOCAP_DATA_DIR:-$ROOT/../shared/data}"
if [ -f "$DATA/shelf/calibration.json" ]; then
  printf '\n== Main job: mocap calib show %s\n' "$DATA/shelf/calibration.json"
  exec "$ROOT/build/bin/mocap" calib show "$DATA/shelf/calibration.json"
fi
printf '\n== Main job: no shared data at %s; showing the CLI\n' "$DATA"
exec "$ROOT/build/bin/mocap" --help
