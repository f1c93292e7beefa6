// libFuzzer target: decode_image() (runtime/image/image.h) on arbitrary bytes: MJPEG frames from
// USB cameras (mocapd's camera thumbnails, the V4L2 backend) and the photos `mocap infer`
// reads, JPEG through libturbojpeg and PNG through libpng (the system's, not instrumented).
// Every input must give an image of the size it says or an Error, never crash, hang, leak or
// write out of bounds in mocap-box's code (ASan/UBSan are on for it). Seeds:
// tests/fuzz/corpus/image_decode/.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "runtime/image/image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto image = mocap::image::decode_image(std::span<const std::uint8_t>(data, size), "fuzz");
  if (!image.ok()) {
    if (image.error().message().empty()) std::abort();
    return 0;
  }
  if (image->width_px <= 0 || image->height_px <= 0 ||
      image->rgb.size() != static_cast<std::size_t>(image->width_px) *
                               static_cast<std::size_t>(image->height_px) * 3) {
    std::abort();
  }
  return 0;
}
