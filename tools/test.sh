#!/usr/bin/env bash
# Runs the whole test suite (GoogleTest via CTest). Builds first if needed.
#
#   tools/test.sh              Release build in build/ (GCC)
#   tools/test.sh --sanitize   ASan + UBSan build in build-asan/ (clang, -O1, tests -Og; three UBSan
#                              checks ASan covers are off: cmake/Sanitizers.cmake) of the test
#                              executables it runs, and mocap, mocapd (some tests run them).
#                              Left to the Release suite, to keep CI within its budget: the
#                              labels in MOCAP_RELEASE_ONLY_LABELS (tests/CMakeLists.txt: HIL
#                              VM, whole recordings, browser, DDS stage, soak, TF.js) and, as
#                              under --tsan, the calibration CLI's two solves and the two
#                              longest self-calibration solves (3-4 min each under ASan; the
#                              same solver runs under it in the other self-calibration cases,
#                              the daemon's and the web page's recalibration).
#   tools/test.sh --tsan       ThreadSanitizer build in build-tsan/ (clang) of the tests of threaded
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

# The longest calibration solves, run in the Release suite only (measured under ASan at -O1:
# 218, 176, 159 and 143 s, against 30, 18, 23 and 25 s in Release).
LONG_SOLVES='SelfCalibrationTest\.(FiveViewsTwoPeopleFocalUnknown|LeftRightSwapsAndFalseCandidates)'
LONG_SOLVES+='|CalibrateCliTest\.(SyntheticWritesCalibrationAndReport|ShelfWithinTargetsOfItsCalibration)'
# The faults put in on purpose (issue 37: 10-40 s each in Release, two solves in some).
LONG_SOLVES+='|SelfCalibrationRefusalTest\.|SelfCalibrationHypothesesTest\.'
LONG_SOLVES+='|BackgroundCalibratorTest\.RefinesWithMoreFrames|CalibrateCliTest\.ShelfStabilityReduced'
# The board calibration's accuracy runs (issue 38: 300 rendered views each, the caliscope videos
# twice, the stereo photos; 8-25 s each in Release). Its refusals, the floor solve and the CLI's
# bad input stay under the sanitizers.
LONG_SOLVES+='|BoardCalibrationRenderTest\.(FiveCameras|WideAngle)|BoardCliTest\.Caliscope'
LONG_SOLVES+='|BoardStereoPhotosTest\.'

# The sanitizer builds use clang (Debian's clang 14, as the fuzz build does): it compiles this
# code under ASan/TSan about 1.8 times faster than GCC 12 (measured on calib/epipolar.cpp at
# -O1: ASan+UBSan 107.7 s with g++, 61.6 s with clang++; TSan 76.0 / 40.9 s), and it is a
# second compiler's warnings on every file. A folder configured with another compiler is
# configured afresh (CMake cannot change a build folder's compiler).
SANITIZER_CC=(-DCMAKE_CXX_COMPILER=clang++ -DCMAKE_C_COMPILER=clang)
fresh_if_not_clang() {
  if [ -f "$1/CMakeCache.txt" ] && ! grep -q '^CMAKE_CXX_COMPILER:[A-Z]*=.*clang++' "$1/CMakeCache.txt"; then
    echo "test.sh: $1 was configured with another compiler; configuring it afresh with clang++"
    rm -rf "$1/CMakeCache.txt" "$1/CMakeFiles"
  fi
}

if [ "$SANITIZE" -eq 1 ]; then
  B="$ROOT/build-asan"
  fresh_if_not_clang "$B"
  cmake -S "$ROOT" -B "$B" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMOCAP_SANITIZE=ON \
    "${SANITIZER_CC[@]}" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g0 -DNDEBUG" >/dev/null
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1
  # Leaks inside the Vulkan validation layer only (its synchronization validation; why there).
  export LSAN_OPTIONS="suppressions=$ROOT/tests/lsan.supp"
  # The labels left to the Release suite: MOCAP_RELEASE_ONLY_LABELS (tests/CMakeLists.txt).
  CTEST_ARGS=(-LE "$(<"$B/release_only_labels.txt")" -E "$LONG_SOLVES" "${CTEST_ARGS[@]}")
  BUILD_TARGET=(--target mocap_asan_tests)
elif [ "$TSAN" -eq 1 ]; then
  B="$ROOT/build-tsan"
  fresh_if_not_clang "$B"
  cmake -S "$ROOT" -B "$B" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMOCAP_TSAN=ON \
    "${SANITIZER_CC[@]}" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" >/dev/null
  export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$ROOT/tests/tsan.supp"
  # Left out: the calibration CLI tests (they run build/bin/mocap, another process) and the two
  # longest self-calibration solves (4 min each under TSan; the same solver and Ceres threads
  # are run by the other SelfCalibrationTest cases and the daemon's background calibration).
  CTEST_ARGS=(-L threads -LE "hil|e2e|browser|scaleout" -E "CalibrateCliTest|$LONG_SOLVES"
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
