#!/usr/bin/env bash
# build_image.sh - build the bootable mocap-box appliance image (Debian bookworm + Debian kernel,
# mocapd enabled at boot, no configuration needed).
#
# Usage: image/build_image.sh [--out DIR] [--build DIR] [options]
#   --build DIR        CMake build folder whose install target goes into the image
#                      (default: <repo>/build); it must already be built
#   --out DIR          output folder (default: <build>/appliance), receives
#                        mocap-box.img   raw ext4 root file system, mounted read-only (label
#                                        mocap-root)
#                        mocap-state.img raw ext4 state file system, mounted on /var (label
#                                        mocap-state; sparse): calibration, takes, caches
#                        vmlinuz         Debian's kernel, initrd.img its initramfs
#                        manifest.txt    kernel, packages and versions, sizes, inputs
#   --extra-tree DIR   copy DIR's tree into the rootfs after the project's install (repeatable;
#                      site additions, or a hand-made usr/bin/mocapd while the install
#                      target is missing)
#   --serial-root      root logs in without a password on the serial console ttyS0 (debug
#                      images only); default: the root account is locked, no login at all
#   --refresh          rebuild the cached base rootfs (new Debian package versions)
#   --force            rebuild the image even when its inputs did not change
#   --mirror URL       Debian mirror (default http://deb.debian.org/debian)
# Environment: MOCAP_IMAGE_CACHE (default ~/.cache/mocap-box/image): the .deb cache and the
#   base rootfs (debootstrap + packages), keyed by the package list.
#
# Steps: (1) `DESTDIR=stage cmake --install BUILD --prefix /usr` and the Debian packages its
# ELF files need (ldd on this host -> dpkg -S); (2) the base rootfs, cached: debootstrap
# --variant=minbase bookworm + those packages + the fixed appliance set (kernel, systemd,
# udev, Mesa lavapipe...), docs/man/locales excluded, kernel modules xz-compressed;
# (3) a copy of the base + the staged install + image/rootfs/ (hostname, DHCP on every
# Ethernet port, the QEMU calibration import) + `systemctl enable mocapd`; (4) mkfs.ext4 -d
# (no loop device, no mount) twice: the read-only root without /var, and /var, the only
# writable file system (docs/hardening.md). Needs root (chroot, device nodes, file ownership).
# A second run with unchanged inputs prints "up to date" and does nothing.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/.." && pwd)
CACHE=${MOCAP_IMAGE_CACHE:-${HOME:-/root}/.cache/mocap-box/image}
SUITE=bookworm
ARCH=amd64
MIRROR=http://deb.debian.org/debian
SECURITY_MIRROR=http://deb.debian.org/debian-security
HOSTNAME_=mocap-box
LABEL=mocap-root
STATE_LABEL=mocap-state
# Bump when the way the base rootfs is made changes (its cache key includes this).
RECIPE_BASE=4
# Bump when the per-image steps change (the up-to-date check includes this).
RECIPE_IMAGE=4

# The appliance's fixed package set; the libraries of the installed binaries are added to it.
BASE_PACKAGES=(
    systemd-sysv udev kmod dbus        # init, device manager (V4L2 nodes), modules
    systemd-resolved systemd-timesyncd # DNS and clock from the DHCP network
    iproute2 procps less               # diagnosis on the console
    linux-image-amd64 initramfs-tools zstd e2fsprogs
    libvulkan1 mesa-vulkan-drivers     # Vulkan loader + Mesa (lavapipe on CPU, RADV, ANV)
    libcamera-ipa                      # libcamera's image processing algorithms (CSI boards)
)

out=
build=
extra_trees=()
serial_root=0
refresh=0
force=0
while (($#)); do
    case $1 in
    --out | --build | --extra-tree | --mirror)
        (($# > 1)) || {
            echo "build_image.sh: $1 needs a value" >&2
            exit 2
        }
        case $1 in
        --out) out=$2 ;;
        --build) build=$2 ;;
        --extra-tree) extra_trees+=("$2") ;;
        --mirror) MIRROR=$2 ;;
        esac
        shift 2
        ;;
    --serial-root) serial_root=1 && shift ;;
    --refresh) refresh=1 && shift ;;
    --force) force=1 && shift ;;
    -h | --help)
        sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
        exit 0
        ;;
    *)
        echo "build_image.sh: unknown argument '$1' (see --help)" >&2
        exit 2
        ;;
    esac
done

log() { echo "image: $*" >&2; }
# die WHAT [FIX]
die() {
    echo "image: error: $1" >&2
    if (($# > 1)); then echo "image:   fix: $2" >&2; fi
    exit 1
}
need_cmd() {
    command -v "$1" >/dev/null 2>&1 || die "host command '$1' not found" "apt-get install -y $2   (or run tools/setup.sh)"
}

[[ $(id -u) == 0 ]] || die "must run as root (debootstrap, chroot, device nodes, file owners)" "run it as root"
need_cmd debootstrap debootstrap
need_cmd mkfs.ext4 e2fsprogs
need_cmd cmake cmake
need_cmd chroot coreutils
need_cmd dpkg dpkg
need_cmd ldd libc-bin
need_cmd flock util-linux
need_cmd findmnt util-linux
need_cmd xz xz-utils
need_cmd sha256sum coreutils

build=${build:-$ROOT/build}
[[ -d $build && -f $build/CMakeCache.txt ]] ||
    die "build folder '$build' is not a configured CMake build" \
        "cmake -S $ROOT -B $build -G Ninja -DCMAKE_BUILD_TYPE=Release && ninja -C $build mocapd mocap"
build=$(cd "$build" && pwd)
out=${out:-$build/appliance}
mkdir -p "$out" "$CACHE/debs" || die "cannot create $out or $CACHE" "pick writable folders (--out, MOCAP_IMAGE_CACHE)"
out=$(cd "$out" && pwd)
for t in "${extra_trees[@]}"; do [[ -d $t ]] || die "--extra-tree $t is not a directory"; done

exec 9>"$CACHE/.lock"
flock -w 3600 9 || die "another build_image.sh holds $CACHE/.lock" "wait for it, or remove a stale lock"

sum() { sha256sum | cut -c1-16; }
t_start=$SECONDS
work=$out/.work
# Nothing may be mounted under a directory before it is deleted (chroot /proc, /sys).
umount_under() {
    local m
    while read -r m; do
        if [[ -n $m ]]; then umount -l "$m" 2>/dev/null || true; fi
    done < <(findmnt -rn -o TARGET | grep -F "$1/" | sort -r)
}
safe_rm() {
    local d
    for d; do
        [[ -e $d ]] || continue
        umount_under "$d"
        if findmnt -rn -o TARGET | grep -qF "$d/"; then
            die "cannot unmount everything under $d" "umount -R $d, then rerun"
        fi
        rm -rf --one-file-system "$d"
    done
}
cleanup() {
    umount_under "$work"
    umount_under "$CACHE/base.tmp"
}
trap cleanup EXIT

# ---------------------------------------------------------------- 1. stage the install
# The project's install target into a staging tree (never straight into the rootfs: its ELF
# files decide the package list, and with it the cached base).
safe_rm "$work"
mkdir -p "$work"
stage=$work/stage
log "cmake --install $build (DESTDIR staging)"
DESTDIR=$stage cmake --install "$build" --prefix /usr >"$work/install.log" 2>&1 ||
    {
        cat "$work/install.log" >&2
        die "cmake --install $build failed (log above)" "ninja -C $build (build first), then rerun"
    }
mkdir -p "$stage"
installed_by_cmake=$(find "$stage" -type f | wc -l)
for t in "${extra_trees[@]}"; do
    log "adding --extra-tree $t"
    cp -a --no-preserve=ownership "$t/." "$stage/"
done
missing=()
for f in usr/bin/mocapd usr/lib/systemd/system/mocapd.service; do
    [[ -e $stage/$f ]] || missing+=("/$f")
done
((${#missing[@]} == 0)) ||
    die "the install of $build has no ${missing[*]} (cmake --install installed $installed_by_cmake files)" \
        "the project's install() rules must install mocapd and its unit (issue #6), or pass --extra-tree DIR holding them"

# ELF files -> shared libraries (resolved on this host, which built them) -> Debian packages.
elf_files=()
while IFS= read -r -d '' f; do
    magic=
    IFS= read -r -n 4 magic <"$f" 2>/dev/null || true
    if [[ $magic == $'\x7fELF' ]]; then elf_files+=("$f"); fi
done < <(find "$stage" -type f -print0)
declare -A lib_seen=()
for f in "${elf_files[@]}"; do
    while read -r line; do
        if [[ $line == *"not found"* ]]; then
            die "${f#"$stage"}: $line (on this host)" "install the library's -dev/runtime package on the build host and rebuild"
        fi
        if [[ $line =~ =\>\ (/[^ ]+) ]]; then lib_seen[${BASH_REMATCH[1]}]=1; fi
    done < <(ldd "$f" 2>/dev/null || true)
done
# One dpkg -S for every spelling of every library path (usrmerge: /lib vs /usr/lib, links).
declare -A owner_of=()
candidates=()
for lib in "${!lib_seen[@]}"; do
    real=$(realpath "$lib")
    candidates+=("$lib" "$real" "/usr$lib" "${lib#/usr}" "/usr$real" "${real#/usr}")
done
while IFS= read -r line; do
    if [[ $line =~ ^([^:, ]+)(:[a-z0-9]+)?(,[^:]*)?:\ (/.*)$ ]]; then owner_of[${BASH_REMATCH[4]}]=${BASH_REMATCH[1]}; fi
done < <(printf '%s\n' "${candidates[@]}" | LC_ALL=C sort -u | xargs -d '\n' dpkg -S 2>/dev/null || true)
declare -A pkg_seen=()
for lib in "${!lib_seen[@]}"; do
    real=$(realpath "$lib")
    owner=
    for cand in "$lib" "$real" "/usr$lib" "${lib#/usr}" "/usr$real" "${real#/usr}"; do
        if [[ -n ${owner_of[$cand]:-} ]]; then
            owner=${owner_of[$cand]}
            break
        fi
    done
    [[ -n $owner ]] || die "library $lib (needed by the installed binaries) belongs to no Debian package" \
        "link against Debian's packaged libraries only (a /usr/local library cannot go into the image)"
    pkg_seen[$owner]=1
done
mapfile -t lib_packages < <(printf '%s\n' "${!pkg_seen[@]}" | LC_ALL=C sort)
log "${#elf_files[@]} ELF files need ${#lib_seen[@]} libraries from ${#lib_packages[@]} packages"

# ---------------------------------------------------------------- 2. the cached base rootfs
mapfile -t packages < <(printf '%s\n' "${BASE_PACKAGES[@]}" "${lib_packages[@]}" | LC_ALL=C sort -u)
base_key=$(printf 'recipe=%s suite=%s arch=%s mirror=%s\n%s\n' "$RECIPE_BASE" "$SUITE" "$ARCH" "$MIRROR" "${packages[*]}" | sum)
base=$CACHE/base-$base_key

# in_chroot DIR CMD...: run in the rootfs with /proc and /sys mounted, services never started.
in_chroot() {
    local r=$1 rc=0
    shift
    mount -t proc proc "$r/proc"
    mount -t sysfs sysfs "$r/sys"
    chroot "$r" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LC_ALL=C.UTF-8 \
        DEBIAN_FRONTEND=noninteractive "$@" || rc=$?
    umount "$r/sys" "$r/proc"
    return $rc
}

make_base() {
    local tmp=$CACHE/base.tmp t0=$SECONDS
    safe_rm "$tmp"
    log "debootstrap --variant=minbase $SUITE (.debs cached in $CACHE/debs)"
    debootstrap --variant=minbase --arch="$ARCH" --cache-dir="$CACHE/debs" "$SUITE" "$tmp" "$MIRROR" \
        >"$CACHE/debootstrap.log" 2>&1 || {
        tail -n 30 "$CACHE/debootstrap.log" >&2
        die "debootstrap failed (last lines above; full log $CACHE/debootstrap.log)" \
            "check that $MIRROR is reachable (apt-get update works), then rerun"
    }
    log "debootstrap took $((SECONDS - t0)) s"
    umount_under "$tmp"

    # Never start services inside the chroot; keep docs, man pages and translations out.
    printf '#!/bin/sh\nexit 101\n' >"$tmp/usr/sbin/policy-rc.d"
    chmod 755 "$tmp/usr/sbin/policy-rc.d"
    cp "$HERE/rootfs/etc/dpkg/dpkg.cfg.d/90-mocap-box-trim" "$tmp/etc/dpkg/dpkg.cfg.d/"
    cp "$HERE/rootfs/etc/apt/apt.conf.d/90-mocap-box" "$tmp/etc/apt/apt.conf.d/"
    cat >"$tmp/etc/apt/sources.list" <<EOF
deb $MIRROR $SUITE main
deb $MIRROR $SUITE-updates main
deb $SECURITY_MIRROR $SUITE-security main
EOF
    cp -L /etc/resolv.conf "$tmp/etc/resolv.conf"
    # The .debs of earlier builds are hard-linked in (copied across file systems) and new ones
    # go back to the cache: a rebuild downloads nothing.
    find "$CACHE/debs" -maxdepth 1 -name '*.deb' -exec cp -aln -t "$tmp/var/cache/apt/archives/" {} + 2>/dev/null ||
        find "$CACHE/debs" -maxdepth 1 -name '*.deb' -exec cp -an -t "$tmp/var/cache/apt/archives/" {} +
    t0=$SECONDS
    log "apt-get install ${#packages[@]} packages"
    # INITRD=No: the kernel's postinst makes no initramfs; it is made once, below, after the
    # modules are compressed.
    if ! in_chroot "$tmp" env INITRD=No sh -c 'apt-get update -q && apt-get install -y -q --no-install-recommends "$@"' sh \
        "${packages[@]}" >"$CACHE/apt.log" 2>&1; then
        tail -n 30 "$CACHE/apt.log" >&2
        die "apt-get install in the rootfs failed (last lines above; full log $CACHE/apt.log)" \
            "check the package names and the mirror; --refresh after a Debian point release"
    fi
    log "packages took $((SECONDS - t0)) s"
    find "$tmp/var/cache/apt/archives" -maxdepth 1 -name '*.deb' -exec cp -aln -t "$CACHE/debs/" {} + 2>/dev/null ||
        find "$tmp/var/cache/apt/archives" -maxdepth 1 -name '*.deb' -exec cp -an -t "$CACHE/debs/" {} +
    in_chroot "$tmp" apt-get clean

    # Kernel modules: xz-compressed (kmod and initramfs-tools read .ko.xz); ~400 -> ~120 MB.
    local abi
    abi=$(basename "$(find "$tmp/lib/modules" -mindepth 1 -maxdepth 1 -type d | head -n1)")
    [[ -n $abi && -f $tmp/boot/vmlinuz-$abi ]] || die "no kernel in the rootfs after installing linux-image-amd64" "see $CACHE/apt.log"
    t0=$SECONDS
    # xz -2: 10% bigger than -6 (~110 MB) but three times faster to compress.
    find "$tmp/lib/modules/$abi" -name '*.ko' -print0 | xargs -0 -r -P "$(nproc)" -n 64 xz --check=crc32 -2
    # The initramfs checks the root file system before mounting it when fstab names it.
    printf 'LABEL=%s\t/\text4\tdefaults,noatime,x-systemd.growfs\t0\t1\n' "$LABEL" >"$tmp/etc/fstab"
    in_chroot "$tmp" depmod -a "$abi"
    rm -f "$tmp/boot/initrd.img-$abi"
    in_chroot "$tmp" update-initramfs -c -k "$abi" >>"$CACHE/apt.log" 2>&1 ||
        die "update-initramfs failed in the rootfs" "see $CACHE/apt.log"
    log "modules compressed, initramfs made in $((SECONDS - t0)) s"

    # Docs and translations of the packages debootstrap installed (before the dpkg excludes).
    find "$tmp/usr/share/doc" -mindepth 1 ! -name copyright ! -type d -delete 2>/dev/null || true
    find "$tmp/usr/share/doc" -mindepth 1 -type d -empty -delete 2>/dev/null || true
    rm -rf "$tmp/usr/share/man" "$tmp/usr/share/info" "$tmp/usr/share/lintian" "$tmp/usr/share/linda"
    find "$tmp/usr/share/locale" -mindepth 1 -maxdepth 1 ! -name locale.alias -exec rm -rf {} + 2>/dev/null || true
    rm -rf "$tmp/var/lib/apt/lists/"* "$tmp/var/cache/apt/"*.bin "$tmp/var/cache/debconf/"*-old \
        "$tmp/var/lib/dpkg/"*-old "$tmp/var/log/"*.log "$tmp/var/log/apt/"*
    rm -f "$tmp/usr/sbin/policy-rc.d" "$tmp/etc/resolv.conf"
    {
        echo "created=$(date -u +%Y-%m-%dT%H:%M:%SZ)"
        echo "key=$base_key"
        echo "kernel=$abi"
        echo "packages=${packages[*]}"
    } >"$tmp/.mocap-base"
    safe_rm "$base"
    mv "$tmp" "$base"
    log "base rootfs $base ($(du -sh --apparent-size "$base" | cut -f1)) in $((SECONDS - t_base)) s"
}
t_base=$SECONDS
if ((refresh)) || [[ ! -f $base/.mocap-base ]]; then
    make_base
    # Older bases (other package lists) are kept until --refresh: remove the others then.
    if ((refresh)); then
        for d in "$CACHE"/base-*; do [[ $d == "$base" ]] || safe_rm "$d"; done
    fi
else
    log "cached base rootfs $(basename "$base") ($(sed -n 's/^created=//p' "$base/.mocap-base"))"
    age_days=$((($(date +%s) - $(stat -c %Y "$base/.mocap-base")) / 86400))
    if ((age_days >= 14)); then
        log "note: the base rootfs is $age_days days old; --refresh rebuilds it with Debian's current (security) updates"
    fi
fi
abi=$(sed -n 's/^kernel=//p' "$base/.mocap-base")

# ---------------------------------------------------------------- 3. up to date?
inputs=$(
    {
        echo "recipe=$RECIPE_IMAGE base=$base_key $(sed -n 's/^created=//p' "$base/.mocap-base") serial_root=$serial_root"
        (cd "$stage" && find . -printf '%p %m %s\n' | LC_ALL=C sort && find . -type f -print0 | LC_ALL=C sort -z | xargs -0 -r cat) | sum
        (cd "$HERE/rootfs" && find . -printf '%p %m\n' | LC_ALL=C sort && find . -type f -print0 | LC_ALL=C sort -z | xargs -0 -r cat) | sum
        sum <"${BASH_SOURCE[0]}"
    } | sum
)
if ((!force)) && [[ -f $out/.inputs && "$(<"$out/.inputs")" == "$inputs" && -s $out/mocap-box.img && -s $out/mocap-state.img && -s $out/vmlinuz && -s $out/initrd.img ]]; then
    safe_rm "$work"
    log "up to date: $out/mocap-box.img (inputs unchanged; --force rebuilds)"
    exit 0
fi

# ---------------------------------------------------------------- 4. the image's rootfs
rootfs=$work/rootfs
t0=$SECONDS
cp -a --reflink=auto "$base" "$rootfs"
rm -f "$rootfs/.mocap-base"
cp -a "$stage/." "$rootfs/"
# Overlay: hostname, network, journald, the QEMU calibration import, dpkg/apt trimming.
cp -a --no-preserve=ownership "$HERE/rootfs/." "$rootfs/"
echo "$HOSTNAME_" >"$rootfs/etc/hostname"
printf '127.0.0.1\tlocalhost\n127.0.1.1\t%s\n::1\t\tlocalhost ip6-localhost ip6-loopback\n' "$HOSTNAME_" >"$rootfs/etc/hosts"
# Read-only root; /var (the state: calibration, takes, the Vulkan cache, systemd's and dpkg's
# state) on a file system of its own, grown to its device at boot.
{
    printf 'LABEL=%s\t/\text4\tro,noatime\t0\t1\n' "$LABEL"
    printf 'LABEL=%s\t/var\text4\tdefaults,noatime,nosuid,nodev,x-systemd.growfs\t0\t2\n' "$STATE_LABEL"
} >"$rootfs/etc/fstab"
# resolved without its stub listener (rootfs/etc/systemd/resolved.conf.d): the upstream servers
# go straight into resolv.conf.
ln -sf ../run/systemd/resolve/resolv.conf "$rootfs/etc/resolv.conf"
# First boot generates the machine id (empty file = "uninitialized").
: >"$rootfs/etc/machine-id"
rm -f "$rootfs/var/lib/dbus/machine-id"
mkdir -p "$rootfs/var/lib/mocap"

# Root: locked (no password login anywhere), or --serial-root: passwordless on ttyS0 only.
in_chroot "$rootfs" usermod -p '!*' root
if ((serial_root)); then
    mkdir -p "$rootfs/etc/systemd/system/serial-getty@ttyS0.service.d"
    cat >"$rootfs/etc/systemd/system/serial-getty@ttyS0.service.d/autologin.conf" <<'EOF'
# build_image.sh --serial-root: debug image, root shell on the serial console without password.
[Service]
ExecStart=
ExecStart=-/sbin/agetty --autologin root --keep-baud 115200,57600,38400,9600 %I $TERM
EOF
fi

# mocapd's user and device groups (lib/sysusers.d/mocap.conf) made now, not at first boot: the
# daemon never runs as root, and the state directory is handed to that user by systemd.
in_chroot "$rootfs" systemd-sysusers >"$work/sysusers.log" 2>&1 || {
    cat "$work/sysusers.log" >&2
    die "systemd-sysusers failed in the rootfs (log above)" "check lib/sysusers.d/mocap.conf in the install"
}
in_chroot "$rootfs" id mocap >/dev/null 2>&1 ||
    die "the rootfs has no user mocap after systemd-sysusers" "the install must put tools/mocapd/mocap-sysusers.conf in lib/sysusers.d"

in_chroot "$rootfs" systemctl enable mocapd.service mocap-qemu-import.service mocap-qemu-report.service systemd-networkd.service \
    systemd-resolved.service systemd-timesyncd.service >"$work/enable.log" 2>&1 || {
    cat "$work/enable.log" >&2
    die "systemctl enable failed in the rootfs (log above)" "check the unit files under $rootfs/usr/lib/systemd/system"
}
# Nothing waits for the network at boot: mocapd listens on every address as soon as it starts.
in_chroot "$rootfs" systemctl disable systemd-networkd-wait-online.service >/dev/null 2>&1 || true

# Every installed binary must resolve its libraries in the image itself.
for f in "${elf_files[@]}"; do
    rel=${f#"$stage"}
    if in_chroot "$rootfs" ldd "$rel" 2>&1 | grep -q 'not found'; then
        in_chroot "$rootfs" ldd "$rel" | grep 'not found' >&2
        die "$rel misses libraries in the image (above)" "report this: the package detection in $0 missed them"
    fi
done

# Device nodes debootstrap made are replaced by devtmpfs at boot; caches and logs go.
find "$rootfs/dev" -mindepth 1 -delete
rm -rf "$rootfs/tmp/"* "$rootfs/var/tmp/"* "$rootfs/var/cache/apt/"*.bin "$rootfs/var/lib/apt/lists/"*
log "rootfs assembled in $((SECONDS - t0)) s"

# ---------------------------------------------------------------- 5. the file system images
t0=$SECONDS
# /var leaves the root for a file system of its own; the root keeps an empty mount point.
mv "$rootfs/var" "$work/var"
mkdir -m 0755 "$rootfs/var"
# make_fs LABEL DIR FILE FREE_MIB: an ext4 image of DIR, content + 25 % + FREE_MIB.
make_fs() {
    local used inodes size
    used=$(du -s --block-size=1K "$2" | cut -f1)
    inodes=$(find "$2" | wc -l)
    size=$(((used * 5 / 4) / 1024 + $4))
    rm -f "$3"
    truncate -s "${size}M" "$3"
    mkfs.ext4 -q -F -L "$1" -N $((inodes * 2 + 16384)) -E root_owner=0:0 -d "$2" "$3" >"$work/mkfs.log" 2>&1 || {
        cat "$work/mkfs.log" >&2
        die "mkfs.ext4 -d of $1 failed (log above)" "needs e2fsprogs >= 1.43 and free disk space in $out"
    }
    echo "$size"
}
used_kib=$(du -s --block-size=1K "$rootfs" | cut -f1)
# The root is never written: 32 MiB spare. The state gets 256 MiB free (calibration, takes, the
# Vulkan cache; x-systemd.growfs grows it to its device when written to a bigger one).
size_mib=$(make_fs "$LABEL" "$rootfs" "$out/mocap-box.img.new" 32)
state_mib=$(make_fs "$STATE_LABEL" "$work/var" "$out/mocap-state.img.new" 256)
img=$out/mocap-box.img.new
cp "$rootfs/boot/vmlinuz-$abi" "$out/vmlinuz.new"
cp "$rootfs/boot/initrd.img-$abi" "$out/initrd.img.new"
mv "$out/vmlinuz.new" "$out/vmlinuz"
mv "$out/initrd.img.new" "$out/initrd.img"
mv "$img" "$out/mocap-box.img"
mv "$out/mocap-state.img.new" "$out/mocap-state.img"
log "mkfs.ext4 took $((SECONDS - t0)) s"

{
    echo "# mocap-box image, built $(date -u +%Y-%m-%dT%H:%M:%SZ) by image/build_image.sh"
    echo "build=$build"
    echo "git=$(git -C "$ROOT" describe --always --dirty 2>/dev/null || echo '?')"
    echo "kernel=$abi"
    echo "root=locked$( ((serial_root)) && echo ', passwordless root on ttyS0 (--serial-root)')"
    echo "image_mib=$size_mib (allocated $(du -m "$out/mocap-box.img" | cut -f1)) rootfs_used_mib=$((used_kib / 1024)) read-only"
    echo "state_mib=$state_mib (allocated $(du -m "$out/mocap-state.img" | cut -f1)) on /var"
    echo "vmlinuz_bytes=$(stat -c %s "$out/vmlinuz") initrd_bytes=$(stat -c %s "$out/initrd.img")"
    echo "base=$(basename "$base") $(sed -n 's/^created=/created /p' "$base/.mocap-base")"
    echo "# installed by cmake --install ($installed_by_cmake files) and --extra-tree:"
    (cd "$stage" && find . -type f | sed 's#^\.##' | LC_ALL=C sort)
    echo "# packages (name version):"
    # shellcheck disable=SC2016
    chroot "$rootfs" dpkg-query -W -f='${Package} ${Version}\n'
} >"$out/manifest.txt"
echo "$inputs" >"$out/.inputs"
safe_rm "$work"
log "done in $((SECONDS - t_start)) s: $out/mocap-box.img (${size_mib} MiB, $(du -m "$out/mocap-box.img" | cut -f1) MiB allocated, read-only), mocap-state.img (/var, ${state_mib} MiB), vmlinuz, initrd.img ($abi)"
