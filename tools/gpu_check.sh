#!/usr/bin/env bash
# tools/gpu_check.sh [BUILD_DIR]: what the CNN does on whatever Vulkan device is present (a
# hardware GPU when one is at hand; lavapipe or SwiftShader otherwise, or the device named by
# MOCAP_VULKAN_DEVICE / VK_ICD_FILENAMES). Prints the devices and their limits (`mocap gpu`),
# runs the GPU correctness tests (kernels against the CPU reference, heads against TF.js), then
# `mocap bench cnn` for every model and input size, and ends with one table: ms per view,
# GFLOP/s achieved, and % of the device's peak where it can be estimated (Vulkan reports no
# clock or core count: "n/a" unless MOCAP_GPU_PEAK_GFLOPS gives the datasheet figure).
# Record the table in docs/gpu.md whenever it ran on a hardware GPU.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
B=${1:-build}
mocap="$B/bin/mocap"
[ -x "$mocap" ] || { echo "gpu_check: $mocap not built (bash tools/setup.sh --no-run)" >&2; exit 2; }
"$mocap" gpu
echo "== GPU correctness tests"
ctest --test-dir "$B" -L gpu -LE "e2e|swiftshader|minimum_limits" --output-on-failure -j "$(nproc)"
peak=${MOCAP_GPU_PEAK_GFLOPS:-}
rows=()
for spec in posenet:257 posenet:353 posenet:513 movenet-multipose:256 movenet-multipose:448 \
    movenet-multipose:512 movenet-thunder:256 movenet-lightning:192; do
  model=${spec%%:*}
  size=${spec##*:}
  file=models/$model.mcnn
  if [ ! -f "$file" ]; then
    rows+=("$(printf '%-20s %5s  %s' "$model" "$size" "model not installed (tools/fetch_models.sh)")")
    continue
  fi
  out=$("$mocap" bench cnn --model "$file" --input-size-px "$size" --runs 20 --no-tfjs 2>&1) || {
    rows+=("$(printf '%-20s %5s  %s' "$model" "$size" "failed: $(echo "$out" | tail -n 1)")")
    continue
  }
  device=$(echo "$out" | sed -n 's/^cnn: .* on \(.*\)$/\1/p' | head -n 1)
  ms=$(echo "$out" | sed -n 's/^ms_per_frame=\([0-9.]*\).*/\1/p')
  gflops=$(echo "$out" | sed -n 's/^gflop_per_s=\([0-9.]*\).*/\1/p')
  pct=n/a
  if [ -n "$peak" ] && [ -n "$gflops" ]; then pct=$(echo "scale=1; 100 * $gflops / $peak" | bc); fi
  rows+=("$(printf '%-20s %5s %10s %10s %8s  %s' "$model" "$size" "$ms" "$gflops" "$pct" "$device")")
done
echo "== CNN per view (mocap bench cnn, batch 1, median of 20)"
printf '%-20s %5s %10s %10s %8s  %s\n' model size ms/view GFLOP/s %peak device
for r in "${rows[@]}"; do echo "$r"; done
