#!/usr/bin/env bash
# smoke_guest.sh - prove that the HIL guest can do what the HIL tests need:
# vivid (V4L2), vimc through libcamera, gpio-sim through libgpiod, and
# simulated camera disconnects. Run it inside the guest:
#
#   tests/hil/vm/run_vm.sh tests/hil/vm/smoke_guest.sh
#
# Prints PASS/FAIL per check and exits with the number of failures (capped
# at 100), so 0 means everything works.
# The helpers below are called indirectly (through check/wait_for):
# shellcheck disable=SC2317
set -euo pipefail

if [[ ${MOCAP_HIL_GUEST:-} != 1 ]]; then
    echo "smoke_guest.sh runs inside the HIL guest: tests/hil/vm/run_vm.sh $0" >&2
    exit 77
fi

failures=0
t0=$EPOCHREALTIME
# Elapsed seconds since the start, for the PASS/FAIL lines.
elapsed() {
    local us=$(((${EPOCHREALTIME/./} - ${t0/./}) / 1000))
    printf '%d.%02d' $((us / 1000)) $((us % 1000 / 10))
}
pass() { echo "PASS [$(elapsed)s]: $*"; }
fail() {
    echo "FAIL [$(elapsed)s]: $*"
    failures=$((failures + 1))
}
# check DESCRIPTION COMMAND...: run COMMAND, PASS or FAIL by its status.
check() {
    local what=$1
    shift
    if "$@"; then pass "$what"; else fail "$what"; fi
}
# wait_for SECONDS COMMAND...: poll COMMAND every 0.1 s until it succeeds.
wait_for() {
    local deadline=$((SECONDS + $1))
    shift
    until "$@"; do
        ((SECONDS < deadline)) || return 1
        sleep 0.1
    done
}
# The /dev/videoN node whose V4L2 name is $1 (e.g. vivid-001-vid-cap).
video_node() {
    local n
    for n in /sys/class/video4linux/video*; do
        [[ -e $n/name && "$(<"$n/name")" == "$1" ]] && { echo "/dev/${n##*/}"; return 0; }
    done
    return 1
}
is_char() { [[ -c $1 ]]; }
gone() { [[ ! -e $1 ]]; }
proc_done() { ! kill -0 "$1" 2>/dev/null; }
stream3() { timeout 60 v4l2-ctl -d "$1" --stream-mmap --stream-count=3 --stream-to=/dev/null >/dev/null 2>&1; }
has_formats() { v4l2-ctl -d "$1" --list-formats 2>/dev/null | grep -q "\[0\]:"; }

echo "== guest $(uname -r), $(nproc) CPUs, modules from $MOCAP_HIL_MODDIR"

# ------------------------------------------------------------------ vivid
# Two vivid instances with only a video capture node each: /dev/video0, /dev/video1.
check "modprobe vivid n_devs=2 node_types=0x1,0x1" modprobe vivid n_devs=2 node_types=0x1,0x1
check "/dev/video0 exists" wait_for 10 is_char /dev/video0
check "/dev/video1 exists" wait_for 10 is_char /dev/video1
for inst in 000 001; do
    if node=$(video_node "vivid-$inst-vid-cap"); then
        pass "vivid instance $inst is $node"
        check "$node --list-formats" has_formats "$node"
        check "$node streams 3 frames (mmap)" stream3 "$node"
    else
        fail "no video node named vivid-$inst-vid-cap"
    fi
done

# Per-instance disconnect: vivid's "Disconnect" button control makes one
# instance behave like an unplugged USB camera (ioctls and open() fail with
# ENODEV; the /dev node stays) until its last file handle is closed, after
# which it reconnects by itself.
timeout 60 v4l2-ctl -d /dev/video1 --stream-mmap --stream-count=100000 --stream-to=/dev/null >/dev/null 2>&1 &
streamer=$!
sleep 2
check "disconnect control on /dev/video1" v4l2-ctl -d /dev/video1 -c disconnect=1
# (v4l2-ctl reports the ENODEV but still exits 0, so only its end is checked.)
check "streamer on /dev/video1 stops after disconnect" wait_for 10 proc_done "$streamer"
wait "$streamer" || true
check "/dev/video1 reconnects after the last close" has_formats /dev/video1
check "/dev/video0 unaffected by the disconnect" stream3 /dev/video0

# Hot-unplug through the driver core: every V4L2 node links to its parent
# device (.../videoN/device) and that to its driver; writing the device name
# to the driver's unbind file removes it, bind brings it back. For vivid the
# parent is the single platform device "vivid.0" that owns *all* instances,
# so unbinding removes /dev/video0 and /dev/video1 together:
#   echo vivid.0 > /sys/bus/platform/drivers/vivid/unbind
parent=$(basename "$(readlink -f /sys/class/video4linux/video1/device)")
driver=$(readlink -f /sys/class/video4linux/video1/device/driver)
echo "   /dev/video1: parent device '$parent', driver $driver"
timeout 60 v4l2-ctl -d /dev/video1 --stream-mmap --stream-count=100000 --stream-to=/dev/null >/dev/null 2>&1 &
streamer=$!
sleep 2
check "unbind $parent while /dev/video1 streams" sh -c "echo $parent > $driver/unbind"
check "/dev/video1 goes away" wait_for 10 gone /dev/video1
check "/dev/video0 goes away (same parent)" wait_for 10 gone /dev/video0
check "streamer stops after unbind" wait_for 10 proc_done "$streamer"
wait "$streamer" || true
check "bind $parent again" sh -c "echo $parent > $driver/bind"
check "/dev/video1 is back" wait_for 10 is_char /dev/video1
udevadm settle --timeout=30 || true
check "/dev/video1 streams after rebind" stream3 /dev/video1
check "modprobe -r vivid" modprobe -r vivid

# ------------------------------------------------------------------ vimc + libcamera
# libcamera 0.0.3 has a vimc pipeline handler (not one for vivid); it needs
# libcamera-ipa and udev-initialised devices (the modprobe wrapper settles).
check "modprobe vimc" modprobe vimc
cams=$(timeout 60 cam -l 2>/dev/null || true)
printf '   cam -l: %s\n' "${cams//$'\n'/$'\n   cam -l: '}"
if camid=$(echo "$cams" | sed -n "s/^[0-9]*: .*(\(.*\))$/\1/p" | grep -m1 vimc); then
    pass "libcamera lists vimc camera '$camid'"
    cam_capture() { timeout 120 cam -c "$camid" --capture=3 >/dev/null 2>&1; }
    check "cam captures 3 frames from '$camid'" cam_capture
else
    fail "cam -l lists no vimc camera"
fi

# ------------------------------------------------------------------ gpio-sim + libgpiod
check "modprobe gpio-sim" modprobe gpio-sim
cfg=/sys/kernel/config/gpio-sim/hil
if mkdir "$cfg" "$cfg/bank0" &&
    echo 8 >"$cfg/bank0/num_lines" &&
    mkdir "$cfg/bank0/line0" "$cfg/bank0/line1" &&
    echo trigger-out >"$cfg/bank0/line0/name" &&
    echo trigger-in >"$cfg/bank0/line1/name" &&
    echo 1 >"$cfg/live"; then
    pass "gpio-sim chip created through configfs"
else
    fail "gpio-sim chip created through configfs"
fi
dev=$(cat "$cfg/dev_name" 2>/dev/null || true)         # e.g. gpio-sim.0
chip=$(cat "$cfg/bank0/chip_name" 2>/dev/null || true) # e.g. gpiochip0
sim=/sys/devices/platform/$dev/$chip                   # holds sim_gpio<offset>/{pull,value}
echo "   gpio-sim device '$dev', chip '$chip', simulator attributes in $sim"
check "$sim/sim_gpio1/pull exists" test -w "$sim/sim_gpio1/pull"
check "gpiodetect lists $chip (8 lines)" sh -c "gpiodetect | grep -q '^$chip .*(8 lines)'"
check "gpioinfo shows the line names" sh -c "gpioinfo $chip | grep -q '\"trigger-out\"' && gpioinfo $chip | grep -q '\"trigger-in\"'"
check "gpiofind trigger-in = $chip 1" test "$(gpiofind trigger-in)" = "$chip 1"

# Input edge: gpiomon waits on line 1; the simulator's pull drives it high.
echo pull-down >"$sim/sim_gpio1/pull"
gpiomon_out=$(mktemp)
timeout 30 gpiomon --num-events=1 --rising-edge "$chip" 1 >"$gpiomon_out" 2>&1 &
mon=$!
line_used() { gpioinfo "$chip" | grep -q 'line *1:.*\[used'; }
check "gpiomon holds line 1" wait_for 10 line_used
echo pull-up >"$sim/sim_gpio1/pull"
if wait "$mon" && grep -q "RISING EDGE" "$gpiomon_out"; then
    pass "gpiomon saw the rising edge: $(head -n1 "$gpiomon_out")"
else
    fail "gpiomon saw no rising edge: $(cat "$gpiomon_out")"
fi
rm -f "$gpiomon_out"

# Output: a line driven by userspace shows up in sim_gpio0/value.
timeout 30 gpioset --mode=time --sec=20 "$chip" 0=1 &
setter=$!
value_is_1() { [[ "$(<"$sim/sim_gpio0/value")" == 1 ]]; }
check "gpioset $chip 0=1 shows in sim_gpio0/value" wait_for 10 value_is_1
kill "$setter" 2>/dev/null || true
wait "$setter" 2>/dev/null || true

# Tear the chip down again (configfs dirs must be removed bottom-up).
check "gpio-sim chip removed" sh -c "echo 0 > $cfg/live && rmdir $cfg/bank0/line0 $cfg/bank0/line1 $cfg/bank0 $cfg"

echo "== smoke: $failures failure(s)"
exit $((failures > 100 ? 100 : failures))
