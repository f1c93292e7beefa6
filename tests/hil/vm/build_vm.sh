#!/usr/bin/env bash
# build_vm.sh - build (or verify) the cached hardware-in-the-loop guest.
#
# The host kernel has no module support and no media/GPIO subsystems, so the
# HIL tests run inside a QEMU (TCG) guest that boots Debian's own kernel and
# sees the host's root filesystem read-only over virtio-9p (see
# docs in /work/shared/docs/vm-hil.md and tests/hil/vm/README.md).
#
# This script produces, under ${MOCAP_HIL_CACHE:-$HOME/.cache/mocap-box/hil}/<abi>/:
#   kernel/vmlinuz          Debian's linux-image-<abi> kernel (not installed on the host)
#   modroot/lib/modules/<abi>/
#                           Debian's modules + out-of-tree gpio-sim, irq_sim and vimc
#                           (updates/mocap-hil/), depmod'ed: use `modprobe -d modroot`
#   initramfs.cpio.gz       busybox initramfs (tests/hil/vm/initramfs_init.sh as /init)
#   versions.txt            what was used (kernel, headers, source versions)
#
# Every step is cached behind a stamp file whose content records its inputs; a
# second run only verifies and prints "cached". Safe to run concurrently (flock).
#
# Usage: build_vm.sh [--print-dir] [--quiet]
#   --print-dir  print the <abi> cache directory on stdout when done
#   --quiet      no progress messages (errors and warnings are still printed)
# Environment:
#   MOCAP_HIL_CACHE  cache root (default $HOME/.cache/mocap-box/hil)
#   MOCAP_HIL_ABI    force a kernel ABI (e.g. 6.1.0-56-amd64) instead of asking apt
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
CACHE_ROOT=${MOCAP_HIL_CACHE:-${HOME:-/root}/.cache/mocap-box/hil}

# Bump a step's recipe version when the way that step builds changes; the
# stamp then no longer matches and the step (and the ones after it) rerun.
RECIPE_IMAGE=1
RECIPE_SOURCE=1
RECIPE_OOT=1
RECIPE_MODROOT=1
RECIPE_INITRAMFS=1

# The source files the out-of-tree modules need, relative to the top of the
# linux-source tree. Only these members are extracted from the ~1.3 GB tarball.
SRC_MEMBERS=(
    Makefile
    drivers/gpio/gpio-sim.c
    drivers/gpio/gpiolib.h
    kernel/irq/irq_sim.c
    drivers/media/test-drivers/vimc
)

# Modules the initramfs loads before it can mount the 9p shares and configfs.
INITRAMFS_MODULES=(virtio_pci 9pnet_virtio 9p configfs)

print_dir=0
quiet=0
while (($#)); do
    case $1 in
    --print-dir) print_dir=1 ;;
    --quiet) quiet=1 ;;
    -h | --help)
        sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
        exit 0
        ;;
    *)
        echo "build_vm.sh: unknown argument '$1' (see --help)" >&2
        exit 2
        ;;
    esac
    shift
done

log() { ((quiet)) || echo "HIL: $*" >&2; }
warn() { echo "HIL: warning: $*" >&2; }
# die WHAT [FIX]: name the missing/broken thing and how to fix it.
die() {
    echo "HIL: error: $1" >&2
    if (($# > 1)); then echo "HIL:   fix: $2" >&2; fi
    exit 1
}

# ---------------------------------------------------------------- host tools
# need_cmd COMMAND PACKAGE
need_cmd() {
    command -v "$1" >/dev/null 2>&1 ||
        die "host command '$1' not found" "apt-get install -y $2   (or run tools/setup.sh)"
}
need_cmd apt-get apt
need_cmd apt-cache apt
need_cmd dpkg-deb dpkg
need_cmd dpkg-query dpkg
need_cmd tar tar
need_cmd xz xz-utils
need_cmd gzip gzip
need_cmd cpio cpio
need_cmd depmod kmod
need_cmd modprobe kmod
need_cmd make make
need_cmd gcc gcc
need_cmd strip binutils
need_cmd flock util-linux
need_cmd sha256sum coreutils
[[ -x /bin/busybox ]] ||
    die "/bin/busybox not found (needed for the guest initramfs)" \
        "apt-get install -y busybox-static   (or run tools/setup.sh)"
# The initramfs has no libc, so busybox must be the static build.
if ldd /bin/busybox >/dev/null 2>&1; then
    die "/bin/busybox is dynamically linked (package busybox, not busybox-static)" \
        "apt-get install -y busybox-static"
fi

mkdir -p "$CACHE_ROOT" || die "cannot create cache dir $CACHE_ROOT" "set MOCAP_HIL_CACHE to a writable directory"

# Serialise concurrent builds (e.g. several run_vm.sh from a parallel ctest).
exec 9>"$CACHE_ROOT/.lock"
flock 9

# ---------------------------------------------------------------- kernel ABI
# The guest kernel is whatever linux-image-amd64 currently depends on, e.g.
# "Depends: linux-image-6.1.0-56-amd64 (= 6.1.192-2)" -> ABI 6.1.0-56-amd64,
# Debian version 6.1.192-2 (security updates bump both). Each apt-cache call
# costs ~1 s here (no binary package cache), so the answer is remembered
# until the package lists or the apt configuration change.
sum() { sha256sum | cut -c1-16; }
resolve_abi() {
    local out line key memo=$CACHE_ROOT/.resolved
    if [[ -n ${MOCAP_HIL_ABI:-} ]]; then
        echo "$MOCAP_HIL_ABI"
        return
    fi
    key=$(find /var/lib/apt/lists /etc/apt -maxdepth 2 -printf '%p %T@ %s\n' 2>/dev/null | LC_ALL=C sort | sum)
    if [[ -f $memo ]]; then
        read -r line <"$memo" || true
        if [[ $line == "$key "* ]]; then
            echo "${line#"$key "}"
            return
        fi
    fi
    # Same answer as `apt-cache depends linux-image-amd64`, plus the version.
    out=$(apt-cache show --no-all-versions linux-image-amd64 2>/dev/null) || return 1
    local dep deps=()
    while IFS= read -r line; do
        if [[ $line == Depends:* ]]; then
            IFS=',|' read -r -a deps <<<"${line#Depends:}"
            break
        fi
    done <<<"$out"
    for dep in "${deps[@]}"; do
        if [[ $dep =~ ^[[:space:]]*linux-image-([0-9][^[:space:]]*-amd64)([[:space:]]+\(=[[:space:]]*([^\)]+)\))?[[:space:]]*$ ]]; then
            echo "$key ${BASH_REMATCH[1]} ${BASH_REMATCH[3]}" >"$memo"
            echo "${BASH_REMATCH[1]} ${BASH_REMATCH[3]}"
            return
        fi
    done
    return 1
}

# A cache entry is complete when its last step (initramfs) has a stamp.
newest_cached_abi() {
    local d best=
    for d in "$CACHE_ROOT"/*/; do
        [[ -f $d/.stamp-initramfs && -f $d/kernel/vmlinuz ]] || continue
        best+="$(basename "$d")"$'\n'
    done
    [[ -n $best ]] || return 1
    printf '%s' "$best" | sort -V | tail -n 1
}

img_ver= # Debian version of linux-image-<abi>, when apt names it
if resolved=$(resolve_abi); then
    read -r abi img_ver <<<"$resolved"
else
    if abi=$(newest_cached_abi); then
        warn "cannot resolve the kernel ABI from apt (linux-image-amd64); using cached $abi"
    else
        die "cannot resolve the kernel ABI: apt's linux-image-amd64 depends on no linux-image-<abi>-amd64" \
            "apt-get update (the package lists are missing), or set MOCAP_HIL_ABI=6.1.0-NN-amd64"
    fi
fi
[[ $abi =~ ^([0-9]+)\.([0-9]+)\.[0-9]+-[0-9]+-amd64$ ]] ||
    die "unexpected kernel ABI '$abi'" "set MOCAP_HIL_ABI to something like 6.1.0-56-amd64"
series="${BASH_REMATCH[1]}.${BASH_REMATCH[2]}" # 6.1 -> linux-source-6.1

dir=$CACHE_ROOT/$abi
mkdir -p "$dir"
modroot=$dir/modroot
moddir=$modroot/lib/modules/$abi
headers=/usr/src/linux-headers-$abi

# ---------------------------------------------------------------- stamps
# Each step writes .stamp-<step> containing a description of its inputs; the
# step is up to date when the stamp exists and has exactly that content.
stamp_ok() { [[ -f $dir/.stamp-$1 && "$(<"$dir/.stamp-$1")" == "$2" ]]; }
stamp_set() { printf '%s' "$2" >"$dir/.stamp-$1"; }
built=0 # set when any step did work

# Candidate (installable) version of a package, empty if unknown.
candidate_version() {
    local out line
    out=$(apt-cache policy "$1" 2>/dev/null) || return 0
    while IFS= read -r line; do
        if [[ $line =~ ^[[:space:]]*Candidate:\ (.*)$ && ${BASH_REMATCH[1]} != "(none)" ]]; then
            echo "${BASH_REMATCH[1]}"
            return 0
        fi
    done <<<"$out"
}

# apt_download DESTDIR PKG[=VERSION]: fetch one .deb into DESTDIR, echo its path.
apt_download() {
    local dest=$1 spec=$2 deb
    mkdir -p "$dest"
    rm -f "$dest"/*.deb
    # apt-get download works as root without locking dpkg; the "_apt cannot
    # access" sandbox warning is harmless and filtered out.
    if ! (cd "$dest" && apt-get download -q "$spec" 2>&1 | grep -v -e 'unsandboxed as root' -e '^Get:' -e '^Fetched' >&2); then
        : # grep's status is irrelevant; success is judged by the file below
    fi
    deb=$(find "$dest" -maxdepth 1 -name '*.deb' -print -quit)
    [[ -n $deb ]] || return 1
    echo "$deb"
}

# Upstream "VERSION.PATCHLEVEL.SUBLEVEL" from a kernel Makefile.
makefile_version() {
    local v p s
    v=$(sed -n 's/^VERSION = //p' "$1")
    p=$(sed -n 's/^PATCHLEVEL = //p' "$1")
    s=$(sed -n 's/^SUBLEVEL = //p' "$1")
    echo "$v.$p.$s"
}

# ---------------------------------------------------------------- step: image
# Download linux-image-<abi>, keep the kernel and move its module tree into
# modroot. The package is never installed on the host.
img_pkg=linux-image-$abi
[[ -n $img_ver ]] || img_ver=$(candidate_version "$img_pkg")
if [[ -f $dir/.stamp-image ]] && [[ -z $img_ver ]]; then
    img_ver=$(sed -n 's/^image=//p' "$dir/.stamp-image") # offline: trust the cache
fi
[[ -n $img_ver ]] || die "apt knows no package $img_pkg" "apt-get update, or set MOCAP_HIL_ABI to an available ABI"

step_image() {
    local deb tmp
    log "downloading $img_pkg $img_ver"
    deb=$(apt_download "$dir/dl-image" "$img_pkg=$img_ver") ||
        die "apt-get download $img_pkg=$img_ver failed" "check network access and apt sources (apt-get update)"
    tmp=$dir/tmp-image
    rm -rf "$tmp" "$dir/kernel" "$modroot"
    dpkg-deb -x "$deb" "$tmp"
    mkdir -p "$dir/kernel" "$modroot/lib/modules"
    mv "$tmp/boot/vmlinuz-$abi" "$dir/kernel/vmlinuz"
    mv "$tmp/boot/config-$abi" "$dir/kernel/config"
    # bookworm ships /lib/modules; later releases may use /usr/lib/modules.
    if [[ -d $tmp/lib/modules/$abi ]]; then
        mv "$tmp/lib/modules/$abi" "$moddir"
    elif [[ -d $tmp/usr/lib/modules/$abi ]]; then
        mv "$tmp/usr/lib/modules/$abi" "$moddir"
    else
        die "$img_pkg contains no lib/modules/$abi" "report this: the package layout changed"
    fi
    rm -rf "$tmp" "$dir/dl-image"
    log "kernel $abi extracted ($(find "$moddir" -name '*.ko*' | wc -l) modules)"
}

# ---------------------------------------------------------------- step: source
# Extract only SRC_MEMBERS from linux-source-<series>, preferably the very same
# Debian version as the kernel image. The .deb holds one big tar.xz; it is
# streamed (no temporary 1.3 GB tree) and decompressed with xz threads.
src_pkg=linux-source-$series
step_source() {
    local deb ver members=() m tmp
    log "downloading $src_pkg $img_ver"
    if ! deb=$(apt_download "$dir/dl-source" "$src_pkg=$img_ver"); then
        ver=$(candidate_version "$src_pkg")
        [[ -n $ver ]] || die "apt knows no package $src_pkg" "apt-get update (needs the bookworm main/security sources)"
        warn "$src_pkg $img_ver is not downloadable; using $src_pkg $ver (kernel is $img_ver)"
        deb=$(apt_download "$dir/dl-source" "$src_pkg=$ver") ||
            die "apt-get download $src_pkg=$ver failed" "check network access and apt sources"
    fi
    ver=$(dpkg-deb -f "$deb" Version)
    for m in "${SRC_MEMBERS[@]}"; do members+=("linux-source-$series/$m"); done
    tmp=$dir/tmp-src
    rm -rf "$tmp" "$dir/src"
    mkdir -p "$tmp"
    dpkg-deb --fsys-tarfile "$deb" |
        tar -xO "./usr/src/linux-source-$series.tar.xz" |
        xz -T0 -dc |
        tar -x -C "$tmp" "${members[@]}" ||
        die "cannot extract ${SRC_MEMBERS[*]} from $deb" "delete $dir and retry; the source layout may have changed"
    mv "$tmp/linux-source-$series" "$dir/src"
    rmdir "$tmp"
    echo "$ver" >"$dir/src/.debian-version"
    rm -rf "$dir/dl-source"
    log "sources extracted from $src_pkg $ver (Makefile: $(makefile_version "$dir/src/Makefile"))"
}

# ---------------------------------------------------------------- step: headers
# The out-of-tree build needs linux-headers-<abi> installed on the host (it
# pulls linux-kbuild and the matching gcc). Installing it is harmless: it only
# adds files under /usr/src and /usr/lib/linux-kbuild-*.
headers_pkg=linux-headers-$abi
installed_version() { dpkg-query -W -f='${db:Status-Status} ${Version}' "$1" 2>/dev/null | sed -n 's/^installed //p'; }
ensure_headers() {
    if [[ -n $(installed_version "$headers_pkg") && -f $headers/Makefile ]]; then
        return
    fi
    [[ $(id -u) == 0 ]] ||
        die "$headers_pkg is not installed (needed to build gpio-sim and vimc)" \
            "run as root, or: apt-get install -y --no-install-recommends $headers_pkg"
    log "installing $headers_pkg (apt-get)"
    # Lock::Timeout: wait for a concurrently running apt instead of failing.
    # Upgrade-By-Source-Package=false: apt 2.6 would otherwise also upgrade
    # installed packages built from the same source (linux-libc-dev,
    # linux-perf), changing the host's kernel UAPI headers behind our back.
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        -o DPkg::Lock::Timeout=600 -o APT::Get::Upgrade-By-Source-Package=false \
        "$headers_pkg" >"$dir/apt-headers.log" 2>&1 ||
        {
            cat "$dir/apt-headers.log" >&2
            die "apt-get install $headers_pkg failed (log above)" "apt-get update; apt-get install -y --no-install-recommends $headers_pkg"
        }
    [[ -f $headers/Makefile ]] || die "$headers missing after installing $headers_pkg" "apt-get install --reinstall $headers_pkg"
}

# ---------------------------------------------------------------- step: oot
# Build gpio-sim (+ irq_sim, which 6.1 only has as a bool option) and vimc
# against the installed headers.
step_oot() {
    local b=$dir/oot-build
    rm -rf "$b" "$dir/oot"
    mkdir -p "$b/gpio-sim" "$b/vimc" "$dir/oot"

    cp "$dir/src/drivers/gpio/gpio-sim.c" "$dir/src/drivers/gpio/gpiolib.h" "$b/gpio-sim/"
    # irq_sim.c as a module: it calls handle_simple_irq(irq_to_desc()), and
    # irq_to_desc is not exported to modules in 6.1; generic_handle_irq() does
    # the same lookup + flow-handler call and is exported. It also needs a
    # MODULE_LICENSE to be allowed the GPL-only symbols it uses.
    sed 's/handle_simple_irq(irq_to_desc(irqnum));/generic_handle_irq(irqnum);/' \
        "$dir/src/kernel/irq/irq_sim.c" >"$b/gpio-sim/irq_sim.c"
    grep -q 'generic_handle_irq(irqnum);' "$b/gpio-sim/irq_sim.c" ||
        die "could not apply the irq_sim.c fix (source changed?)" "update step_oot in $0 for this kernel source"
    printf '\n#include <linux/module.h>\nMODULE_LICENSE("GPL");\nMODULE_DESCRIPTION("interrupt simulator (out-of-tree build for mocap-box HIL)");\n' \
        >>"$b/gpio-sim/irq_sim.c"
    printf 'obj-m := gpio-sim.o irq_sim.o\n' >"$b/gpio-sim/Kbuild"

    cp -r "$dir/src/drivers/media/test-drivers/vimc/." "$b/vimc/"

    log "building gpio-sim, irq_sim, vimc against $headers"
    # vimc's own Makefile keys on CONFIG_VIDEO_VIMC, unset in Debian's config.
    local sub
    for sub in gpio-sim vimc; do
        make -C "$headers" M="$b/$sub" CONFIG_VIDEO_VIMC=m -j"$(nproc)" modules \
            >"$b/$sub/build.log" 2>&1 || {
            cat "$b/$sub/build.log" >&2
            die "building $sub failed (log above)" "check that $headers_pkg matches the kernel source"
        }
    done
    # Debug info makes these several MB; the guest loads them over 9p.
    strip --strip-debug -o "$dir/oot/gpio-sim.ko" "$b/gpio-sim/gpio-sim.ko"
    strip --strip-debug -o "$dir/oot/irq_sim.ko" "$b/gpio-sim/irq_sim.ko"
    strip --strip-debug -o "$dir/oot/vimc.ko" "$b/vimc/vimc.ko"
    rm -rf "$b"
}

# ---------------------------------------------------------------- step: modroot
# Add the out-of-tree modules to Debian's tree and index it on the host, so
# that `modprobe -d $modroot NAME` works in the guest.
step_modroot() {
    rm -rf "$moddir/updates/mocap-hil"
    mkdir -p "$moddir/updates/mocap-hil"
    cp "$dir/oot/"*.ko "$moddir/updates/mocap-hil/"
    depmod -b "$modroot" "$abi"
    # Sanity: the new modules must resolve (gpio-sim needs irq_sim).
    modprobe -d "$modroot" -S "$abi" --show-depends gpio-sim | grep -q irq_sim.ko ||
        die "depmod did not resolve gpio-sim -> irq_sim" "delete $dir and rerun"
}

# ---------------------------------------------------------------- step: initramfs
# A busybox initramfs: /init (initramfs_init.sh) loads the modules listed in
# /lib/hil-modules/order, mounts the host root over 9p and switch_roots.
initramfs_modules() {
    # --show-depends prints "insmod PATH" lines in load order (deps first),
    # with duplicates across the requested names; keep the first occurrence.
    modprobe -d "$modroot" -S "$abi" --show-depends -a "${INITRAMFS_MODULES[@]}" |
        awk '$1 == "insmod" && !seen[$2]++ { print $2 }'
}
step_initramfs() {
    local r=$dir/tmp-initramfs ko
    log "building the initramfs"
    rm -rf "$r"
    mkdir -p "$r"/{bin,dev,proc,sys,newroot,lib/hil-modules}
    cp /bin/busybox "$r/bin/busybox"
    ln -s busybox "$r/bin/sh"
    install -m 0755 "$HERE/initramfs_init.sh" "$r/init"
    : >"$r/lib/hil-modules/order"
    while IFS= read -r ko; do
        cp "$ko" "$r/lib/hil-modules/"
        basename "$ko" >>"$r/lib/hil-modules/order"
    done < <(initramfs_modules)
    [[ -s $r/lib/hil-modules/order ]] || die "no initramfs modules resolved" "delete $dir and rerun"
    # The kernel opens /dev/console for /init before anything is mounted.
    mknod -m 600 "$r/dev/console" c 5 1 2>/dev/null || warn "mknod /dev/console failed (init will still reopen it)"
    (cd "$r" && find . -print0 | LC_ALL=C sort -z | cpio --null -o -H newc --owner=0:0 --quiet) |
        gzip -6 >"$dir/initramfs.cpio.gz.new"
    mv "$dir/initramfs.cpio.gz.new" "$dir/initramfs.cpio.gz"
    rm -rf "$r"
}

# ---------------------------------------------------------------- run the steps
start=$SECONDS

# image and source downloads are independent: run them in the background while
# the (foreground) apt-get install of the headers runs.
img_stamp="recipe=$RECIPE_IMAGE"$'\n'"image=$img_ver"
pids=()
if ! stamp_ok image "$img_stamp"; then
    built=1
    rm -f "$dir"/.stamp-*
    # Not "step && stamp": set -e is inert on the left of && in bash.
    (
        step_image
        stamp_set image "$img_stamp"
    ) &
    pids+=($!)
fi
src_stamp="recipe=$RECIPE_SOURCE series=$series members=$(printf '%s\n' "${SRC_MEMBERS[@]}" | sum) want=$img_ver"
if ! stamp_ok source "$src_stamp" || [[ ! -f $dir/src/.debian-version ]]; then
    built=1
    rm -f "$dir/.stamp-source" "$dir/.stamp-oot" "$dir/.stamp-modroot" "$dir/.stamp-initramfs"
    (
        step_source
        stamp_set source "$src_stamp"
    ) &
    pids+=($!)
fi
if [[ ! -f $dir/.stamp-oot ]]; then ensure_headers; fi
fail=0
for p in "${pids[@]}"; do wait "$p" || fail=1; done
((fail == 0)) || die "downloading/extracting the kernel packages failed (messages above)" "fix the cause and rerun $0"

src_ver=$(<"$dir/src/.debian-version")
src_up=$(makefile_version "$dir/src/Makefile")

# The oot step depends on the headers, so its stamp names their version.
# If the headers package was removed after a build, the built modules are
# still valid for the same source: keep them rather than reinstalling.
hdr_ver=$(installed_version "$headers_pkg")
oot_stamp="recipe=$RECIPE_OOT src=$src_ver headers=$hdr_ver"
oot_ok=0
if [[ -f $dir/oot/vimc.ko && -f $dir/oot/gpio-sim.ko && -f $dir/oot/irq_sim.ko && -f $dir/.stamp-oot ]]; then
    if [[ -n $hdr_ver ]]; then
        stamp_ok oot "$oot_stamp" && oot_ok=1
    elif [[ "$(<"$dir/.stamp-oot")" == "recipe=$RECIPE_OOT src=$src_ver headers="* ]]; then
        oot_ok=1
    fi
fi
if ((!oot_ok)); then
    built=1
    ensure_headers
    hdr_ver=$(installed_version "$headers_pkg")
    oot_stamp="recipe=$RECIPE_OOT src=$src_ver headers=$hdr_ver"
    rm -f "$dir/.stamp-modroot" "$dir/.stamp-initramfs"
    step_oot
    stamp_set oot "$oot_stamp"
fi

mod_stamp="recipe=$RECIPE_MODROOT image=$img_ver oot=$(cat "$dir"/oot/*.ko | sum)"
if ! stamp_ok modroot "$mod_stamp" || [[ ! -f $moddir/modules.dep ]]; then
    built=1
    rm -f "$dir/.stamp-initramfs"
    step_modroot
    stamp_set modroot "$mod_stamp"
fi

init_stamp="recipe=$RECIPE_INITRAMFS init=$(sum <"$HERE/initramfs_init.sh") busybox=$(sum </bin/busybox) mods=${INITRAMFS_MODULES[*]} image=$img_ver"
if ! stamp_ok initramfs "$init_stamp" || [[ ! -f $dir/initramfs.cpio.gz ]]; then
    built=1
    step_initramfs
    stamp_set initramfs "$init_stamp"
fi

# ---------------------------------------------------------------- verify + report
for f in "$dir/kernel/vmlinuz" "$dir/initramfs.cpio.gz" "$moddir/modules.dep" \
    "$moddir/updates/mocap-hil/gpio-sim.ko" "$moddir/updates/mocap-hil/irq_sim.ko" \
    "$moddir/updates/mocap-hil/vimc.ko" "$moddir/kernel/drivers/media/test-drivers/vivid/vivid.ko"; do
    [[ -s $f ]] || die "cache is incomplete: $f is missing" "rm -rf $dir and rerun $0"
done

# Version consistency: the modules are compiled against the headers (which
# fix the ABI and symbol CRCs) from the source package's .c files; all three
# packages should be the same Debian upload.
hdr_up=
if [[ -f /usr/src/linux-headers-${abi%-amd64}-common/Makefile ]]; then
    hdr_up=$(makefile_version "/usr/src/linux-headers-${abi%-amd64}-common/Makefile")
fi
hdr_ver=$(sed -n 's/.* headers=//p' "$dir/.stamp-oot")
{
    echo "abi=$abi"
    echo "image=$img_pkg $img_ver"
    echo "headers=$headers_pkg $hdr_ver (Makefile ${hdr_up:-?})"
    echo "source=$src_pkg $src_ver (Makefile $src_up)"
    echo "busybox=$(dpkg-query -W -f='${Version}' busybox-static 2>/dev/null || echo '?')"
} >"$dir/versions.txt"
if ((built)); then
    log "kernel  $img_pkg $img_ver"
    log "headers $headers_pkg $hdr_ver (upstream ${hdr_up:-?})"
    log "source  $src_pkg $src_ver (upstream $src_up)"
fi
if [[ $src_ver != "$hdr_ver" ]]; then
    warn "kernel source $src_ver != headers $hdr_ver; gpio-sim/vimc are built from slightly different sources"
fi
if [[ -n $hdr_up && $src_up != "$hdr_up" ]]; then
    warn "upstream versions differ: source $src_up, headers $hdr_up"
fi
if [[ $hdr_ver != "$img_ver" ]]; then
    warn "headers $hdr_ver != kernel image $img_ver"
fi

if ((built)); then
    log "built $dir in $((SECONDS - start)) s"
else
    log "cached $dir ($abi)"
fi
if ((print_dir)); then echo "$dir"; fi
