#!/usr/bin/env bash
# Runs the whole test suite (GoogleTest via CTest). Builds first if needed.
#
#   tools/test.sh              Release build in build/
#   tools/test.sh --sanitize   ASan + UBSan build in build-asan/ of the test executables (and
#                              mocap, mocapd: the mixed-geometry test runs them), without
#                              the hil, e2e, browser, scaleout and soak labels: the HIL VM boot,
#                              the whole-recording runs (~1 min each under ASan), the
#                              headless-Chromium page tests (the browser's side) and the
#                              five-process DDS stage (timing checks) and the 3-minute soak
#                              (a process of its own) are in the Release
#                              suite, to keep CI within its budget. No debug info
#                              (-g0): reports name functions (UBSan also file:line), and a
#                              cold CI build took 14.7 instead of 15.4 min (one run each)
#   tools/test.sh --tsan       ThreadSanitizer build in build-tsan/ of the tests of threaded
#                              code only (label "threads": pipeline, stream server, capture
#                              rig, trigger, self-calibration worker, mocapd, fusion node),
#                              those tests run under it; suppressions: tests/tsan.supp
# Extra arguments after -- go to ctest (e.g. -- -R Shelf).
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SANITIZE=0
TSAN=0
CTEST_ARGS=()
while [ $# -gt 0 ]; do
  case "$1" in
    --sanitize) SANITIZE=1 ;;
    --tsan) TSAN=1 ;;
    --) shift; CTEST_ARGS=("$@"); break ;;
    -h|--help) sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "test.sh: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done

# Packages and models (fast no-ops when present).
bash "$ROOT/tools/setup.sh" --no-build

if [ "$SANITIZE" -eq 1 ]; then
  B="$ROOT/build-asan"
  cmake -S "$ROOT" -B "$B" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMOCAP_SANITIZE=ON \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g0 -DNDEBUG" >/dev/null
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1
  CTEST_ARGS=(-LE "hil|e2e|browser|scaleout|soak" "${CTEST_ARGS[@]}")
  BUILD_TARGET=(--target mocap_tests)
elif [ "$TSAN" -eq 1 ]; then
  B="$ROOT/build-tsan"
  cmake -S "$ROOT" -B "$B" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMOCAP_TSAN=ON \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" >/dev/null
  export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$ROOT/tests/tsan.supp"
  # Left out: the calibration CLI tests (they run build/bin/mocap, another process) and the two
  # longest self-calibration solves (4 min each under TSan; the same solver and Ceres threads
  # are run by the other SelfCalibrationTest cases and the daemon's background calibration).
  CTEST_ARGS=(-L threads -LE "hil|e2e|browser|scaleout"
    -E "CalibrateCliTest|SelfCalibrationTest\.(FiveViewsTwoPeopleFocalUnknown|LeftRightSwapsAndFalseCandidates)"
    "${CTEST_ARGS[@]}")
  BUILD_TARGET=(--target mocap_thread_tests)
else
  B="$ROOT/build"
  cmake -S "$ROOT" -B "$B" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  BUILD_TARGET=()
fi
cmake --build "$B" "${BUILD_TARGET[@]}"
# Line-buffered, so that a run cut short (a CI time limit) still shows the last test it started.
# Not under ASan: stdbuf works by LD_PRELOAD, which every test executable would inherit, and
# ASan aborts when its runtime is not the first library loaded.
LINE_BUFFERED=(stdbuf -oL)
if [ "$SANITIZE" -eq 1 ] || [ "$TSAN" -eq 1 ]; then LINE_BUFFERED=(); fi
"${LINE_BUFFERED[@]}" ctest --test-dir "$B" --output-on-failure -j "$(nproc)" "${CTEST_ARGS[@]}"
