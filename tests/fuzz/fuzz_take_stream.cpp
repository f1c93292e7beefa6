// libFuzzer target: a take as `mocap export` and mocapd's take list read it (runtime/out/
// take_reader.h): the input as the stream file's bytes (parse_stream_text: the "skeletons"
// lines on the fast scanner or through nlohmann::json, skipped messages, a cut-off last line)
// and as the take.json sidecar (parse_take_json). Arbitrary bytes must give a take or an
// Error, never crash, hang, leak or read out of bounds (ASan/UBSan are on in the fuzz build).
// Seeds: tests/fuzz/corpus/take_stream/.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "runtime/out/take_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);

  auto take = mocap::out::parse_stream_text(text, "fuzz/skeletons.ndjson");
  if (take.ok()) {
    // Invariants of a read take: frames, one skeleton, confidences in [0, 1] (0 when unseen).
    if (take->frames.empty() || take->topology.empty() || take->partial_lines > 1) std::abort();
    const std::size_t joints = take->joint_names.size();
    for (const mocap::out::TakeFrame& f : take->frames) {
      for (const mocap::out::TakePerson& p : f.persons) {
        if (p.joints_m.size() != joints || p.confidence.size() != joints) std::abort();
        for (std::size_t j = 0; j < joints; ++j) {
          const float c = p.confidence[j];
          if (!(c >= 0.f && c <= 1.f)) std::abort();
          if (c > 0.f && !p.joints_m[j].allFinite()) std::abort();
        }
      }
    }
  } else if (take.error().message().empty()) {
    std::abort();
  }

  auto meta = mocap::out::parse_take_json(text, "fuzz/take.json");
  if (meta.ok() ? !meta->is_object() : meta.error().message().empty()) std::abort();
  return 0;
}
