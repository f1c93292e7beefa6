#!/usr/bin/env bash
# run_vm.sh - run a command inside the hardware-in-the-loop QEMU guest.
#
# Usage: run_vm.sh [options] [--] GUEST_COMMAND [ARGS...]
#   --timeout SEC   wall-clock limit for the whole guest run, boot included
#                   (default $MOCAP_HIL_TIMEOUT or 600)
#   --share DIR     mount host DIR read-write at the same path in the guest
#                   (repeatable); use it to get files back from the guest
#   --env NAME[=VALUE]
#                   pass one more environment variable (repeatable)
#   --verbose       show the kernel boot log and kernel messages
#   --mem MIB       guest memory (default 2048); --smp N: vCPUs (default 2)
# Environment: MOCAP_HIL_TIMEOUT (default --timeout), MOCAP_HIL_VERBOSE=1,
#   MOCAP_HIL_APPEND (extra kernel command line), MOCAP_HIL_CACHE and
#   MOCAP_HIL_ABI (see build_vm.sh).
#
# The guest boots Debian's kernel (built/cached by build_vm.sh) under QEMU TCG
# with the host's / mounted read-only over 9p, so host binaries run unchanged.
# Inside it, as root: /proc /sys /dev (devtmpfs) /sys/kernel/config are
# mounted, /tmp /run /dev/shm are tmpfs, systemd-udevd runs, `modprobe NAME`
# loads from the cached module tree (vivid, vimc, gpio-sim, ...) and waits for
# udev, and the command runs in the host's current directory with
# PATH, HOME=/tmp, TERM, LANG/LC_ALL/TZ, all MOCAP_* variables and
#   MOCAP_HIL_GUEST=1, MOCAP_HIL_ABI=<kernel abi>,
#   MOCAP_HIL_MODDIR=/run/mocap-hil/modroot  (modprobe -d "$MOCAP_HIL_MODDIR")
# Its stdout/stderr go to this script's stdout (the serial console); its stdin
# is /dev/null.
#
# Exit status: the guest command's status (0..125 exactly; 126..255 are taken
# from the console log); 124 on timeout, kernel panic, guest setup failure or
# a missing status; 125 if the VM cannot be built or the arguments are wrong;
# 77 if qemu-system-x86_64 is not installed (a "skip" for ctest).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
HIL=/run/mocap-hil # guest-side directory, see guest_stage2.sh

timeout_s=${MOCAP_HIL_TIMEOUT:-600}
verbose=${MOCAP_HIL_VERBOSE:-0}
mem=2048
smp=2
shares=()
extra_env=()

usage() {
    sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
}
bad_usage() {
    echo "run_vm.sh: $*" >&2
    echo "usage: run_vm.sh [--timeout SEC] [--share DIR] [--env NAME[=VALUE]] [--verbose] [--] GUEST_COMMAND [ARGS...]" >&2
    exit 125
}

while (($#)); do
    case $1 in
    --timeout)
        (($# > 1)) || bad_usage "--timeout needs a value"
        timeout_s=$2
        shift 2
        ;;
    --share)
        (($# > 1)) || bad_usage "--share needs a directory"
        [[ -d $2 ]] || bad_usage "--share $2: not a directory"
        shares+=("$(realpath -- "$2")")
        shift 2
        ;;
    --env)
        (($# > 1)) || bad_usage "--env needs NAME or NAME=VALUE"
        extra_env+=("$2")
        shift 2
        ;;
    --mem)
        (($# > 1)) || bad_usage "--mem needs a value in MiB"
        mem=$2
        shift 2
        ;;
    --smp)
        (($# > 1)) || bad_usage "--smp needs a value"
        smp=$2
        shift 2
        ;;
    --verbose)
        verbose=1
        shift
        ;;
    -h | --help)
        usage
        exit 0
        ;;
    --)
        shift
        break
        ;;
    -*) bad_usage "unknown option $1" ;;
    *) break ;;
    esac
done
(($#)) || bad_usage "no GUEST_COMMAND given"
[[ $timeout_s =~ ^[0-9]+$ && $timeout_s -gt 0 ]] || bad_usage "--timeout must be a positive number of seconds"
[[ $mem =~ ^[0-9]+$ && $smp =~ ^[0-9]+$ ]] || bad_usage "--mem and --smp take numbers"

if ! command -v qemu-system-x86_64 >/dev/null 2>&1; then
    echo "HIL: qemu-system-x86_64 not found (install qemu-system-x86, or run tools/setup.sh)" >&2
    exit 77
fi

# The guest mounts tmpfs over /tmp, /run and /dev/shm and its own /proc /sys
# /dev, so host paths below those are invisible there unless shared.
guest_visible() {
    local p=$1 s
    for s in "${shares[@]}"; do
        [[ $p == "$s" || $p == "$s"/* ]] && return 0
    done
    case $p in
    /tmp | /tmp/* | /run | /run/* | /dev | /dev/* | /proc | /proc/* | /sys | /sys/*) return 1 ;;
    esac
    return 0
}
cwd=$(pwd -P)
guest_visible "$cwd" ||
    bad_usage "the current directory $cwd is hidden in the guest (tmpfs/proc/sys/dev there); run from elsewhere or add --share $cwd"
if [[ $1 == /* ]] && ! guest_visible "$1"; then
    bad_usage "$1 is hidden in the guest (tmpfs/proc/sys/dev there); put it elsewhere or --share its directory"
fi

# ---- build or verify the cached kernel, modules and initramfs.
build_args=(--print-dir)
((verbose)) || build_args+=(--quiet)
if ! vmdir=$("$HERE/build_vm.sh" "${build_args[@]}"); then
    echo "HIL: building the guest failed (see above)" >&2
    exit 125
fi
abi=$(basename "$vmdir")

# ---- per-run job directory, shared read-only with the guest as tag hiljob.
tmp=$(mktemp -d "${TMPDIR:-/tmp}/mocap-hil.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/job"
cp "$HERE/guest_stage2.sh" "$tmp/job/stage2.sh"
log=$tmp/console.log

# Guest environment: a clean one (env -i in the guest) built from these.
genv=(
    "PATH=$HIL/bin:${PATH:-/usr/sbin:/usr/bin:/sbin:/bin}"
    "HOME=/tmp"
    "TERM=${TERM:-dumb}"
    "MOCAP_HIL_GUEST=1"
    "MOCAP_HIL_ABI=$abi"
    "MOCAP_HIL_MODDIR=$HIL/modroot"
)
for v in LANG LC_ALL TZ; do
    if [[ -n ${!v:-} ]]; then genv+=("$v=${!v}"); fi
done
while IFS= read -r v; do
    case $v in MOCAP_HIL_GUEST | MOCAP_HIL_ABI | MOCAP_HIL_MODDIR) continue ;; esac
    genv+=("$v=${!v}")
done < <(compgen -e | grep '^MOCAP_' || true)
for v in "${extra_env[@]}"; do
    if [[ $v == *=* ]]; then
        genv+=("$v")
    elif [[ -n ${!v+set} ]]; then
        genv+=("$v=${!v}")
    else
        bad_usage "--env $v: not set on the host (use --env $v=VALUE)"
    fi
done

# job.sh is sourced by the guest's bash: %q quoting round-trips any value.
{
    printf 'HIL_CWD=%q\n' "$cwd"
    printf 'HIL_VERBOSE=%q\n' "$verbose"
    printf 'HIL_CMD=('
    printf '%q ' "$@"
    printf ')\n'
    printf 'HIL_ENV=('
    printf '%q ' "${genv[@]}"
    printf ')\n'
    printf 'HIL_SHARES=('
    if ((${#shares[@]})); then printf '%q ' "${shares[@]}"; fi
    printf ')\n'
} >"$tmp/job/job.sh"

# ---- QEMU command line.
if ((verbose)); then loglevel=8; else loglevel=2; fi
qemu=(
    qemu-system-x86_64
    -nodefaults -no-user-config -display none
    -machine pc -accel "tcg,thread=multi" -cpu max -smp "$smp" -m "$mem"
    -kernel "$vmdir/kernel/vmlinuz" -initrd "$vmdir/initramfs.cpio.gz"
    # panic=-1 + -no-reboot: a panic makes QEMU exit at once (status 0).
    -append "console=ttyS0 loglevel=$loglevel panic=-1 oops=panic i8042.noaux i8042.nokbd${MOCAP_HIL_APPEND:+ $MOCAP_HIL_APPEND}"
    -no-reboot
    # Serial console on stdout, also logged to find the status marker.
    -chardev "stdio,id=con,signal=off,logfile=$log" -serial chardev:con
    # The guest writes its status to port 0xf4; QEMU exits (byte << 1) | 1.
    -device "isa-debug-exit,iobase=0xf4,iosize=0x04"
    -virtfs "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap"
    -virtfs "local,path=$tmp/job,mount_tag=hiljob,security_model=none,readonly=on,multidevs=remap"
    -virtfs "local,path=$vmdir/modroot,mount_tag=hilmods,security_model=none,readonly=on,multidevs=remap"
)
for i in "${!shares[@]}"; do
    qemu+=(-virtfs "local,path=${shares[$i]},mount_tag=hilshare$i,security_model=none,multidevs=remap")
done

# --foreground: Ctrl-C reaches QEMU; -k: SIGKILL if it ignores the SIGTERM.
set +e
timeout --foreground -k 10 "$timeout_s" "${qemu[@]}" </dev/null
rc=$?
set -e

if ((rc == 124 || rc == 137)); then
    echo "HIL: timeout: the guest did not finish within ${timeout_s}s (--timeout)" >&2
    exit 124
fi

# Status line printed by guest_stage2.sh just before it writes the port.
marker=$(grep -a -o 'HIL: guest command exited with status [0-9]*' "$log" 2>/dev/null | tail -n 1 || true)
marker=${marker##* }

if ((rc >= 3 && rc % 2 == 1)); then
    byte=$(((rc - 1) / 2)) # QEMU exit = (byte << 1) | 1
    if ((byte <= 126)); then
        st=$((byte - 1))
        if [[ -n $marker && $marker != "$st" ]]; then
            echo "HIL: warning: debug-exit status $st but console says $marker" >&2
        fi
    else
        # 126..255 do not fit the port; the console line has the exact value.
        st=${marker:-127}
    fi
    exit "$st"
fi

# No status: the guest panicked, its setup failed, or QEMU itself failed.
if grep -aq 'Kernel panic' "$log" 2>/dev/null; then
    echo "HIL: the guest kernel panicked: $(grep -a -m1 'Kernel panic' "$log" | tr -d '\r')" >&2
elif grep -aq 'HIL: .*setup failed\|HIL: initramfs:' "$log" 2>/dev/null; then
    echo "HIL: guest setup failed: $(grep -a -m1 'HIL: initramfs:\|HIL: guest setup failed' "$log" | tr -d '\r')" >&2
else
    echo "HIL: QEMU exited with status $rc without a guest exit status" >&2
fi
exit 124
