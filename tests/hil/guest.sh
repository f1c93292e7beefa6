#!/usr/bin/env bash
# The HIL checks, run inside the QEMU guest by run_hil.sh (through tests/hil/vm/run_vm.sh):
# loads the kernel's virtual devices, then runs the project's own code against them:
#   - hil_guest_test (GoogleTest): the V4L2 backend on two vivid cameras (every format, busy /
#     unsupported / missing / permission errors, the synchroniser over both with one camera
#     disconnected mid-stream and reconnected), the libcamera backend on vimc, the trigger
#     master and monitor on gpio-sim lines, a GPIO line already requested;
#   - the CLI: mocap cameras, capture, sync and trigger, checked on their last lines; mocap
#     calibrate board --live on the vivid cameras (no board in view: a refusal naming them);
#   - mocapd on the vivid cameras: 2D detections without calibration, skeletons with one, and
#     one camera unplugged and plugged back while it streams.
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
  "$MOCAP" capture --device "$v0,$v1" --format YUYV --frame-size 640x360 --frame-rate-hz 30 --frames 10
expect_last "mocap sync: 30 sets from two cameras" '^  camera 1 .*live' \
  "$MOCAP" sync --device "$v0,$v1" --frame-size 320x180 --frame-rate-hz 30 --sets 30 --report-s 0
expect_last "mocap capture --out: a 2-view recording of 20 sets" '^codec=.* recorded_sets=20$' \
  "$MOCAP" capture --device "$v0,$v1" --frame-size 320x180 --frame-rate-hz 30 --frames 20 --out /tmp/hil-take
for v in 0 1; do
  if [[ -s /tmp/hil-take/videos/$v.mp4 ]]; then pass "recorded videos/$v.mp4"; else fail "recorded videos/$v.mp4"; fi
done
expect_last "mocap capture --backend libcamera (vimc)" '^captured=5$' \
  "$MOCAP" capture --camera-backend libcamera --frames 5
expect_last "mocap trigger drives 10 pulses" '^pulses=10$' \
  "$MOCAP" trigger --chip "$chip" --line trigger-out --frame-rate-hz 50 --width-us 2000 --pulses 10
# An error names the thing: busy line (held by a background trigger), unknown chip.
"$MOCAP" trigger --chip "$chip" --line trigger-out --frame-rate-hz 5 --width-us 1000 --pulses 20 >/dev/null &
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

echo "== mocapd on the two vivid cameras (board as data, no calibration, then a calibration)"
# The CNN runs on the CPU backend at a small input: lavapipe's shader JIT is slow under TCG, and
# what is checked here is the camera path, not the detections (vivid shows a test pattern).
ip link set lo up 2>/dev/null || ifconfig lo 127.0.0.1 up 2>/dev/null || true
boards=/tmp/hil-boards
state=/tmp/hil-state
mkdir -p "$boards/hil" "$state"
cat >"$boards/hil/board.json" <<EOF
{ "name": "hil", "description": "HIL guest: the two vivid cameras",
  "cameras": [{ "backend": "v4l2", "match": "$v0" }, { "backend": "v4l2", "match": "$v1" }],
  "max_cameras": 2, "frame_rate_hz": 30, "trigger": { "mode": "software" } }
EOF
# The board calibration on the box's own cameras (mocap calibrate board --live): vivid shows a
# test pattern, never a board, so after 5 s of streaming (sampled 4 times a second) it must
# refuse, naming each camera and what it saw, and write nothing.
rm -rf /tmp/hil-boardcal
if out=$("$MOCAP" calibrate board --live --board-dir "$boards" --hw-board hil --seconds 5 \
  --board charuco:4x5:0.054:0.0405:DICT_4X4_1000 --out /tmp/hil-boardcal/calibration.json 2>&1); then
  fail "calibrate board --live without a board in view must refuse: $(echo "$out" | tail -n2)"
elif [[ $out =~ ([0-9]+)\ frame\ sets\ looked\ at && ${BASH_REMATCH[1]} -ge 5 &&
  $out == *"2 cameras"* && $out == *"camera 0 saw the board in 0 frames"* &&
  $out == *"camera 1 saw the board in 0 frames"* && ! -e /tmp/hil-boardcal/calibration.json ]]; then
  pass "calibrate board --live streamed both cameras and refused: $(echo "$out" | tail -n1 | cut -c1-300)"
else
  fail "calibrate board --live: $(echo "$out" | tail -n4 | cut -c1-400)"
fi
health() {  # GET /health from the daemon's HTTP port
  exec 3<>/dev/tcp/127.0.0.1/9871 && printf 'GET /health HTTP/1.0\r\n\r\n' >&3 && cat <&3
  exec 3<&-
}
HEALTH=
mocapd_run() {  # mocapd_run NAME REGEX: run mocapd, read 2 messages, GET /health, SIGTERM
  local name=$1 re=$2 out rc=0 drc=0
  XDG_CACHE_HOME=/tmp "$BUILD/bin/mocapd" --board-dir "$boards" --board hil --state-dir "$state" \
    --gpu cpu --input-size-px 64 --status-log-interval-s 0 &
  local pid=$!
  out=$("$MOCAP" stream --raw --messages 2 --timeout-s 150 2>&1) || rc=$?
  HEALTH=$(health 2>&1 || true)
  kill -TERM "$pid" 2>/dev/null || true
  wait "$pid" || drc=$?
  echo "$out" | cut -c1-200 | sed 's/^/    /'
  echo "$HEALTH" | tail -n1 | cut -c1-600 | sed 's/^/    health: /'
  if [[ $rc -eq 0 && $(echo "$out" | grep -c "$re") -eq 2 ]]; then
    pass "$name"
  else
    fail "$name (stream exit $rc)"
  fi
  if [[ $drc -eq 0 ]]; then pass "$name: SIGTERM stops it, exit 0"; else fail "$name: mocapd exit $drc"; fi
}
mocapd_run "mocapd without calibration streams 2D detections" '"type":"detections"'
# No calibration found: the box calibrates itself (state "calibrating"), naming the cameras.
if [[ $HEALTH == *'"state":"calibrating"'* && $HEALTH == *"$v0, $v1 have no calibration"* ]]; then
  pass "mocapd /health names the uncalibrated cameras"
else
  fail "mocapd /health names the uncalibrated cameras"
fi
# Two cameras 1 m apart at 320x180, the size the cameras are then asked for.
cat >"$state/calibration.json" <<EOF
{ "0": { "K": [250, 0, 160, 0, 250, 90, 0, 0, 1], "RT": [1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 3], "imgSize": [320, 180] },
  "1": { "K": [250, 0, 160, 0, 250, 90, 0, 0, 1], "RT": [1, 0, 0, -1, 0, 0, -1, 0, 0, 1, 0, 3], "imgSize": [320, 180] } }
EOF
mocapd_run "mocapd with a calibration in its state folder streams skeletons" '"type":"skeletons"'
if [[ $HEALTH == *'"state":"ok"'* && $HEALTH == *'320x180'* ]]; then
  pass "mocapd /health: calibration ok, cameras at the calibrated 320x180"
else
  fail "mocapd /health: calibration ok, cameras at the calibrated 320x180"
fi

echo "== mocapd: camera 1 unplugged and plugged back under it (vivid's Disconnect)"
# The camera path of a running daemon: vivid's Disconnect control makes camera 1 act like an
# unplugged USB camera until mocapd closes it; mocapd's rig marks it lost, keeps streaming
# from camera 0, re-opens camera 1 when it is back and takes it into the sets again.
camera() {  # camera VIEW: that camera's object in a fresh /health (cameras in view order)
  HEALTH=$(health 2>&1 || true)
  grep -o '{[^{}]*"disconnects"[^{}]*}' <<<"$HEALTH" | sed -n "$(($1 + 1))p" || true
}
number() {  # number KEY JSON: the first KEY's value, 0 when absent
  local v
  v=$(grep -o "\"$1\":[0-9]*" <<<"$2" | head -n1 | cut -d: -f2) || true
  echo "${v:-0}"
}
messages() { grep -c '"type":"skeletons"' /tmp/hil-unplug.ndjson 2>/dev/null || true; }
at_least() { (($(messages) >= $1)); }
camera1_gone() { [[ $(camera 1) == *'"disconnects":1'* ]]; }
camera1_back() { local c; c=$(camera 1); [[ $c == *'"reconnects":1'* && $c == *'"state":"streaming"'* ]]; }
XDG_CACHE_HOME=/tmp "$BUILD/bin/mocapd" --board-dir "$boards" --board hil --state-dir "$state" \
  --gpu cpu --input-size-px 64 --status-log-interval-s 0 &
dpid=$!
"$MOCAP" stream --raw --messages 0 --timeout-s 150 >/tmp/hil-unplug.ndjson 2>&1 &
spid=$!
if wait_for 150 at_least 3; then
  cam0_before=$(number frames "$(camera 0)")
  n_before=$(messages)
  if "$BUILD/tests/hil_vivid_disconnect" "$v1"; then pass "camera 1 ($v1) unplugged"; else fail "unplugging $v1"; fi
  if wait_for 20 camera1_gone; then
    pass "mocapd /health: camera 1 disconnected: $(camera 1 | cut -c1-300)"
  else
    fail "mocapd /health never counted camera 1's disconnect: $(camera 1 | cut -c1-300)"
  fi
  if wait_for 30 camera1_back; then
    pass "camera 1 re-opened and streaming: $(camera 1 | cut -c1-300)"
  else
    fail "camera 1 never came back: $(camera 1 | cut -c1-300)"
  fi
  cam0_gap=$(number frames "$(camera 0)")
  cam1_back=$(number frames "$(camera 1)")
  n_back=$(messages)
  sleep 3
  cam1_later=$(number frames "$(camera 1)")
  n_later=$(messages)
  echo "    camera 0 frames $cam0_before -> $cam0_gap; stream messages $n_before -> $n_back -> $n_later; camera 1 frames after re-open $cam1_back -> $cam1_later"
  if ((cam0_gap > cam0_before && n_back > n_before)); then
    pass "camera 0 and the stream went on while camera 1 was away"
  else
    fail "camera 0 or the stream stopped while camera 1 was away"
  fi
  if ((cam1_later > cam1_back && n_later > n_back)); then
    pass "camera 1 delivers again and the stream goes on"
  else
    fail "camera 1 does not deliver after re-opening, or the stream stopped"
  fi
  if kill -0 "$dpid" 2>/dev/null; then pass "the same mocapd process throughout"; else fail "mocapd died"; fi
else
  fail "mocapd streamed no skeletons before the unplug: $(tail -n2 /tmp/hil-unplug.ndjson)"
fi
kill -TERM "$dpid" 2>/dev/null || true
drc=0
wait "$dpid" || drc=$?
kill "$spid" 2>/dev/null || true
wait "$spid" 2>/dev/null || true
if [[ $drc -eq 0 ]]; then pass "mocapd after the unplug: SIGTERM stops it, exit 0"; else fail "mocapd after the unplug: exit $drc"; fi

echo "== HIL: $failures failure(s)"
exit $((failures > 100 ? 100 : failures))
