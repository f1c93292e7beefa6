#!/usr/bin/env bash
# One command on a fresh Debian 12 machine: installs the Debian packages, fetches the PoseNet
# and MoveNet weights and test photos (SHA-256 checked, cached), installs the TF.js reference
# runner, builds (CMake + Ninja, Release), converts models/posenet.json to models/posenet.mcnn
# (and MoveNet MultiPose, Thunder and Lightning, cut at their heads, to models/movenet-*.mcnn)
# and runs
# the main job. Idempotent: a second run installs and downloads nothing. --no-models skips
# every download (weights, photos, npm packages) and the conversion.
#
#   tools/setup.sh [--no-run] [--no-build] [--no-models]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
RUN=1 BUILD=1 MODELS=1
for arg in "$@"; do
  case "$arg" in
    --no-run) RUN=0 ;;
    --no-build) BUILD=0; RUN=0 ;;
    --no-models) MODELS=0 ;;
    -h|--help) sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "setup.sh: unknown option '$arg' (see --help)" >&2; exit 2 ;;
  esac
done

say() { printf '\n== %s\n' "$*"; }

install_packages() {
  local wanted missing=()
  wanted=$(grep -v '^\s*#' "$ROOT/tools/packages.txt" | grep -v '^\s*$')
  for p in $wanted; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    say "Debian packages: all $(echo "$wanted" | wc -l) present"
    return
  fi
  say "Debian packages: installing ${missing[*]}"
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

install_npm() {
  # Node.js/npm may come from the machine image rather than Debian; only install when absent.
  command -v npm >/dev/null && return
  say "npm not found: installing Debian's nodejs + npm"
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends nodejs npm
}

# npm ci in tools/<sub> when node_modules is missing or older than package-lock.json: the
# TF.js reference runner (tools/tfjs_ref) and the web page's three.js and browser-test driver
# (tools/web). Needs only the npm registry at install time, nothing at run time.
npm_ci_in() {
  local sub=$1 what=$2
  local dir="$ROOT/tools/$sub"
  if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    say "$what: node/npm not found, skipped"
    return
  fi
  if [ -d "$dir/node_modules" ] && [ ! "$dir/package-lock.json" -nt "$dir/node_modules" ]; then
    say "$what: tools/$sub/node_modules up to date"
    return
  fi
  say "$what: npm ci in tools/$sub"
  (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error)
  touch "$dir/node_modules"
}

build() {
  say "Build (Release) in build/"
  cmake -S "$ROOT" -B "$ROOT/build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$ROOT/build"
}

convert_model() {  # convert_model NAME [CUT]: models/NAME.mcnn from models/NAME.json
  # docs/model-format.md; with the mocap just built; redone only when missing or older than
  # the .json/.bin. mocap writes a temporary file and renames it, so an interrupted run leaves
  # no partial model behind. CUT: mocap model convert --cut (a graph cut at its heads).
  local name="$1" cut="${2:-}"
  local json="$ROOT/models/$name.json" bin="$ROOT/models/$name.bin"
  local out="$ROOT/models/$name.mcnn"
  if [ ! -f "$json" ]; then
    say "Model file: models/$name.json not found, conversion skipped"
    return
  fi
  if [ -f "$out" ] && [ ! "$json" -nt "$out" ] && [ ! "$bin" -nt "$out" ]; then
    say "Model file: models/$name.mcnn up to date"
    return
  fi
  say "Model file: converting models/$name.json to models/$name.mcnn"
  "$ROOT/build/bin/mocap" model convert --tfjs "$json" --out "$out" ${cut:+--cut "$cut"}
}

convert_models() {
  convert_model posenet
  convert_model movenet-multipose movenet-multipose
  convert_model movenet-thunder movenet-singlepose
  convert_model movenet-lightning movenet-singlepose
  convert_model blazepose-lite blazepose
  convert_model blazepose-full blazepose
}

install_packages
if [ "$MODELS" -eq 1 ]; then
  install_npm
  say "Models"
  bash "$ROOT/tools/fetch_models.sh"
  say "Test photos"
  bash "$ROOT/tools/fetch_test_photos.sh"
  npm_ci_in tfjs_ref "TF.js reference"
fi
# The page's three.js is part of the build (installed with mocapd), not only of the models.
install_npm
npm_ci_in web "Web page (three.js, puppeteer-core)"
[ "$BUILD" -eq 1 ] && build
[ "$BUILD" -eq 1 ] && [ "$MODELS" -eq 1 ] && convert_models
if [ "$RUN" -eq 1 ]; then
  bash "$ROOT/tools/run_main.sh"
fi
