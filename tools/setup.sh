#!/usr/bin/env bash
# One command on a fresh Debian 12 machine: installs the Debian packages the project needs,
# fetches the PoseNet weights (checked by SHA-256, cached), builds (CMake + Ninja, Release)
# and runs the main job. Idempotent: a second run installs and downloads nothing.
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
    -h|--help) sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
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

build() {
  say "Build (Release) in build/"
  cmake -S "$ROOT" -B "$ROOT/build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$ROOT/build"
}

install_packages
if [ "$MODELS" -eq 1 ]; then
  install_npm
  say "Models"
  bash "$ROOT/tools/fetch_models.sh"
fi
[ "$BUILD" -eq 1 ] && build
if [ "$RUN" -eq 1 ]; then
  bash "$ROOT/tools/run_main.sh"
fi
