#!/usr/bin/env bash
# CTest's hil.vm: boots the QEMU guest (tests/hil/vm/run_vm.sh, which builds and caches the
# kernel, the out-of-tree modules and the initramfs on first use) and runs tests/hil/guest.sh
# there against BUILD_DIR's binaries. Passes when every guest check passes.
# Without QEMU: a skip (exit 77) outside CI, a failure in CI (CI=true), where it must run.
#
#   run_hil.sh BUILD_DIR
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
BUILD=$(cd "${1:?usage: run_hil.sh BUILD_DIR}" && pwd)
if ! command -v qemu-system-x86_64 >/dev/null; then
  if [[ ${CI:-} == true ]]; then
    echo "HIL: qemu-system-x86_64 not found, and CI must run this test (tools/setup.sh installs it)" >&2
    exit 1
  fi
  echo "HIL: skipped, qemu-system-x86_64 not found (install qemu-system-x86, or run tools/setup.sh)"
  exit 77
fi
ROOT=$(cd "$HERE/../.." && pwd)
# The guest sees the host's / read-only but has its own tmpfs on /tmp, /run and /dev/shm: the
# checkout and the build folder are shared explicitly (a CI clone may live under /tmp).
shares=(--share "$ROOT")
[[ $BUILD == "$ROOT"/* ]] || shares+=(--share "$BUILD")
cd "$ROOT"
start=$(date +%s)
rc=0
"$HERE/vm/run_vm.sh" --timeout "${MOCAP_HIL_TIMEOUT:-420}" "${shares[@]}" -- "$HERE/guest.sh" "$BUILD" || rc=$?
echo "HIL: guest exit status $rc after $(($(date +%s) - start)) s"
if [[ $rc -eq 77 && ${CI:-} == true ]]; then
  echo "HIL: the VM could not run, and CI must run this test" >&2
  exit 1
fi
exit "$rc"
