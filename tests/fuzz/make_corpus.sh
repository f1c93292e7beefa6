#!/usr/bin/env bash
# Builds an extra (uncommitted) seed corpus for fuzz_shelf_detections from the shared Shelf
# detections: for each view, the header plus the first frame as a valid 1-frame file, and a
# few truncations of it. Never copy these into the repository; the committed seeds under
# tests/fuzz/corpus/shelf_detections/ are tiny hand-made files.
#
#   tests/fuzz/make_corpus.sh [OUT_DIR]    (default: build-fuzz/corpus_generated)
#   build-fuzz/tests/fuzz_shelf_detections OUT_DIR tests/fuzz/corpus/shelf_detections
set -euo pipefail

root="$(cd "$(dirname "$0")/../.." && pwd)"
data="${MOCAP_DATA_DIR:-$root/../shared/data}/shelf/detection"
out="${1:-$root/build-fuzz/corpus_generated}"
[[ -d "$data" ]] || { echo "make_corpus.sh: no Shelf detections at $data (set MOCAP_DATA_DIR)" >&2; exit 1; }
mkdir -p "$out"

for f in "$data"/*.txt; do
  view="$(basename "$f" .txt)"
  # Tokens of frame 0: 25 joint blocks (n + 3n values), then the 26 BODY_25 PAF matrices.
  python3 - "$f" "$out/view${view}_frame0.txt" <<'PY'
import sys
limbs = [(1, 8), (9, 10), (10, 11), (8, 9), (8, 12), (12, 13), (13, 14), (1, 2), (2, 3), (3, 4),
         (2, 17), (1, 5), (5, 6), (6, 7), (5, 18), (1, 0), (0, 15), (0, 16), (15, 17), (16, 18),
         (14, 19), (19, 20), (14, 21), (11, 22), (22, 23), (11, 24)]
tok = open(sys.argv[1]).read().split()
i, counts, lines = 2, [], []
for j in range(25):
    n = int(tok[i]); counts.append(n); i += 1
    lines.append(str(n))
    for _ in range(3):
        lines.append(" ".join(tok[i:i + n])); i += n
for a, b in limbs:
    for _ in range(counts[a]):
        lines.append(" ".join(tok[i:i + counts[b]])); i += counts[b]
open(sys.argv[2], "w").write("4 1\n" + "\n".join(lines) + "\n")
PY
  size=$(stat -c %s "$out/view${view}_frame0.txt")
  for cut in 17 $((size / 3)) $((size / 2)) $((size - 5)); do
    head -c "$cut" "$out/view${view}_frame0.txt" > "$out/view${view}_frame0_cut${cut}.txt"
  done
done
echo "make_corpus.sh: $(ls "$out" | wc -l) seeds in $out"
