#!/usr/bin/env bash
# The HIL checks, run inside the QEMU guest by run_hil.sh (through tests/hil/vm/run_vm.sh):
# loads the kernel's virtual devices, then runs the project's own code against them:
#   - hil_guest_test (GoogleTest): the V4L2 backend on two vivid cameras (every format, busy /
#     unsupported / missing / permission errors, the synchroniser over both with one camera
#     disconnected mid-stream and reconnected), the libcamera backend on vimc, the trigger
#     master and monitor on gpio-sim lines, a GPIO line already requested;
#   - the CLI: mocap cameras, capture, sync and trigger, checked on their last lines.
# Exits with the number of failed checks (0 = pass).
#
#   guest.sh BUILD_DIR
set -euo pipefail
BUILD=${1:?usage: guest.sh BUILD_DIR}
MOCAP="$BUILD/bin/mocap"
failures=0
pass() { echo "HIL PASS: $*"; }
fail() {
  echo "HIL FAIL: $*"
  failures=$((failures + 1))
}
wait_for() {  # wait_for SECONDS COMMAND...
  local deadline=$((SECONDS + $1))
  shift
  until "$@"; do
    ((SECONDS < deadline)) || return 1
    sleep 0.1
  done
}
video_node() {  # the /dev/videoN whose V4L2 name is $1
  local n
  for n in /sys/class/video4linux/video*; do
    [[ -e $n/name && "$(<"$n/name")" == "$1" ]] && { echo "/dev/${n##*/}"; return 0; }
  done
  return 1
}

echo "== HIL guest: kernel $(uname -r), $(nproc) CPUs"
# Two vivid instances with one capture node each; vimc (libcamera's virtual pipeline);
# gpio-sim with a bank of 8 lines, line 0 "trigger-out" and line 1 "trigger-in".
modprobe vivid n_devs=2 node_types=0x1,0x1
modprobe vimc
modprobe gpio-sim
v0=$(wait_for 10 video_node vivid-000-vid-cap >/dev/null && video_node vivid-000-vid-cap)
v1=$(wait_for 10 video_node vivid-001-vid-cap >/dev/null && video_node vivid-001-vid-cap)
cfg=/sys/kernel/config/gpio-sim/hil
mkdir "$cfg" "$cfg/bank0" "$cfg/bank0/line0" "$cfg/bank0/line1"
echo 8 >"$cfg/bank0/num_lines"
echo trigger-out >"$cfg/bank0/line0/name"
echo trigger-in >"$cfg/bank0/line1/name"
echo 1 >"$cfg/live"
chip=$(<"$cfg/bank0/chip_name")
sim=/sys/devices/platform/$(<"$cfg/dev_name")/$chip
echo pull-down >"$sim/sim_gpio1/pull"
echo "== vivid: $v0 $v1; gpio-sim: $chip ($sim)"

export MOCAP_HIL_VIDEO="$v0,$v1" MOCAP_HIL_GPIO_CHIP="$chip" MOCAP_HIL_GPIO_SIM="$sim"
export LIBCAMERA_LOG_LEVELS="*:ERROR"

echo "== hil_guest_test"
if "$BUILD/tests/hil_guest_test" --gtest_color=no; then
  pass "hil_guest_test"
else
  fail "hil_guest_test"
fi

# expect_last NAME REGEX COMMAND...: the command succeeds and its last stdout line matches.
expect_last() {
  local name=$1 re=$2 out rc=0
  shift 2
  out=$("$@" 2>&1) || rc=$?
  echo "$out" | sed 's/^/    /'
  if [[ $rc -eq 0 && "$(echo "$out" | tail -n1)" =~ $re ]]; then
    pass "$name"
  else
    fail "$name (exit $rc)"
  fi
}
echo "== CLI"
expect_last "mocap cameras lists the vivid and vimc cameras" '^cameras=([3-9]|[1-9][0-9])$' "$MOCAP" cameras
expect_last "mocap capture: 10 frames from each vivid camera" '^captured=20$' \
  "$MOCAP" capture --device "$v0,$v1" --format YUYV --size 640x360 --fps 30 --frames 10
expect_last "mocap sync: 30 sets from two cameras" '^  camera 1 .*live' \
  "$MOCAP" sync --device "$v0,$v1" --size 320x180 --fps 30 --sets 30 --report-s 0
expect_last "mocap capture --out: a 2-view recording of 20 sets" '^codec=.* recorded_sets=20$' \
  "$MOCAP" capture --device "$v0,$v1" --size 320x180 --fps 30 --frames 20 --out /tmp/hil-take
for v in 0 1; do
  if [[ -s /tmp/hil-take/videos/$v.mp4 ]]; then pass "recorded videos/$v.mp4"; else fail "recorded videos/$v.mp4"; fi
done
expect_last "mocap capture --backend libcamera (vimc)" '^captured=5$' \
  "$MOCAP" capture --backend libcamera --frames 5
expect_last "mocap trigger drives 10 pulses" '^pulses=10$' \
  "$MOCAP" trigger --chip "$chip" --line trigger-out --rate 50 --width-us 2000 --pulses 10
# An error names the thing: busy line (held by a background trigger), unknown chip.
"$MOCAP" trigger --chip "$chip" --line trigger-out --rate 5 --width-us 1000 --pulses 20 >/dev/null &
bg=$!
sleep 1
if out=$("$MOCAP" trigger --chip "$chip" --line trigger-out --pulses 1 2>&1); then
  fail "a second trigger on a held line must fail"
elif [[ $out == *"already requested by 'mocap-trigger'"* ]]; then
  pass "busy GPIO line: $out"
else
  fail "busy GPIO line message: $out"
fi
kill "$bg" 2>/dev/null || true
wait "$bg" 2>/dev/null || true

echo "== HIL: $failures failure(s)"
exit $((failures > 100 ? 100 : failures))
