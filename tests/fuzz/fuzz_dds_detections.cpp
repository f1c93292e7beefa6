// libFuzzer target: the detections samples a fusion node reads over DDS (runtime/dds/
// wire_codec.h, decode()). A foreign or broken writer controls every field, so the bytes build
// a mocap_wire_Detections as the deserialiser would hand it over: names filling their whole
// array (terminated or not), any numbers (NaN, infinities, negatives), and sequence lengths
// within and beyond the IDL bounds (joints 32, candidates 64, limbs 64, affinities 4096), each
// sequence's buffer holding exactly its length. decode() must give detections or an Error,
// never crash, hang, leak or read out of bounds (ASan/UBSan are on in the fuzz build). What it
// accepts must encode (DetectionsEncoder) and decode again to the same detections.
// Seeds: tests/fuzz/corpus/dds_detections/ (tests/fuzz/make_dds_corpus.py).
#include <fuzzer/FuzzedDataProvider.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "runtime/dds/wire_codec.h"
#include "runtime/skeleton/topology.h"

namespace {

using mocap::SkeletonTopology;

const SkeletonTopology& pick_topology(std::uint8_t b) {
  switch (b % 3) {
    case 0:
      return mocap::body19_topology();
    case 1:
      return mocap::coco17_topology();
    default:
      return mocap::body25_topology();
  }
}

template <std::size_t N>
void fill_name(FuzzedDataProvider& in, char (&field)[N], const char* usual) {
  if (in.ConsumeBool()) {  // a sane, terminated name (most real samples)
    std::strncpy(field, usual, N - 1);
    return;
  }
  const std::vector<std::uint8_t> bytes = in.ConsumeBytes<std::uint8_t>(N);
  if (!bytes.empty()) std::memcpy(field, bytes.data(), bytes.size());  // maybe no NUL
}

float any_float(FuzzedDataProvider& in) {
  const std::uint32_t bits = in.ConsumeIntegral<std::uint32_t>();
  float f = 0;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

// A sequence length: usually `usual`, else anything up to a little past `bound`.
std::uint32_t length(FuzzedDataProvider& in, std::uint32_t usual, std::uint32_t bound) {
  return in.ConsumeBool() ? usual : in.ConsumeIntegralInRange<std::uint32_t>(0, bound + 8);
}

// The sample and the buffers its sequences point into.
struct Sample {
  mocap_wire_Detections s{};
  std::vector<mocap_wire_JointCandidates> joints;
  std::vector<std::vector<mocap_wire_Candidate>> candidates;
  std::vector<mocap_wire_LimbAffinity> limbs;
  std::vector<std::vector<float>> values;
};

void build(FuzzedDataProvider& in, const SkeletonTopology& topology, Sample& out) {
  mocap_wire_Detections& s = out.s;
  fill_name(in, s.camera, "cam0");
  fill_name(in, s.node, "left");
  fill_name(in, s.topology, topology.name().c_str());
  s.capture_time_ns = in.ConsumeBool() ? 1764720000000000000 : in.ConsumeIntegral<std::int64_t>();
  s.frame_count = in.ConsumeIntegral<std::uint64_t>();
  s.frame_rate_hz = in.ConsumeBool() ? 30.0 : in.ConsumeFloatingPoint<double>();
  s.width_px = in.ConsumeBool() ? 1280 : in.ConsumeIntegral<std::uint16_t>();
  s.height_px = in.ConsumeBool() ? 720 : in.ConsumeIntegral<std::uint16_t>();

  const auto joint_count = static_cast<std::uint32_t>(topology.joint_count());
  out.joints.resize(length(in, joint_count, 32));
  out.candidates.resize(out.joints.size());
  std::vector<std::uint32_t> counts(out.joints.size());
  for (std::size_t j = 0; j < out.joints.size(); ++j) {
    counts[j] = length(in, in.ConsumeIntegralInRange<std::uint32_t>(0, 3), 64);
    auto& c = out.candidates[j];
    c.resize(counts[j]);
    for (mocap_wire_Candidate& k : c) {
      if (in.ConsumeBool()) {
        k = {in.ConsumeFloatingPointInRange<float>(0.f, 1280.f),
             in.ConsumeFloatingPointInRange<float>(0.f, 720.f),
             in.ConsumeFloatingPointInRange<float>(0.f, 1.f)};
      } else {
        k = {any_float(in), any_float(in), any_float(in)};
      }
    }
    out.joints[j].candidates = {counts[j], counts[j], c.data(), false};
  }

  const auto limb_count = static_cast<std::uint32_t>(topology.limb_count());
  out.limbs.resize(length(in, limb_count, 64));
  out.values.resize(out.limbs.size());
  for (std::size_t l = 0; l < out.limbs.size(); ++l) {
    mocap_wire_LimbAffinity& a = out.limbs[l];
    // Usually the shape of the limb's candidates, else any.
    std::uint32_t rows = 0, cols = 0;
    if (l < static_cast<std::size_t>(topology.limb_count())) {
      const auto ja = static_cast<std::size_t>(topology.limb(static_cast<int>(l)).joint_a);
      const auto jb = static_cast<std::size_t>(topology.limb(static_cast<int>(l)).joint_b);
      rows = ja < counts.size() ? counts[ja] : 0;
      cols = jb < counts.size() ? counts[jb] : 0;
    }
    a.rows =
        static_cast<std::uint16_t>(in.ConsumeBool() ? rows : in.ConsumeIntegral<std::uint16_t>());
    a.cols =
        static_cast<std::uint16_t>(in.ConsumeBool() ? cols : in.ConsumeIntegral<std::uint16_t>());
    // rows x cols may be up to 65535^2: the deserialiser never hands over more than a little
    // past the bound here (it refuses the sample), so neither does the fuzzer.
    const std::uint32_t n = length(
        in, std::min<std::uint32_t>(static_cast<std::uint32_t>(a.rows) * a.cols, 4104), 4096);
    out.values[l].resize(n);
    for (float& v : out.values[l]) {
      v = in.ConsumeBool() ? in.ConsumeFloatingPointInRange<float>(0.f, 1.f) : any_float(in);
    }
    a.values = {n, n, out.values[l].data(), false};
  }
  s.joints = {static_cast<std::uint32_t>(out.joints.size()),
              static_cast<std::uint32_t>(out.joints.size()), out.joints.data(), false};
  s.limbs = {static_cast<std::uint32_t>(out.limbs.size()),
             static_cast<std::uint32_t>(out.limbs.size()), out.limbs.data(), false};
}

bool same(const mocap::dds::CameraDetections& a, const mocap::dds::CameraDetections& b) {
  if (a.camera != b.camera || a.node != b.node || a.capture_time_ns != b.capture_time_ns ||
      a.frame_count != b.frame_count || a.frame_rate_hz != b.frame_rate_hz ||
      a.view.width_px != b.view.width_px || a.view.height_px != b.view.height_px ||
      a.view.candidates.size() != b.view.candidates.size() ||
      a.view.affinities.size() != b.view.affinities.size()) {
    return false;
  }
  for (std::size_t j = 0; j < a.view.candidates.size(); ++j) {
    const auto& x = a.view.candidates[j];
    const auto& y = b.view.candidates[j];
    if (x.size() != y.size()) return false;
    for (std::size_t c = 0; c < x.size(); ++c) {
      if (x[c].x_px != y[c].x_px || x[c].y_px != y[c].y_px || x[c].score != y[c].score) {
        return false;
      }
    }
  }
  for (std::size_t l = 0; l < a.view.affinities.size(); ++l) {
    const auto& x = a.view.affinities[l];
    const auto& y = b.view.affinities[l];
    if (x.rows != y.rows || x.cols != y.cols || x.values != y.values) return false;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  const SkeletonTopology& topology = pick_topology(in.ConsumeIntegral<std::uint8_t>());
  Sample sample;
  build(in, topology, sample);

  auto decoded = mocap::dds::decode(sample.s, topology);
  if (!decoded.ok()) {
    if (decoded.error().message().empty()) std::abort();
    return 0;
  }
  mocap::dds::DetectionsEncoder encoder;
  if (!encoder.encode(*decoded, topology).ok()) std::abort();
  // The names go into mocapd's status JSON: they must print (UTF-8), never throw.
  (void)nlohmann::json({{"camera", decoded->camera}, {"node", decoded->node}}).dump();
  auto again = mocap::dds::decode(encoder.sample(), topology);
  if (!again.ok() || !same(*decoded, *again)) std::abort();
  return 0;
}
