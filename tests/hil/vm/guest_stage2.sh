#!/bin/bash
# guest_stage2.sh - PID 1 of the HIL guest after switch_root (host's bash on
# the host's read-only root). run_vm.sh copies it into the per-run job share
# together with job.sh (cwd, command, environment, extra shares); the
# initramfs mounts that share at /run/mocap-hil/job and execs this script.
#
# It finishes the guest setup (extra shares, modprobe wrappers, udevd), runs
# the guest command and reports its exit status to QEMU through the
# isa-debug-exit port (0xf4). Setup failures power off without a status.
set -Eeuo pipefail

HIL=/run/mocap-hil
export PATH=/usr/sbin:/usr/bin:/sbin:/bin

poweroff_now() {
    # sysrq 'o' powers off immediately; QEMU exits 0 = "no status" to run_vm.sh.
    echo o >/proc/sysrq-trigger
    sleep 30
}
setup_failed() {
    trap - ERR
    echo "HIL: guest setup failed: $*" >&2
    poweroff_now
}
trap 'setup_failed "guest_stage2.sh line $LINENO: $BASH_COMMAND"' ERR

# Defines HIL_CWD, HIL_CMD[], HIL_ENV[] (NAME=VALUE), HIL_SHARES[], HIL_VERBOSE.
# shellcheck source=/dev/null
source "$HIL/job/job.sh"

# With --verbose, note the guest uptime at each setup stage.
stage() {
    if [[ $HIL_VERBOSE == 1 ]]; then echo "HIL: [$(cut -d' ' -f1 /proc/uptime)] $*"; fi
}
stage "stage 2 started"

# Console: no CR/LF translation, so the host sees the command's bytes as-is.
stty -F /dev/console -onlcr
# Keep kernel chatter off the console unless --verbose: level 2 still shows
# oopses and panics (KERN_ALERT/KERN_EMERG); everything is in dmesg anyway.
if [[ $HIL_VERBOSE == 1 ]]; then
    echo 8 >/proc/sys/kernel/printk
else
    echo 2 >/proc/sys/kernel/printk
fi

stage "mounting shares"
# Writable 9p shares (--share DIR), mounted at the same path as on the host.
# mkdir only matters below a tmpfs (/tmp, /run); on the read-only host root
# the directory exists already.
for i in "${!HIL_SHARES[@]}"; do
    mkdir -p "${HIL_SHARES[$i]}" 2>/dev/null || true
    mount -t 9p -o trans=virtio,version=9p2000.L,msize=512000,cache=mmap \
        "hilshare$i" "${HIL_SHARES[$i]}"
done

# The module tree (Debian's + gpio-sim/irq_sim/vimc) is mounted at
# $HIL/modroot; /lib/modules does not exist on the read-only host root, so a
# plain /sbin/modprobe cannot find it. Wrappers first in PATH fix that:
#   modprobe  -> /sbin/modprobe -d $HIL/modroot, then `udevadm settle` so new
#                devices are initialised by udev before the caller uses them
#   modinfo   -> /sbin/modinfo -b $HIL/modroot
# and the kernel's own module autoloading uses a wrapper without the settle
# (settling from inside a kernel module request could deadlock).
mkdir -p "$HIL/bin" "$HIL/sbin"
cat >"$HIL/bin/modprobe" <<EOF
#!/bin/sh
# HIL guest: modprobe from the cached module tree, then wait for udev.
/sbin/modprobe -d $HIL/modroot "\$@" || exit
if [ -S /run/udev/control ]; then udevadm settle --timeout=60 || true; fi
EOF
cat >"$HIL/bin/modinfo" <<EOF
#!/bin/sh
exec /sbin/modinfo -b $HIL/modroot "\$@"
EOF
cat >"$HIL/sbin/modprobe" <<EOF
#!/bin/sh
exec /sbin/modprobe -d $HIL/modroot "\$@"
EOF
chmod 0755 "$HIL/bin/modprobe" "$HIL/bin/modinfo" "$HIL/sbin/modprobe"
echo "$HIL/sbin/modprobe" >/proc/sys/kernel/modprobe

stage "starting udevd"
# udev: libcamera only uses devices that udev has initialised. Devices appear
# later (when the command loads vivid/vimc/gpio-sim); the running udevd
# handles their uevents, and the modprobe wrapper settles.
if [[ $HIL_VERBOSE == 1 ]]; then
    /lib/systemd/systemd-udevd --daemon --resolve-names=never
else
    /lib/systemd/systemd-udevd --daemon --resolve-names=never >/dev/null 2>&1
fi
stage "udev trigger"
udevadm trigger --action=add --subsystem-match=media --subsystem-match=video4linux --subsystem-match=gpio
udevadm settle --timeout=60
stage "running the command"

# ---- run the command (outside the ERR trap: its failure is a result).
trap - ERR
set +e
st=0
if cd "$HIL_CWD"; then
    env -i "${HIL_ENV[@]}" "${HIL_CMD[@]}" </dev/null
    st=$?
else
    echo "HIL: cannot cd to $HIL_CWD in the guest" >&2
    st=125
fi

# ---- report. run_vm.sh reads this line when the status does not fit the port.
echo "HIL: guest command exited with status $st"
# stty uses tcsetattr(TCSADRAIN): wait until the console has sent everything,
# otherwise QEMU would exit with the command's last output still queued.
stty -F /dev/console -onlcr
# The port carries status+1 (1..126) or 127 for "126 or more", so that QEMU's
# own exit codes 0 (guest powered off) and 1 (QEMU error) never look like a
# status. QEMU exits with (byte << 1) | 1.
if ((st <= 125)); then byte=$((st + 1)); else byte=127; fi
# shellcheck disable=SC2059 # the format is the escaped byte itself
printf "$(printf '\\%03o' "$byte")" | dd of=/dev/port bs=1 seek=244 count=1 conv=notrunc status=none
echo "HIL: isa-debug-exit did not stop QEMU; powering off" >&2
poweroff_now
