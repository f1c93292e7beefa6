// Still-image decoding for offline inputs and tests: JPEG (libturbojpeg) and PNG (libpng) into
// packed 8-bit RGB. The format is chosen by the file's magic bytes, never by its extension.
//
//   auto img = mocap::image::load_image("photo.jpg");
//   if (!img) return img.error();          // names the file and what is wrong with it
//   use(img->width_px, img->height_px, img->rgb);
//
// Conversions: gray and gray+alpha are replicated to RGB; palette is expanded; 16-bit samples
// are rounded to 8 bits (v * 255 / 65535); alpha is dropped (not composited). JPEG uses
// libjpeg's default accurate IDCT and smooth chroma upsampling, so pixels match other
// libjpeg-based decoders. Damaged data is an error, never a partially grey image.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::image {

// Largest accepted width or height; larger images are rejected before any pixel is allocated.
inline constexpr int kMaxImageSidePx = 16384;

// Row-major, top row first, 3 bytes (R, G, B) per pixel, no row padding:
// rgb.size() == width_px * height_px * 3.
struct ImageRgb8 {
  int width_px = 0;
  int height_px = 0;
  std::vector<std::uint8_t> rgb{};

  std::size_t pixel_offset(int x_px, int y_px) const {
    return (static_cast<std::size_t>(y_px) * static_cast<std::size_t>(width_px) +
            static_cast<std::size_t>(x_px)) *
           3;
  }
};

enum class ImageFormat { kUnknown, kJpeg, kPng };

// Identifies JPEG (FF D8 FF) and PNG (89 'PNG' 0D 0A 1A 0A) by their first bytes.
ImageFormat sniff_format(std::span<const std::uint8_t> bytes);

// Reads and decodes a JPEG or PNG file. Errors: kNotFound (no such file), kParse (not a
// JPEG/PNG, truncated or corrupt data), kUnsupported (other image formats, CMYK JPEG, larger
// than kMaxImageSidePx), kIo (unreadable). Every message starts with the file name.
Result<ImageRgb8> load_image(const std::filesystem::path& path);

// Decodes an in-memory JPEG or PNG; `name` prefixes error messages (a file name, a camera).
Result<ImageRgb8> decode_image(std::span<const std::uint8_t> bytes, std::string_view name);

// Encodes a JPEG (4:2:0, quality in [1, 100]) with libturbojpeg. kInvalidArgument when the
// image is inconsistent or empty.
Result<std::vector<std::uint8_t>> encode_jpeg(const ImageRgb8& image, int quality);

// Encodes a PNG (8-bit RGB, libpng's default compression). kInvalidArgument when the image is
// inconsistent or empty.
Result<std::vector<std::uint8_t>> encode_png(const ImageRgb8& image);
// encode_png into a file; kIo names the file when it cannot be written.
Status save_png(const ImageRgb8& image, const std::filesystem::path& path);

// Writes a binary PPM (P6), for debugging. kInvalidArgument when the image is inconsistent.
Status save_ppm(const ImageRgb8& image, const std::filesystem::path& path);

}  // namespace mocap::image
