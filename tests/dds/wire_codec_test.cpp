// The wire codec: a view survives encode -> CDR -> decode exactly; every malformed field a
// foreign or broken writer could send is refused with the camera and the field named.
#include "runtime/dds/wire_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "runtime/skeleton/topology.h"

namespace mocap::dds {
namespace {

CameraDetections sample_view() {
  const SkeletonTopology& t = body19_topology();
  CameraDetections c;
  c.camera = "sim3";
  c.node = "box-a";
  c.capture_time_ns = 1796000000000000000;
  c.frame_count = 42;
  c.frame_rate_hz = 120;
  c.view.width_px = 1032;
  c.view.height_px = 776;
  c.view.candidates.resize(static_cast<std::size_t>(t.joint_count()));
  for (int j = 0; j < t.joint_count(); ++j) {
    for (int k = 0; k < (j % 3); ++k) {
      c.view.candidates[static_cast<std::size_t>(j)].push_back(
          {100.f + static_cast<float>(j), 200.f + static_cast<float>(k), 0.5f});
    }
  }
  for (const Limb& l : t.limbs()) {
    const auto rows =
        static_cast<int>(c.view.candidates[static_cast<std::size_t>(l.joint_a)].size());
    const auto cols =
        static_cast<int>(c.view.candidates[static_cast<std::size_t>(l.joint_b)].size());
    c.view.affinities.emplace_back(rows, cols, 0.25f);
  }
  return c;
}

TEST(WireCodec, RoundTripIsExact) {
  DetectionsEncoder enc;
  const CameraDetections in = sample_view();
  ASSERT_TRUE(enc.encode(in, body19_topology()).ok());
  auto out = decode(enc.sample(), body19_topology());
  ASSERT_TRUE(out.ok()) << out.error().message();
  EXPECT_EQ(out->camera, "sim3");
  EXPECT_EQ(out->node, "box-a");
  EXPECT_EQ(out->capture_time_ns, in.capture_time_ns);
  EXPECT_EQ(out->frame_count, 42u);
  ASSERT_EQ(out->view.candidates.size(), in.view.candidates.size());
  for (std::size_t j = 0; j < in.view.candidates.size(); ++j) {
    ASSERT_EQ(out->view.candidates[j].size(), in.view.candidates[j].size());
    for (std::size_t k = 0; k < in.view.candidates[j].size(); ++k) {
      EXPECT_EQ(out->view.candidates[j][k].x_px, in.view.candidates[j][k].x_px);
    }
  }
  ASSERT_EQ(out->view.affinities.size(), in.view.affinities.size());
  EXPECT_EQ(out->view.affinities[0].values, in.view.affinities[0].values);
}

TEST(WireCodec, NamesOverTheBoundAreRefusedWhenEncoding) {
  DetectionsEncoder enc;
  CameraDetections in = sample_view();
  in.camera = std::string(64, 'x');
  const Status s = enc.encode(in, body19_topology());
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("63"), std::string::npos);
}

// Encodes a good view, lets `spoil` break the wire sample, and expects decode to refuse it
// naming `what`.
template <typename F>
void expect_refused(F spoil, const std::string& what) {
  DetectionsEncoder enc;
  ASSERT_TRUE(enc.encode(sample_view(), body19_topology()).ok());
  mocap_wire_Detections s = enc.sample();
  std::vector<float> values(9, 0.5f);
  spoil(s, values);
  auto out = decode(s, body19_topology());
  ASSERT_FALSE(out.ok()) << what;
  EXPECT_NE(out.error().message().find("sim3"), std::string::npos) << out.error().message();
  EXPECT_NE(out.error().message().find(what), std::string::npos) << out.error().message();
}

TEST(WireCodec, MalformedSamplesAreRefusedNamingTheField) {
  using S = mocap_wire_Detections;
  using V = std::vector<float>;
  expect_refused([](S& s, V&) { s.topology[0] = 'x'; }, "topology");
  expect_refused([](S& s, V&) { s.frame_rate_hz = std::nan(""); }, "frame rate");
  expect_refused([](S& s, V&) { s.frame_rate_hz = 1e9; }, "frame rate");
  expect_refused([](S& s, V&) { s.capture_time_ns = -5; }, "capture time");
  expect_refused([](S& s, V&) { s.width_px = 0; }, "image size");
  expect_refused([](S& s, V&) { s.joints._length = 3; }, "joints");
  expect_refused([](S& s, V&) { s.limbs._length = 60; }, "limbs");
  expect_refused(
      [](S& s, V& v) {
        s.limbs._buffer[0].rows = 3;  // 3 x 3 = 9 values, but the joints have other counts
        s.limbs._buffer[0].cols = 3;
        s.limbs._buffer[0].values = {9, 9, v.data(), false};
      },
      "limb");
  expect_refused([](S& s, V&) { s.limbs._buffer[1].rows = 60000; }, "values");
  expect_refused([](S& s, V&) { s.joints._buffer[1].candidates._buffer[0].x_px = std::nanf(""); },
                 "");
  expect_refused([](S& s, V&) { s.joints._buffer[1].candidates._buffer[0].score = 7.f; }, "");
  expect_refused([](S& s, V&) { s.joints._buffer[1].candidates._buffer[0].x_px = 1e9f; },
                 "outside the image");
  expect_refused([](S& s, V&) { s.node[0] = '\0'; }, "node name");
  expect_refused([](S& s, V&) { s.joints._buffer[2].candidates._length = 65; }, "");
}

// Found by fuzz_dds_detections: a camera name filling its whole 64-byte array (no NUL within
// the bound of string<63>) was accepted, and could not be encoded again; names that are not
// UTF-8 were accepted and reached the fusion node's status JSON, whose writer throws on them.
TEST(WireCodec, NamesOverTheirBoundOrNotUtf8AreRefused) {
  DetectionsEncoder enc;
  ASSERT_TRUE(enc.encode(sample_view(), body19_topology()).ok());

  mocap_wire_Detections unterminated = enc.sample();
  std::memset(unterminated.camera, 'c', sizeof unterminated.camera);
  auto r = decode(unterminated, body19_topology());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("longer than its bound"), std::string::npos)
      << r.error().message();

  for (const char* name : {"\xff\xfe", "caf\xc3", "\xed\xa0\x80", "\xc0\xaf", "tab\there"}) {
    mocap_wire_Detections s = enc.sample();
    std::memset(s.node, 0, sizeof s.node);
    std::strcpy(s.node, name);
    auto bad = decode(s, body19_topology());
    ASSERT_FALSE(bad.ok()) << name;
    EXPECT_NE(bad.error().message().find("node name"), std::string::npos) << bad.error().message();
  }
  mocap_wire_Detections utf8 = enc.sample();
  std::strcpy(utf8.node, "b\xc3\xbchne-\xe2\x82\xac-\xf0\x9f\x8e\xa5");  // "bühne-€-🎥"
  auto ok = decode(utf8, body19_topology());
  ASSERT_TRUE(ok.ok()) << ok.error().message();
  EXPECT_EQ(ok->node, "b\xc3\xbchne-\xe2\x82\xac-\xf0\x9f\x8e\xa5");
}

}  // namespace
}  // namespace mocap::dds
