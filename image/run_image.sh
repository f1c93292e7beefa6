#!/usr/bin/env bash
# run_image.sh - boot the mocap-box appliance image (image/build_image.sh) in QEMU (TCG).
#
# Usage: image/run_image.sh [options]
#   --image DIR         folder with mocap-box.img (the read-only root, /dev/vda),
#                       mocap-state.img (/var, /dev/vdb), vmlinuz, initrd.img
#                       (default <repo>/build/appliance)
#   --cameras N         N virtual vivid cameras (kernel command line: modules-load=vivid
#                       vivid.n_devs=N vivid.node_types=0x1,...); default 0 (none)
#   --calibration FILE  the guest finds FILE at /var/lib/mocap/calibration.json before mocapd
#                       starts (QEMU fw_cfg opt/mocap-box/calibration.json, copied by the
#                       image's mocap-qemu-import.service)
#   --fw-file NAME=FILE any file: /var/lib/mocap/NAME in the guest (same mechanism; repeatable)
#   --append ARGS       more kernel command line
#   --stream-port P     host port forwarded to the guest's 9870 (default 0: a free one)
#   --status-port P     host port forwarded to the guest's 9871 (default 0: a free one)
#   --ports-file F      write "stream=P status=P" to F once QEMU runs
#   --serial-log F      serial console to F (default: this terminal; Ctrl-A X quits QEMU)
#   --journal-console   journald also writes to the serial console (boot diagnostics)
#   --mem MIB           guest memory (default 3072); --smp N: vCPUs (default 2)
#   --timeout SEC       power the guest off after SEC seconds (default: none)
# The disks are throw-away snapshots (-drive snapshot=on): the image files are never modified.
# SIGTERM/SIGINT to this script: ACPI power-off (clean systemd shutdown, up to 90 s), then kill.
# Exit status: QEMU's (0 after a clean power-off), 124 after --timeout, 77 without QEMU.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/.." && pwd)
image=$ROOT/build/appliance
cameras=0
calibration=
fw_files=()
append=
stream_port=0
status_port=0
ports_file=
serial_log=
journal_console=0
mem=3072
smp=2
timeout_s=0

usage() { sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"; }
bad() {
    echo "run_image.sh: $*" >&2
    exit 2
}
while (($#)); do
    case $1 in
    --journal-console) journal_console=1 && shift && continue ;;
    -h | --help) usage && exit 0 ;;
    --image | --cameras | --calibration | --fw-file | --append | --stream-port | --status-port | \
        --ports-file | --serial-log | --mem | --smp | --timeout)
        (($# > 1)) || bad "$1 needs a value"
        ;;
    *) bad "unknown argument '$1' (see --help)" ;;
    esac
    case $1 in
    --image) image=$2 ;;
    --cameras) cameras=$2 ;;
    --calibration) calibration=$2 ;;
    --fw-file) fw_files+=("$2") ;;
    --append) append+=" $2" ;;
    --stream-port) stream_port=$2 ;;
    --status-port) status_port=$2 ;;
    --ports-file) ports_file=$2 ;;
    --serial-log) serial_log=$2 ;;
    --mem) mem=$2 ;;
    --smp) smp=$2 ;;
    --timeout) timeout_s=$2 ;;
    esac
    shift 2
done
for v in cameras stream_port status_port mem smp timeout_s; do
    [[ ${!v} =~ ^[0-9]+$ ]] || bad "--${v//_/-} takes a number, got '${!v}'"
done

if ! command -v qemu-system-x86_64 >/dev/null 2>&1; then
    echo "run_image.sh: qemu-system-x86_64 not found (apt-get install -y qemu-system-x86, or run tools/setup.sh)" >&2
    exit 77
fi
for f in mocap-box.img mocap-state.img vmlinuz initrd.img; do
    [[ -s $image/$f ]] || bad "$image/$f not found (build the image: image/build_image.sh --build BUILD_DIR --out $image)"
done
if [[ -n $calibration ]]; then fw_files+=("calibration.json=$calibration"); fi
fw_args=()
for spec in "${fw_files[@]}"; do
    name=${spec%%=*} file=${spec#*=}
    [[ $spec == *=* && $name =~ ^[A-Za-z0-9._-]+$ ]] || bad "--fw-file wants NAME=FILE with a plain NAME, got '$spec'"
    [[ -f $file && -r $file ]] || bad "$file: no such readable file"
    fw_args+=(-fw_cfg "name=opt/mocap-box/$name,file=$(realpath "$file")")
done

cmdline="root=/dev/vda ro console=ttyS0,115200 panic=-1 net.ifnames=0"
((journal_console)) && cmdline+=" systemd.journald.forward_to_console=1"
if ((cameras > 0)); then
    types=$(printf '0x1,%.0s' $(seq "$cameras"))
    cmdline+=" modules-load=vivid vivid.n_devs=$cameras vivid.node_types=${types%,}"
fi
cmdline+=$append

# A free localhost TCP port (another process may still take it: QEMU then fails to start and
# the caller retries with new ports).
free_port() {
    local p used
    used=$(ss -Htan 2>/dev/null | awk '{print $4}' | sed 's/.*://' | sort -u)
    for _ in $(seq 200); do
        p=$((20000 + RANDOM % 40000))
        grep -qx "$p" <<<"$used" || {
            echo "$p"
            return
        }
    done
    bad "no free TCP port found"
}
((stream_port)) || stream_port=$(free_port)
((status_port)) || status_port=$(free_port)
[[ $stream_port != "$status_port" ]] || status_port=$(free_port)

run=$(mktemp -d "${TMPDIR:-/tmp}/mocap-image-run.XXXXXX")
qemu_pid=
# shellcheck disable=SC2317 # reached through the EXIT trap
cleanup() {
    if [[ -n $qemu_pid ]] && kill -0 "$qemu_pid" 2>/dev/null; then kill -KILL "$qemu_pid" 2>/dev/null || true; fi
    rm -rf "$run"
}
trap cleanup EXIT
# The monitor on a pipe pair (no socket to reach from elsewhere): used for the ACPI power-off.
mkfifo "$run/mon.in" "$run/mon.out"

if [[ -n $serial_log ]]; then
    : >"$serial_log"
    # shellcheck disable=SC2054 # QEMU's option values have commas
    serial=(-serial "file:$serial_log" -chardev "pipe,id=mon,path=$run/mon" -mon chardev=mon,mode=readline)
else
    serial=(-serial mon:stdio)
fi
# shellcheck disable=SC2054 # QEMU's option values have commas
qemu=(
    qemu-system-x86_64
    -nodefaults -no-user-config -display none
    -machine pc -accel "tcg,thread=multi" -cpu max -smp "$smp" -m "$mem"
    -kernel "$image/vmlinuz" -initrd "$image/initrd.img" -append "$cmdline"
    -drive "file=$image/mocap-box.img,format=raw,if=virtio,snapshot=on"
    -drive "file=$image/mocap-state.img,format=raw,if=virtio,snapshot=on"
    -netdev "user,id=net0,hostfwd=tcp:127.0.0.1:$stream_port-:9870,hostfwd=tcp:127.0.0.1:$status_port-:9871"
    -device virtio-net-pci,netdev=net0
    -device virtio-rng-pci
    "${serial[@]}"
    "${fw_args[@]}"
)
echo "run_image.sh: booting $image (stream 127.0.0.1:$stream_port -> 9870, status 127.0.0.1:$status_port -> 9871)" >&2
echo "run_image.sh: kernel command line: $cmdline" >&2
if [[ -z $serial_log ]]; then
    # Interactive: the console (and QEMU's monitor, Ctrl-A C) on this terminal.
    ((timeout_s == 0)) || bad "--timeout needs --serial-log"
    [[ -z $ports_file ]] || echo "stream=$stream_port status=$status_port" >"$ports_file"
    rm -rf "$run"
    trap - EXIT
    exec "${qemu[@]}"
fi
# Drain the monitor's output so QEMU never blocks on it.
cat "$run/mon.out" >/dev/null &
drain=$!
"${qemu[@]}" </dev/null &
qemu_pid=$!
if [[ -n $ports_file ]]; then echo "stream=$stream_port status=$status_port" >"$ports_file"; fi

powered_off=0
# shellcheck disable=SC2317 # reached through the signal traps
power_off() {
    ((powered_off)) && return
    powered_off=1
    echo "run_image.sh: ACPI power-off" >&2
    echo system_powerdown >"$run/mon.in" || true
    local _
    for _ in $(seq 900); do
        kill -0 "$qemu_pid" 2>/dev/null || return 0
        sleep 0.1
    done
    echo "run_image.sh: the guest did not power off within 90 s; killing QEMU" >&2
    kill -TERM "$qemu_pid" 2>/dev/null || true
}
trap 'power_off' TERM INT
timed_out=0
trap 'timed_out=1; power_off' USR1
timer=
if ((timeout_s)); then
    # The sleep must die with the timer (it would hold the caller's stdout open).
    (
        trap 'kill "$s" 2>/dev/null; exit 0' TERM
        sleep "$timeout_s" &
        s=$!
        wait "$s" && kill -USR1 $$ 2>/dev/null
    ) >/dev/null 2>&1 &
    timer=$!
fi

# wait returns early (>128) when a trapped signal interrupts it; QEMU may still run.
while kill -0 "$qemu_pid" 2>/dev/null; do wait "$qemu_pid" || true; done
rc=0
wait "$qemu_pid" || rc=$?
if [[ -n $timer ]]; then kill "$timer" 2>/dev/null || true; fi
kill "$drain" 2>/dev/null || true
qemu_pid=
((timed_out)) && exit 124
exit "$rc"
