#version 450
// Camera frame -> network input: RGB24 / YUYV / NV12 bytes (any row stride), letterboxed into
// out_w x out_h (aspect kept, bilinear with half-pixel centres, centred, black borders),
// normalised to [-1, 1] (or another range: value_divisor, value_offset), NHWC float32, written at batch item n. GPU version of
// nn::letterbox_frame (runtime/nn/preprocess.cpp), which documents the conventions: BT.601
// limited-range YUV, colour converted per source pixel before the filter, chroma not
// interpolated. One invocation per output pixel. The frame bytes are read as 32-bit words
// (no 8-bit storage needed).
layout(local_size_x_id = 0) in;
layout(constant_id = 1) const int FORMAT = 0;  // 0 RGB24, 1 YUYV, 2 NV12

layout(std430, binding = 0) readonly buffer Src { uint src[]; };
layout(std430, binding = 1) writeonly buffer Out { float y[]; };

layout(push_constant) uniform Params {
  int src_base;   // byte offset of the frame in src
  int src_w;      // image pixels
  int src_h;
  int stride;     // bytes per row
  int uv_offset;  // NV12: byte offset of the UV plane from src_base
  int out_w;
  int out_h;
  int n;          // batch item written
  int x_begin;    // output columns [x_begin, x_end) and rows [y_begin, y_end) show the image
  int x_end;
  int y_begin;
  int y_end;
  float scale;    // network px per image px
  float offset_x;
  float offset_y;
  float value_divisor;  // RGB in [0, 255] / value_divisor + value_offset (black: value_offset)
  float value_offset;
} pc;

float byte_at(int i) {
  const int j = pc.src_base + i;
  return float((src[j >> 2] >> ((j & 3) * 8)) & 0xffu);
}

vec3 yuv_to_rgb(float Y, float U, float V) {
  const float c = 1.164383 * (Y - 16.0);
  const float d = U - 128.0;
  const float e = V - 128.0;
  return clamp(vec3(c + 1.596027 * e, c - 0.391762 * d - 0.812968 * e, c + 2.017232 * d), 0.0,
               255.0);
}

vec3 sample_rgb(int x, int yy) {
  const int row = yy * pc.stride;
  if (FORMAT == 0) {
    const int p = row + x * 3;
    return vec3(byte_at(p), byte_at(p + 1), byte_at(p + 2));
  } else if (FORMAT == 1) {
    const int p = row + (x >> 1) * 4;
    return yuv_to_rgb(byte_at(p + (x & 1) * 2), byte_at(p + 1), byte_at(p + 3));
  }
  const int uv = pc.uv_offset + (yy >> 1) * pc.stride + (x >> 1) * 2;
  return yuv_to_rgb(byte_at(row + x), byte_at(uv), byte_at(uv + 1));
}

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  if (gid >= pc.out_w * pc.out_h) return;
  const int x = gid % pc.out_w;
  const int yy = gid / pc.out_w;
  const int o = ((pc.n * pc.out_h + yy) * pc.out_w + x) * 3;
  if (x < pc.x_begin || x >= pc.x_end || yy < pc.y_begin || yy >= pc.y_end) {
    y[o] = pc.value_offset;
    y[o + 1] = pc.value_offset;
    y[o + 2] = pc.value_offset;
    return;
  }
  const float sx = (float(x) + 0.5 - pc.offset_x) / pc.scale - 0.5;
  const float sy = (float(yy) + 0.5 - pc.offset_y) / pc.scale - 0.5;
  const float cx = clamp(sx, 0.0, float(pc.src_w - 1));
  const float cy = clamp(sy, 0.0, float(pc.src_h - 1));
  const int x0 = int(cx);
  const int y0 = int(cy);
  const int x1 = min(x0 + 1, pc.src_w - 1);
  const int y1 = min(y0 + 1, pc.src_h - 1);
  const float fx = cx - float(x0);
  const float fy = cy - float(y0);
  const vec3 top = sample_rgb(x0, y0) * (1.0 - fx) + sample_rgb(x1, y0) * fx;
  const vec3 bot = sample_rgb(x0, y1) * (1.0 - fx) + sample_rgb(x1, y1) * fx;
  const vec3 v = (top * (1.0 - fy) + bot * fy) / pc.value_divisor + pc.value_offset;
  y[o] = v.x;
  y[o + 1] = v.y;
  y[o + 2] = v.z;
}
