#!/usr/bin/env bash
# The main job: today's best end-to-end demo, updated as the pipeline grows. Now: the 4D
# association engine + skeleton fitting over the Shelf benchmark (5 cameras, 301 frames),
# scored by strict PCP, then its per-frame cost.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DATA="${MOCAP_DATA_DIR:-$ROOT/../shared/data}"
if [ -f "$DATA/shelf/calibration.json" ]; then
  printf '\n== Main job: mocap eval shelf --data %s\n' "$DATA/shelf"
  "$ROOT/build/bin/mocap" eval shelf --data "$DATA/shelf"
  printf '\n== mocap bench assoc --data %s\n' "$DATA/shelf"
  exec "$ROOT/build/bin/mocap" bench assoc --data "$DATA/shelf"
fi
printf '\n== Main job: no shared data at %s (set MOCAP_DATA_DIR); showing the CLI\n' "$DATA"
exec "$ROOT/build/bin/mocap" --help
