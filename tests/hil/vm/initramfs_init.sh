#!/bin/sh
# shellcheck shell=sh
# /init of the HIL guest initramfs (busybox sh, PID 1). Installed by
# build_vm.sh; changing this file makes build_vm.sh rebuild the initramfs.
#
# It loads the virtio/9p/configfs modules listed in /lib/hil-modules/order,
# mounts the host's / (9p tag "hostroot", read-only) on /newroot with the
# usual virtual filesystems and tmpfs on /tmp /run /dev/shm, mounts the
# per-run job share (tag "hiljob") and the module tree (tag "hilmods") under
# /run/mocap-hil, and switch_roots into the host's bash running
# /run/mocap-hil/job/stage2.sh (guest_stage2.sh, copied there by run_vm.sh).
#
# Any failure powers the guest off without an exit status; run_vm.sh reports
# that as "no exit status" (124) and the message below is on the console.
set -u
PATH=/bin
export PATH
/bin/busybox --install -s /bin

fail() {
    echo "HIL: initramfs: $*" >&2
    echo "HIL: guest setup failed; powering off" >&2
    # sysrq 'o' powers off at once; QEMU then exits with status 0 (no status).
    echo o >/proc/sysrq-trigger 2>/dev/null || echo o >/newroot/proc/sysrq-trigger
    sleep 10
    exit 1
}

mount -t devtmpfs devtmpfs /dev || fail "cannot mount devtmpfs"
# Reopen the console in case the kernel could not open it before /dev existed.
exec </dev/console >/dev/console 2>&1
mount -t proc proc /proc || fail "cannot mount /proc"
mount -t sysfs sysfs /sys || fail "cannot mount /sys"

while read -r ko; do
    insmod "/lib/hil-modules/$ko" || fail "insmod $ko failed"
done </lib/hil-modules/order

# msize: 512000 is the largest the 6.1 virtio transport accepts; the 8 KiB
# default makes every read over 9p crawl. cache=loose is safe for a read-only
# view of the host root and makes exec/stat much faster.
p9='trans=virtio,version=9p2000.L,msize=512000'
mount -t 9p -o "$p9,ro,cache=loose" hostroot /newroot ||
    fail "cannot mount the host root (9p tag hostroot)"
mount -t proc proc /newroot/proc || fail "cannot mount /newroot/proc"
mount -t sysfs sysfs /newroot/sys || fail "cannot mount /newroot/sys"
mount -o move /dev /newroot/dev || fail "cannot move /dev"
mount -t configfs configfs /newroot/sys/kernel/config || fail "cannot mount configfs"
mkdir -p /newroot/dev/pts /newroot/dev/shm
mount -t devpts -o gid=5,mode=620,ptmxmode=666 devpts /newroot/dev/pts || fail "cannot mount devpts"
mount -t tmpfs -o mode=1777,nosuid,nodev tmpfs /newroot/dev/shm || fail "cannot mount /dev/shm"
# devtmpfs lacks these links; bash process substitution needs /dev/fd.
ln -sf /proc/self/fd /newroot/dev/fd
ln -sf /proc/self/fd/0 /newroot/dev/stdin
ln -sf /proc/self/fd/1 /newroot/dev/stdout
ln -sf /proc/self/fd/2 /newroot/dev/stderr
mount -t tmpfs -o mode=1777,nosuid,nodev tmpfs /newroot/tmp || fail "cannot mount /tmp"
mount -t tmpfs -o mode=0755,nosuid,nodev tmpfs /newroot/run || fail "cannot mount /run"
mkdir -p /newroot/run/mocap-hil/job /newroot/run/mocap-hil/modroot
mount -t 9p -o "$p9,ro" hiljob /newroot/run/mocap-hil/job ||
    fail "cannot mount the job share (9p tag hiljob)"
mount -t 9p -o "$p9,ro,cache=loose" hilmods /newroot/run/mocap-hil/modroot ||
    fail "cannot mount the module tree (9p tag hilmods)"
[ -x /newroot/bin/bash ] || fail "the host root has no /bin/bash"
[ -r /newroot/run/mocap-hil/job/stage2.sh ] || fail "job share has no stage2.sh"

umount /proc /sys
# switch_root (not chroot: udevd refuses to run in a chroot) deletes the
# initramfs contents, makes /newroot the root and execs stage 2 as PID 1.
exec switch_root -c /dev/console /newroot /bin/bash /run/mocap-hil/job/stage2.sh
