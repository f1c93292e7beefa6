// CPU reference of the network input pre-processing: an RGB8 image letterboxed into an SxS
// square (aspect kept, bilinear with half-pixel centres, centred, borders filled with black),
// normalised to [-1, 1] (u8 / 127.5 - 1, PoseNet's convention), NHWC float32. The mapping back
// from network-input pixels to image pixels is returned with it.
#pragma once

#include <cstdint>
#include <span>

#include "runtime/core/error.h"
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

// Writes batch item `n` of `out` (shape [N, S, S, 3], allocated by the caller).
Result<Letterbox> letterbox_rgb8(std::span<const std::uint8_t> rgb, int width_px, int height_px,
                                 Tensor& out, int n = 0);

}  // namespace mocap::nn
