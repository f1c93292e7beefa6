// libFuzzer target: parse_board_json() (hal/board.h, board/<name>/board.json) on arbitrary
// bytes must give a Board or an Error, never crash, hang, leak or throw (ASan/UBSan are on in
// the fuzz build). A parsed board must satisfy the documented ranges. Seeds:
// tests/fuzz/corpus/board_json/ (the shipped boards and a few broken ones).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "hal/board.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  mocap::Result<mocap::hal::Board> b = mocap::hal::parse_board_json(text, "fuzz/board.json");
  if (!b.ok()) {
    if (b.error().message().empty()) std::abort();
    return 0;
  }
  if (!(b->frame_rate_hz > 0 && b->frame_rate_hz <= 1000) || b->max_cameras < 1 ||
      b->max_cameras > 32) {
    std::abort();
  }
  if (b->trigger.mode != mocap::hal::SyncMode::kSoftware &&
      (b->trigger.gpio_chip.empty() || b->trigger.gpio_line.empty())) {
    std::abort();
  }
  return 0;
}
