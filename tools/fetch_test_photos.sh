#!/usr/bin/env bash
# Fetches real test photos with people from Debian's opencv-doc package (examples/data) without
# installing it: `apt-get download` + extract only the wanted files. They are checked by SHA-256,
# cached in ${MOCAP_CACHE_DIR:-~/.cache/mocap-box}/photos and copied into the repository's
# gitignored .cache/photos/. Idempotent: a second run downloads nothing.
#
#   messi5.jpg       548x342 JPEG, RGB
#   basketball1.png  640x480 PNG, 8-bit gray
#   basketball2.png  640x480 PNG, 8-bit gray
#   left01..14.jpg, right01..14.jpg (no 10)  640x480: a stereo pair of cameras looking at a 9x6
#                    chessboard (25 mm), and left_intrinsics.yml (OpenCV's calibration of the
#                    left one): the board calibration's real-photo test (issue 38)
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
  [left01.jpg]=9621899098adffa1440c8264606bb7be535ccfd9ad126ae8e0bd9b0c5a5b8676
  [left02.jpg]=052e700bbcc865c112958ec2ea105cb1bce4deca50ac8d6efae13adca9df7a2c
  [left03.jpg]=c85b9426c3d8fcf161e1e727356105091009c3fd0b1b1a65bc2da91fea2724d2
  [left04.jpg]=b490599dccfbfe5eb56d33363415b02227a9548ab8c9b8e7b05d3580e97266d9
  [left05.jpg]=40bab8934fa76f82ec614a7fd0e6ebb4d9f74391d5e8b0c6f2f0ed6080c6c4de
  [left06.jpg]=1cb164db61b3bd52f58a7e9340bb27c5e0278895bc80b6f292fba5cf9bccc4a1
  [left07.jpg]=d2211fe9f971646b6ff88ed93a4f0d3f443741eb2894095cba15caade7c8c6e4
  [left08.jpg]=f7a0737894812a28243af5b409c5689f4fadfe7610958b8ca5fc79aec2f2cd1b
  [left09.jpg]=753939bc62d093c001d9118e989bef2b887f1b2f9ac03603df915a8b85aa81d3
  [left11.jpg]=e736ace3d515c94c547009c3c10d818c81506ed7059cb31123749b9cc3f94ee8
  [left12.jpg]=04bdd78b3b507fe0551aa7062a3ffd94846a147ee2bea7fb38082c720bdbe231
  [left13.jpg]=2637fb6dd5e557f4fadb06b353a453eb0b9223f4671f6f572f815302bc4a70b3
  [left14.jpg]=d4c032971dd7b859f9d6aed5090c9888bd8039b82e0604bee5bfe05444fce834
  [right01.jpg]=94a160342fade4d0c4d2e94b8cb6c1e144a6e7682389d2991257e3a28625cb2d
  [right02.jpg]=f7819b2fcc45fdeff0cefd666a1f8bd2a5828c4d34367d7b6b6691f442bf1c42
  [right03.jpg]=43a3cea1907be641268ea18478362ab6c459424a9d8b7265eb5fb2264fcfb894
  [right04.jpg]=d5874ff3d948dbb673beb035dd70aef5e517119ff626ecdfd612fdd6a1eec32e
  [right05.jpg]=9382a24af5a21a9e3ec477bd4f74011e4bb10b0cdbc7e0de3ae60b75e95d650b
  [right06.jpg]=874b60edc8a53da477c6ee393184a1aafdc83ceaedcb4d0535f7c482d1c80e76
  [right07.jpg]=446093eead30c8cb1e51c8d01d322907760a3a57876596a81af6bf0795e9be67
  [right08.jpg]=5f1be870c8709fd5fc4dd578103b320018aabb4e18b8e8edaba9afbdd4d0b8f4
  [right09.jpg]=de28e9f146f4b7de78b0e39be6682997a7428f8ec5ef4efc753415d4ff8d9d76
  [right11.jpg]=2695e8f8e94eaef0bcfe56818090dada6dc76f53e30b77b97bea3a91080949db
  [right12.jpg]=07489b6a334fae390954bbbddedf03a0556163e5e364820838e881ebd3f33e0d
  [right13.jpg]=a576cc5e69668d65dd926366d103c4c77377e0cd71403e4e0fc278e335ed953c
  [right14.jpg]=e98bbe907610e9499d704bd0fe68d4adc158b19346cbc32f4cfe8a0014b1bd62
  [left_intrinsics.yml]=93a35a94eaaa63afba5128292cf2800fce3e783eba12a69e3d3731360d594684
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
  echo "photos: ${#SHA256[@]} files present and verified in .cache/photos/"
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
  echo "photos: downloading Debian package $PKG (~96 MB, once) to extract ${#SHA256[@]} files"
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
echo "photos: ${#SHA256[@]} files installed in .cache/photos/ (from cache $CACHE)"
