// CPU reference of the network input pre-processing: a camera frame (RGB24, YUYV 4:2:2 or NV12
// 4:2:0, any row stride) letterboxed into an SxS square (aspect kept, bilinear with half-pixel
// centres, centred, borders filled with black), normalised to [-1, 1] (u8 / 127.5 - 1,
// PoseNet's convention), NHWC float32. The mapping back from network-input pixels to image
// pixels is returned with it. shaders/preprocess_frame.comp is the GPU version of
// letterbox_frame and is tested against it.
//
// Colour: YUYV and NV12 are BT.601 limited range ("studio swing", Y in [16, 235]), the V4L2
// default colourspace of UVC webcams (V4L2_COLORSPACE_SMPTE170M / V4L2_YCBCR_ENC_601 /
// V4L2_QUANTIZATION_LIM_RANGE). Each source pixel is converted to RGB in float (clamped to
// [0, 255], not rounded) before the bilinear filter; chroma is taken from the sample covering
// the pixel (no chroma interpolation: YUYV shares U, V over a pixel pair, NV12 over 2x2).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"
#include "runtime/nn/cpu_ops.h"

namespace mocap::nn {

struct Letterbox {
  double scale = 1;        // network px per image px
  double offset_x_px = 0;  // network-input position of image x = 0
  double offset_y_px = 0;
  // Image pixel of a network-input pixel.
  double image_x(double net_x) const { return (net_x - offset_x_px) / scale; }
  double image_y(double net_y) const { return (net_y - offset_y_px) / scale; }
};

// The letterbox of a width x height image in an out_w x out_h input, with the half-open ranges
// of output columns and rows whose centres fall on the image (the rest is black border). The
// CPU reference and the GPU kernel both use these ranges, so they agree on every border pixel.
struct LetterboxGrid {
  Letterbox box;
  int x_begin = 0;
  int x_end = 0;
  int y_begin = 0;
  int y_end = 0;
};
LetterboxGrid letterbox_grid(int width_px, int height_px, int out_w_px, int out_h_px);

// A crop: the square of side side_px image pixels centred on (center_x_px, center_y_px),
// scaled to fill min(out_w, out_h) and centred in the out_w x out_h input. Parts of the square
// outside the image are black border, as in a letterbox.
Letterbox crop_letterbox(double center_x_px, double center_y_px, double side_px, int out_w_px,
                         int out_h_px);
// The grid of any mapping (a letterbox or a crop) of a width x height image into an
// out_w x out_h input: the output columns and rows whose centres fall on the image.
LetterboxGrid crop_grid(const Letterbox& box, int width_px, int height_px, int out_w_px,
                        int out_h_px);

// A camera frame's bytes as pre-processing reads them (no ownership).
//  RGB24: 3 bytes per pixel (R, G, B).
//  YUYV:  4 bytes per pixel pair (Y0, U, Y1, V); width must be even.
//  NV12:  a Y plane (1 byte per pixel), then an interleaved U, V plane at half resolution in
//         both directions with the same row stride; width and height must be even.
struct FrameView {
  std::span<const std::uint8_t> bytes;
  int width_px = 0;
  int height_px = 0;
  int stride_bytes = 0;  // bytes per row of the first plane; 0 = tightly packed
  PixelFormat format = PixelFormat::kRGB24;
  // NV12 only: byte offset of the U, V plane; 0 = right after the Y plane (stride * height,
  // V4L2 single-planar NV12).
  std::size_t uv_offset_bytes = 0;
};

// The view of a captured frame (runtime/msg): its buffer, size, row stride, format and NV12
// plane offset, as the capture backend or the decoder described them. The one place a Frame's
// geometry becomes what pre-processing reads; a frame without a buffer gives an empty view,
// which validate_frame rejects.
FrameView frame_view(const Frame& frame);

// The row stride a frame uses (stride_bytes, or the packed stride when 0) and the UV-plane
// offset (NV12), after validate_frame succeeded.
int frame_stride_bytes(const FrameView& frame);
std::size_t frame_uv_offset_bytes(const FrameView& frame);

// Checks size, format, parity, stride and byte count; the error says what is wrong and what
// was expected. kUnsupported for formats pre-processing does not read (GREY, MJPEG).
Status validate_frame(const FrameView& frame);

// BT.601 limited range to RGB in [0, 255] (float, clamped), the conversion both the CPU
// reference and the GPU kernel use.
void yuv_to_rgb_bt601_limited(float y, float u, float v, float rgb[3]);

// The network input's values: RGB in [0, 255] / divisor + offset (black, also the border:
// offset). The default is [-1, 1] (PoseNet, MoveNet's cut); BlazePose takes [0, 1].
struct InputRange {
  float divisor = 127.5f;
  float offset = -1.f;
};
inline constexpr InputRange kSignedUnitInput{};
inline constexpr InputRange kUnitInput{255.f, 0.f};

// Writes batch item `n` of `out` (shape [N, H, W, 3], allocated by the caller).
Result<Letterbox> letterbox_frame(const FrameView& frame, Tensor& out, int n = 0);

// The general form both use: batch item `n` of `out` through `grid` (letterbox_grid or
// crop_grid of this frame's size and out's), the pixels outside it black.
// shaders/preprocess_frame.comp takes the same grid, so GPU crops are tested against this.
Result<Letterbox> resample_frame(const FrameView& frame, const LetterboxGrid& grid, Tensor& out,
                                 int n = 0, InputRange range = kSignedUnitInput);

// letterbox_frame of a packed RGB24 image.
Result<Letterbox> letterbox_rgb8(std::span<const std::uint8_t> rgb, int width_px, int height_px,
                                 Tensor& out, int n = 0);

}  // namespace mocap::nn
