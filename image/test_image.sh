#!/usr/bin/env bash
# test_image.sh - CTest's image.boot: boots the appliance image in QEMU (TCG) with two virtual
# vivid cameras and a calibration for them, and checks from the host that mocapd, started by
# systemd with no configuration, streams skeleton messages on the forwarded stream port and
# answers GET /health; then powers the guest off.
#
# Usage: image/test_image.sh [--build DIR] [--image DIR] [--timeout SEC]
#   --build DIR    the CMake build folder to put in the image (default <repo>/build)
#   --image DIR    where the image is built / looked for (default <build>/appliance)
#   --timeout SEC  boot + first skeleton message deadline (default $MOCAP_IMAGE_BOOT_TIMEOUT
#                  or 420)
# Environment:
#   MOCAP_IMAGE_TEST=1   required: without it the test is skipped (exit 77), so the default
#                        `ctest` run never boots the image (run it with `ctest -L appliance`)
#   MOCAP_IMAGE_BUILD=0  do not (re)build the image, use the one in --image (skip when absent);
#                        default: image/build_image.sh first (incremental: ~10 s when nothing
#                        changed, ~20 s when the binaries did, ~13 min the first time)
# Exit status: 0 pass; 77 skipped (not enabled, no QEMU, no image and no way to build one);
# 1 fail (the serial console's tail is printed).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/.." && pwd)
build=$ROOT/build
image=
deadline_s=${MOCAP_IMAGE_BOOT_TIMEOUT:-420}
while (($#)); do
    case $1 in
    --build | --image | --timeout)
        (($# > 1)) || {
            echo "test_image.sh: $1 needs a value" >&2
            exit 2
        }
        case $1 in
        --build) build=$2 ;;
        --image) image=$2 ;;
        --timeout) deadline_s=$2 ;;
        esac
        shift 2
        ;;
    -h | --help)
        sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
        exit 0
        ;;
    *)
        echo "test_image.sh: unknown argument '$1' (see --help)" >&2
        exit 2
        ;;
    esac
done
image=${image:-$build/appliance}

say() { echo "image.boot: $*"; }
skip() {
    say "skipped: $*"
    exit 77
}
t0=$(date +%s.%N)
elapsed() { awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}'; }

[[ ${MOCAP_IMAGE_TEST:-0} == 1 ]] ||
    skip "boots the full appliance image (~2.5 min, more when the image must be built): set MOCAP_IMAGE_TEST=1 and run ctest -L appliance"
command -v qemu-system-x86_64 >/dev/null 2>&1 ||
    skip "qemu-system-x86_64 not found (apt-get install -y qemu-system-x86, or run tools/setup.sh)"
for c in jq curl; do
    command -v "$c" >/dev/null 2>&1 || {
        say "FAIL: host command '$c' not found (apt-get install -y $c, or run tools/setup.sh)"
        exit 1
    }
done

# ---- the image: (re)built from the build folder unless MOCAP_IMAGE_BUILD=0.
have_image() { [[ -s $image/mocap-box.img && -s $image/mocap-state.img && -s $image/vmlinuz && -s $image/initrd.img ]]; }
if [[ ${MOCAP_IMAGE_BUILD:-1} == 0 ]]; then
    have_image || skip "no image in $image and MOCAP_IMAGE_BUILD=0 (build one: image/build_image.sh --build $build --out $image)"
    say "using the existing image $image (MOCAP_IMAGE_BUILD=0)"
elif [[ $(id -u) != 0 ]]; then
    have_image || skip "no image in $image, and building one needs root (sudo image/build_image.sh --build $build --out $image)"
    say "not root: using the existing image $image as it is (it may predate the build)"
else
    say "building the image (image/build_image.sh --build $build --out $image)"
    if ! "$HERE/build_image.sh" --build "$build" --out "$image"; then
        say "FAIL: image/build_image.sh failed (messages above)"
        exit 1
    fi
    say "image ready after $(elapsed) s"
fi

# ---- boot: two vivid cameras (640x360 is their default and the calibration's size).
tmp=$(mktemp -d "${TMPDIR:-/tmp}/mocap-image-test.XXXXXX")
serial=$tmp/serial.log
runner=
cleanup() {
    if [[ -n $runner ]] && kill -0 "$runner" 2>/dev/null; then
        kill -TERM "$runner" 2>/dev/null || true
        wait "$runner" 2>/dev/null || true
    fi
    # The console of the last test boot stays next to the image for a look afterwards.
    if [[ -f $serial ]]; then cp "$serial" "$image/last-test-boot.log" 2>/dev/null || true; fi
    rm -rf "$tmp"
}
trap cleanup EXIT
trap 'exit 1' INT TERM

# The serial console without colour codes and systemd's progress spinner.
console_tail() {
    echo "---- serial console, last ${1} lines ($serial) ----"
    sed -e 's/\x1b\[[0-9;]*[A-Za-z]//g' -e 's/\r//g' "$serial" 2>/dev/null |
        grep -av -e 'Job .* running (' -e '^\s*$' | tail -n "$1"
    echo "---- end of serial console ----"
}
status_port=
fail() {
    say "FAIL: $* (after $(elapsed) s)"
    if [[ -n $status_port ]] && h=$(curl -fsS --max-time 10 "http://127.0.0.1:$status_port/health" 2>/dev/null); then
        say "GET /health at the failure: $h"
    fi
    console_tail 80
    exit 1
}

boot_start=
for attempt in 1 2 3; do
    rm -f "$tmp/ports"
    boot_start=$(date +%s.%N)
    "$HERE/run_image.sh" --image "$image" --cameras 2 --calibration "$HERE/calibration-vivid2.json" \
        --serial-log "$serial" --journal-console --ports-file "$tmp/ports" \
        --timeout $((deadline_s + 120)) 2>"$tmp/run.err" &
    runner=$!
    sleep 3
    if kill -0 "$runner" 2>/dev/null; then break; fi
    rc=0 && wait "$runner" || rc=$?
    runner=
    if [[ $rc == 77 ]]; then skip "$(cat "$tmp/run.err")"; fi
    # A port taken between choosing and binding: choose again.
    grep -q 'host forwarding' "$tmp/run.err" && ((attempt < 3)) && continue
    cat "$tmp/run.err" >&2
    fail "QEMU did not start (run_image.sh exit $rc)"
done
read -r stream_kv status_kv <"$tmp/ports"
stream_port=${stream_kv#stream=} status_port=${status_kv#status=}
say "guest booting: stream 127.0.0.1:$stream_port, status 127.0.0.1:$status_port, console $serial"
since_boot() { awk -v a="$boot_start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}'; }

# ---- the stream: one connection kept open (a client only gets messages published after it
# connected, and under TCG a CNN frame takes tens of seconds). Until mocapd listens, QEMU's
# user network accepts the connection and closes it at once: reconnect.
end=$((SECONDS + deadline_s))
first_line='' first_line_t='' skel_t='' skel=''
while ((SECONDS < end)) && [[ -z $skel ]]; do
    kill -0 "$runner" 2>/dev/null || fail "QEMU exited before a skeleton message came ($(tr '\n' ' ' <"$tmp/run.err"))"
    if ! { exec 3<>"/dev/tcp/127.0.0.1/$stream_port"; } 2>/dev/null; then
        sleep 1
        continue
    fi
    buf=
    while ((SECONDS < end)); do
        line='' rc=0
        IFS= read -r -t 5 line <&3 || rc=$?
        if ((rc > 128)); then
            buf+=$line # timed out: keep the partial line
            continue
        fi
        ((rc == 0)) || break # EOF: nobody listening yet, or mocapd restarted
        line=$buf$line buf=
        [[ -n $line ]] || continue
        if [[ -z $first_line ]]; then
            first_line=$line first_line_t=$(since_boot)
            say "first stream line ${first_line_t} s after QEMU started: ${line:0:200}"
        fi
        type=$(jq -er 'if type == "object" then .type else error("not an object") end' <<<"$line" 2>/dev/null) ||
            fail "a stream line is not a JSON object: ${line:0:300}"
        if [[ $type == skeletons ]]; then
            skel=$line skel_t=$(since_boot)
            break
        fi
    done
    exec 3<&- 3>&-
    [[ -n $skel ]] || sleep 1
done
[[ -n $skel ]] || fail "no \"type\":\"skeletons\" message on the stream port within ${deadline_s} s${first_line:+ (first line: ${first_line:0:200})}"
say "first skeletons message ${skel_t} s after QEMU started: ${skel:0:300}"
jq -e '.schema == "mocap-box.stream/1" and .topology == "coco17" and (.persons | type == "array")' <<<"$skel" >/dev/null ||
    fail "the skeletons message is not from the cameras (want schema mocap-box.stream/1, topology coco17, persons[]): ${skel:0:300}"

# ---- the status page.
health=$(curl -fsS --max-time 20 "http://127.0.0.1:$status_port/health") ||
    fail "GET /health on 127.0.0.1:$status_port failed"
jq -e 'type == "object"' <<<"$health" >/dev/null || fail "GET /health is not a JSON object: ${health:0:300}"
say "GET /health: $(jq -c '{status, problems, source: .source.kind, board: .source.board, calibration: .calibration.state, gpu: .gpu.device, output, frames_out: .pipeline.frames_out}' <<<"$health")"
jq -e '.source.kind == "cameras" and .calibration.state == "ok" and .output == "skeletons"' <<<"$health" >/dev/null ||
    fail "GET /health: want source.kind cameras, calibration.state ok, output skeletons"
# ---- the appliance's own report (mocap-qemu-report.service, once mocapd listens): the root
# mounted read-only and refusing a write, /var on the state file system and writable, and no
# listening socket but mocapd's, save the DHCP and NTP clients' own ports.
report() { sed -e 's/\x1b\[[0-9;]*[A-Za-z]//g' -e 's/\r//g' "$serial" | grep -ao 'mocap-box-report: .*' | sed 's/^mocap-box-report: //'; }
for _ in $(seq 120); do grep -qx done <<<"$(report)" && break; sleep 1; done
# Read once into a variable: `report | grep -q` under pipefail failed at random (grep -q exits at
# its first match and the pipeline's writer, still reading the console log, gets SIGPIPE).
rep=$(report)
grep -qx done <<<"$rep" || fail "no mocap-box-report from the guest (mocap-qemu-report.service)"
sed 's/^/    report: /' <<<"$rep"
grep -Eq '^root [^ ]+ +ext4 +ro(,|$)' <<<"$rep" || fail "the root file system is not mounted read-only"
grep -qx 'root_write refused' <<<"$rep" || fail "a write to / was not refused"
grep -Eq '^var [^ ]+ +ext4 +rw(,| ).* label mocap-state$' <<<"$rep" ||
    fail "/var is not the writable mocap-state file system"
stray=$(grep '^listen ' <<<"$rep" | grep -v '"mocapd"' |
    grep -Ev '^listen udp [^ ]+:(68|546) .*"systemd-network"|^listen udp [^ ]+ .*"systemd-timesyn"' || true)
[[ -z $stray ]] || fail "listening sockets other than mocapd's: $stray"
grep -q '^listen tcp [^ ]*:9870 .*"mocapd"' <<<"$rep" || fail "mocapd does not listen on 9870 (report above)"
say "read-only root, /var on mocap-state, no listening service but mocapd"
# Guest clock (kernel timestamps) of: systemd starting mocapd, mocapd listening.
# The console is read once; grep -m1 in a pipe would end its writer with SIGPIPE, which fails
# the script under pipefail when the log is long.
console=$(sed -e 's/\x1b\[[0-9;]*[A-Za-z]//g' "$serial")
guest_t() { grep -a -m1 "$1" <<<"$console" | sed -n 's/^\[ *\([0-9.]*\)\].*/\1/p'; }
mocapd_started=$(guest_t 'systemd\[1\]: Started mocapd.service')
mocapd_listening=$(guest_t 'mocapd\[[0-9]*\]: .*stream server on')

# ---- power off (ACPI; run_image.sh kills QEMU after 90 s).
off_start=$(date +%s.%N)
kill -TERM "$runner"
rc=0 && wait "$runner" || rc=$?
runner=
off_s=$(awk -v a="$off_start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}')
grep -aq 'reboot: Power down' "$serial" || fail "the guest did not power off cleanly (run_image.sh exit $rc)"
say "powered off in $off_s s"
say "PASS: guest clock: mocapd started at ${mocapd_started:-?} s, listening at ${mocapd_listening:-?} s; first stream line ${first_line_t} s, first skeletons ${skel_t} s after QEMU started; total $(elapsed) s"
