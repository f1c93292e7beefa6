// How a network kernel reads its two inputs (bindings 0 and 1; an include, not a kernel).
// Uniform texel buffers (texelFetch) by default: on lavapipe a texel fetch is a branch-free
// gather while a storage-buffer load is a per-lane loop (docs/gpu.md). A texel view holds at
// most maxTexelBufferElements texels, which the Vulkan spec guarantees only to 65536 (1 MiB of
// vec4: what Mali GPUs and SwiftShader give), so every kernel is also compiled with
// STORAGE_INPUTS: the same inputs as storage buffers, any size up to maxStorageBufferRange. The
// network picks the variant per step from the device's limits (runtime/gpu/network.cpp).
#ifdef STORAGE_INPUTS
layout(std430, binding = 0) readonly buffer In0 { vec4 in0_[]; };
layout(std430, binding = 1) readonly buffer In1 { vec4 in1_[]; };
#define IN0(i) in0_[i]
#define IN1(i) in1_[i]
#else
layout(binding = 0) uniform samplerBuffer in0_;
layout(binding = 1) uniform samplerBuffer in1_;
#define IN0(i) texelFetch(in0_, i)
#define IN1(i) texelFetch(in1_, i)
#endif
