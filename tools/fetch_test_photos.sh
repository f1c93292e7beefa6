#!/usr/bin/env bash
# Fetches real test photos with people from Debian's opencv-doc package (examples/data) without
# installing it: `apt-get download` + extract only the wanted files. They are checked by SHA-256,
# cached in ${MOCAP_CACHE_DIR:-~/.cache/mocap-box}/photos and copied into the repository's
# gitignored .cache/photos/. Idempotent: a second run downloads nothing.
#
#   messi5.jpg       548x342 JPEG, RGB
#   basketball1.png  640x480 PNG, 8-bit gray
#   basketball2.png  640x480 PNG, 8-bit gray
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
PKG="opencv-doc"
DATA_DIR="usr/share/doc/opencv-doc/examples/data"
DEST="$ROOT/.cache/photos"
CACHE="${MOCAP_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/mocap-box}/photos"
# Observed in opencv-doc 4.6.0+dfsg-12 (Debian 12).
declare -A SHA256=(
  [messi5.jpg]=1d570e49654e84c7a943918537bd9e5e1ef82920152e147c834006e235be97c9
  [basketball1.png]=ba06f6701f7260998b430c39b6557f775497e6ce7b1a74f0b7ea6af371bf54a6
  [basketball2.png]=b3047772e0dc6c9d83c26f64894ca1a897f799f855c5574ac24b2ef934c2978e
)

verified() {  # verified DIR: all photos present with the right hash
  local f
  for f in "${!SHA256[@]}"; do
    [ -f "$1/$f" ] || return 1
    [ "$(sha256sum "$1/$f" | cut -d' ' -f1)" = "${SHA256[$f]}" ] || return 1
  done
}

die() {
  echo "fetch_test_photos: $*" >&2
  exit 1
}

if verified "$DEST"; then
  echo "photos: ${!SHA256[*]} present and verified in .cache/photos/"
  exit 0
fi

if ! verified "$CACHE"; then
  command -v apt-get >/dev/null || die "apt-get not found: the photos come from Debian's $PKG package"
  command -v dpkg-deb >/dev/null || die "dpkg-deb not found"
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  apt_opts=()
  # As root, apt drops to the _apt user, which cannot write into our private temp dir.
  [ "$(id -u)" -eq 0 ] && apt_opts+=(-o APT::Sandbox::User=root)
  echo "photos: downloading Debian package $PKG (~96 MB, once) to extract 3 photos"
  if ! (cd "$tmp" && apt-get download -qq "${apt_opts[@]}" "$PKG") >"$tmp/apt.log" 2>&1; then
    cat "$tmp/apt.log" >&2
    die "'apt-get download $PKG' failed. Check the network and the Debian sources; if the package" \
      "is unknown, refresh the package lists first ('sudo apt-get update') and run this again."
  fi
  deb=$(find "$tmp" -maxdepth 1 -name "${PKG}_*.deb" | head -n 1)
  [ -n "$deb" ] || die "apt-get download $PKG reported success but left no .deb in $tmp"
  mkdir -p "$tmp/x"
  # Extract only the photos (plain, or gzip-compressed as Debian does for some docs).
  members=()
  for f in "${!SHA256[@]}"; do members+=("./$DATA_DIR/$f" "./$DATA_DIR/$f.gz"); done
  dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$tmp/x" --wildcards \
    "${members[@]}" 2>/dev/null || true
  mkdir -p "$tmp/photos"
  for f in "${!SHA256[@]}"; do
    src="$tmp/x/$DATA_DIR/$f"
    if [ -f "$src" ]; then
      cp "$src" "$tmp/photos/$f"
    elif [ -f "$src.gz" ]; then
      gzip -dc "$src.gz" >"$tmp/photos/$f"
    else
      die "$(basename "$deb") has no $DATA_DIR/$f (or $f.gz); the package layout changed"
    fi
  done
  if ! verified "$tmp/photos"; then
    sha256sum "$tmp"/photos/* >&2
    die "SHA-256 mismatch for the photos from $(basename "$deb"); refusing to use them" \
      "(update the hashes in tools/fetch_test_photos.sh after checking the new package)"
  fi
  mkdir -p "$CACHE"
  cp "$tmp"/photos/* "$CACHE/"
fi
mkdir -p "$DEST"
for f in "${!SHA256[@]}"; do cp "$CACHE/$f" "$DEST/$f"; done
verified "$DEST" || die "copy into $DEST failed verification"
echo "photos: ${!SHA256[*]} installed in .cache/photos/ (from cache $CACHE)"
