// The OSC 1.0 encoder: byte-exact against packets worked out by hand from the spec (padding at
// string lengths 3, 4 and 5, empty argument lists, nested bundles), then end to end into a
// real receiver, liblo's oscdump (skipped when it is not installed), with a VMC-shaped frame.
#include "runtime/out/osc.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tests/support/oscdump.h"
#include "tests/support/temp_dir.h"

namespace mocap::out {
namespace {

using namespace std::string_view_literals;

// Expected packets, spelled out: raw bytes (NULs included, via ""sv) and big-endian words.
struct Bytes {
  std::vector<std::uint8_t> v;
  Bytes& str(std::string_view s) {
    v.insert(v.end(), s.begin(), s.end());
    return *this;
  }
  Bytes& u32(std::uint32_t x) {
    for (int shift = 24; shift >= 0; shift -= 8) v.push_back(static_cast<std::uint8_t>(x >> shift));
    return *this;
  }
  Bytes& u64(std::uint64_t x) {
    u32(static_cast<std::uint32_t>(x >> 32));
    return u32(static_cast<std::uint32_t>(x));
  }
};

// "2f616263 00000000 ..." (4-byte words), so a mismatch shows where the packets differ.
std::string hex(const std::vector<std::uint8_t>& bytes) {
  std::string s;
  char buf[3];
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    if (i > 0 && i % 4 == 0) s += ' ';
    std::snprintf(buf, sizeof(buf), "%02x", bytes[i]);
    s += buf;
  }
  return s;
}

// ------------------------------------------------------------------------------ messages

TEST(OscMessage, AddressPaddingAtLengths3To5WithNoArguments) {
  std::vector<std::uint8_t> out;
  OscWriter w(out);
  w.message("/ab");    // 3 characters + NUL: exactly 4 bytes
  w.message("/abc");   // 4 + NUL: padded to 8
  w.message("/abcd");  // 5 + NUL: padded to 8
  const Bytes expected = Bytes()
                             .str("/ab\0"sv)
                             .str(",\0\0\0"sv)  // no arguments: "," alone, padded
                             .str("/abc\0\0\0\0"sv)
                             .str(",\0\0\0"sv)
                             .str("/abcd\0\0\0"sv)
                             .str(",\0\0\0"sv);
  EXPECT_EQ(hex(out), hex(expected.v));
  EXPECT_EQ(w.size(), 4u + 4u + 8u + 4u + 8u + 4u);
}

TEST(OscMessage, SpecExampleOneFloat) {
  // OSC 1.0 spec, "Examples": /oscillator/4/frequency ,f 440.0.
  std::vector<std::uint8_t> out;
  OscWriter(out).message("/oscillator/4/frequency", std::array{440.0f});
  const std::vector<std::uint8_t> expected = {0x2f, 0x6f, 0x73, 0x63, 0x69, 0x6c, 0x6c, 0x61,
                                              0x74, 0x6f, 0x72, 0x2f, 0x34, 0x2f, 0x66, 0x72,
                                              0x65, 0x71, 0x75, 0x65, 0x6e, 0x63, 0x79, 0x00,
                                              0x2c, 0x66, 0x00, 0x00, 0x43, 0xdc, 0x00, 0x00};
  EXPECT_EQ(hex(out), hex(expected));
}

TEST(OscMessage, FloatsAreBigEndianIeee754) {
  std::vector<std::uint8_t> out;
  OscWriter(out).message("/f", std::array{1.0f, -2.5f, 0.0f, -0.0f, 0.1f});
  const Bytes expected = Bytes()
                             .str("/f\0\0"sv)
                             .str(",fffff\0\0"sv)  // 6 tag characters + NUL: padded to 8
                             .u32(0x3f800000)
                             .u32(0xc0200000)
                             .u32(0x00000000)
                             .u32(0x80000000)
                             .u32(0x3dcccccd);
  EXPECT_EQ(hex(out), hex(expected.v));
}

TEST(OscMessage, IntsAreBigEndianTwosComplement) {
  std::vector<std::uint8_t> out;
  const std::array<std::int32_t, 4> ints = {1, -1, std::numeric_limits<std::int32_t>::min(),
                                            0x01020304};
  OscWriter(out).message("/VMC/Ext/OK", ints);
  const Bytes expected = Bytes()
                             .str("/VMC/Ext/OK\0"sv)  // 11 + NUL = 12
                             .str(",iiii\0\0\0"sv)
                             .u32(0x00000001)
                             .u32(0xffffffff)
                             .u32(0x80000000)
                             .u32(0x01020304);
  EXPECT_EQ(hex(out), hex(expected.v));
}

TEST(OscMessage, StringArgumentPaddingAtLengths0And3To5) {
  std::vector<std::uint8_t> out;
  OscWriter w(out);
  const std::array<float, 1> one = {1.0f};
  w.message("/s", "", one);
  w.message("/s", "abc", one);
  w.message("/s", "root", one);
  w.message("/s", "Hips1", one);
  Bytes expected;
  for (std::string_view s : {"\0\0\0\0"sv, "abc\0"sv, "root\0\0\0\0"sv, "Hips1\0\0\0"sv}) {
    expected.str("/s\0\0"sv).str(",sf\0"sv).str(s).u32(0x3f800000);
  }
  EXPECT_EQ(hex(out), hex(expected.v));
}

TEST(OscMessage, VmcBoneTypeTagsPadTo12Bytes) {
  std::vector<std::uint8_t> out;
  const std::array<float, 7> pose = {1, 2, 3, 0, 0, 0, 1};  // position (m) + quaternion
  OscWriter(out).message("/VMC/Ext/Bone/Pos", "Hips", pose);
  Bytes expected;
  expected.str("/VMC/Ext/Bone/Pos\0\0\0"sv).str(",sfffffff\0\0\0"sv).str("Hips\0\0\0\0"sv);
  for (std::uint32_t bits : {0x3f800000u, 0x40000000u, 0x40400000u, 0u, 0u, 0u, 0x3f800000u}) {
    expected.u32(bits);
  }
  EXPECT_EQ(hex(out), hex(expected.v));
  EXPECT_EQ(out.size(), osc_message_size("/VMC/Ext/Bone/Pos", "Hips", 7));
}

// ------------------------------------------------------------------------------- bundles

TEST(OscBundle, EmptyBundleIsHeaderOnly) {
  std::vector<std::uint8_t> out;
  OscWriter w(out);
  w.begin_bundle();
  w.end_bundle();
  EXPECT_EQ(hex(out), hex(Bytes().str("#bundle\0"sv).u64(1).v));
  EXPECT_EQ(w.open_bundles(), 0);
}

TEST(OscBundle, MessagesGetSizePrefixes) {
  std::vector<std::uint8_t> out;
  OscWriter w(out);
  w.begin_bundle(0x0123456789abcdefULL);
  w.message("/VMC/Ext/Blend/Apply");
  w.message("/VMC/Ext/T", std::array{0.5f});
  w.end_bundle();
  const Bytes expected = Bytes()
                             .str("#bundle\0"sv)
                             .u64(0x0123456789abcdefULL)
                             .u32(28)  // 20 characters + NUL -> 24, then ","
                             .str("/VMC/Ext/Blend/Apply\0\0\0\0"sv)
                             .str(",\0\0\0"sv)
                             .u32(20)
                             .str("/VMC/Ext/T\0\0"sv)
                             .str(",f\0\0"sv)
                             .u32(0x3f000000);
  EXPECT_EQ(hex(out), hex(expected.v));
}

TEST(OscBundle, NestedBundleSizeIsPatched) {
  std::vector<std::uint8_t> out;
  OscWriter w(out);
  w.begin_bundle();
  w.message("/a");
  w.begin_bundle(2);
  w.message("/b", std::array<std::int32_t, 1>{7});
  w.begin_bundle(3);  // an empty bundle, nested two deep
  w.end_bundle();
  w.end_bundle();
  w.message("/c");
  w.end_bundle();
  const Bytes expected = Bytes()
                             .str("#bundle\0"sv)
                             .u64(1)
                             .u32(8)
                             .str("/a\0\0,\0\0\0"sv)
                             .u32(16 + 4 + 12 + 4 + 16)  // the inner bundle: header, /b, empty
                             .str("#bundle\0"sv)
                             .u64(2)
                             .u32(12)
                             .str("/b\0\0,i\0\0"sv)
                             .u32(7)
                             .u32(16)
                             .str("#bundle\0"sv)
                             .u64(3)
                             .u32(8)
                             .str("/c\0\0,\0\0\0"sv);
  EXPECT_EQ(hex(out), hex(expected.v));
  EXPECT_EQ(w.open_bundles(), 0);
}

// -------------------------------------------------------------------------- writer, sizes

TEST(OscWriter, AppendsToTheBufferAndCountsItsOwnBytes) {
  std::vector<std::uint8_t> out = {0xaa, 0xbb, 0xcc};
  OscWriter w(out);
  EXPECT_EQ(w.size(), 0u);
  w.begin_bundle();
  w.message("/x");
  EXPECT_EQ(w.open_bundles(), 1);
  w.end_bundle();
  EXPECT_EQ(w.size(), 16u + 4u + 8u);
  ASSERT_EQ(out.size(), 3u + w.size());
  EXPECT_EQ(out[0], 0xaa);
  EXPECT_EQ(out[3], '#');  // a top-level bundle has no size prefix
}

TEST(OscWriter, MessageSizeMatchesWhatIsWritten) {
  const std::array<float, 7> f7{};
  const std::array<std::int32_t, 2> i2{};
  for (std::string_view address : {"/a"sv, "/ab"sv, "/abc"sv, "/abcd"sv, "/VMC/Ext/Root/Pos"sv}) {
    std::vector<std::uint8_t> out;
    OscWriter w(out);
    w.message(address);
    EXPECT_EQ(w.size(), osc_message_size(address, std::nullopt, 0)) << address;
    const std::size_t before = w.size();
    const std::size_t floats = std::min<std::size_t>(address.size(), f7.size());  // 2..7
    w.message(address, std::span<const float>(f7).first(floats));
    EXPECT_EQ(w.size() - before, osc_message_size(address, std::nullopt, floats));
    const std::size_t before_s = w.size();
    w.message(address, address.substr(1), f7);
    EXPECT_EQ(w.size() - before_s, osc_message_size(address, address.substr(1), 7));
    const std::size_t before_i = w.size();
    w.message(address, i2);
    EXPECT_EQ(w.size() - before_i, osc_message_size(address, std::nullopt, 0, 2));
    EXPECT_EQ(w.size() % 4, 0u);
  }
}

// A VMC frame's worth of messages (55 bones + blend shapes + root/time/ok) into a reserved
// buffer: no reallocation, and the size the sender would compute ahead.
TEST(OscWriter, FrameDoesNotReallocateOnceReserved) {
  const std::array<float, 7> pose = {0.1f, 0.9f, -0.2f, 0.0f, 0.0f, 0.0f, 1.0f};
  std::size_t predicted = kOscBundleHeaderBytes;
  std::vector<std::uint8_t> out;
  out.reserve(8192);
  const std::uint8_t* data = out.data();
  OscWriter w(out);
  w.begin_bundle();
  for (int b = 0; b < 100; ++b) {
    w.message("/VMC/Ext/Bone/Pos", "LeftUpperArm", pose);
    predicted += kOscElementPrefixBytes + osc_message_size("/VMC/Ext/Bone/Pos", "LeftUpperArm", 7);
  }
  w.end_bundle();
  EXPECT_EQ(out.data(), data);
  EXPECT_EQ(w.size(), predicted);
}

// ------------------------------------------------------------------- oscdump output parser

TEST(OscDumpParse, ObservedLinesOfLiblo031) {
  const std::string text =
      "eeba8739.70343b70 /VMC/Ext/OK i 1\n"
      "eeba8739.ca71476a /x sfff \"a b\" 1.500000 -2.250000 0.123457\n"
      "eeba8739.ca71476a /VMC/Ext/Blend/Apply \n"
      "eeba8739.ca770bcf /VMC/Ext/OK i 1\n"
      "not a message line\n";
  const std::vector<testing::OscDumpLine> lines = testing::parse_oscdump_output(text);
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0].address, "/VMC/Ext/OK");
  EXPECT_EQ(lines[0].types, "i");
  EXPECT_EQ(lines[0].args, std::vector<std::string>{"1"});
  EXPECT_EQ(lines[1].types, "sfff");
  EXPECT_EQ(lines[1].args, (std::vector<std::string>{"a b", "1.500000", "-2.250000", "0.123457"}));
  EXPECT_EQ(lines[2].address, "/VMC/Ext/Blend/Apply");
  EXPECT_EQ(lines[2].types, "");
  EXPECT_TRUE(lines[2].args.empty());
  EXPECT_EQ(lines[0].bundle_index, 0);
  EXPECT_EQ(lines[1].bundle_index, 1);
  EXPECT_EQ(lines[2].bundle_index, 1);
  EXPECT_EQ(lines[3].bundle_index, 2);
  EXPECT_EQ(testing::parse_oscdump_line("/a f 1.000000")->bundle_index, -1);  // no timetag
}

// ----------------------------------------------------------------------- real receiver

struct SentMessage {
  std::string address;
  std::string types;
  std::optional<std::string> s;
  std::vector<float> f;
  std::vector<std::int32_t> i;
};

// A VMC-shaped frame: root, a few bones, time, blend apply, OK.
std::vector<SentMessage> vmc_frame() {
  std::vector<SentMessage> m;
  m.push_back({"/VMC/Ext/Root/Pos", "sfffffff", "root", {0.25f, -1.5f, 0.875f, 0, 0, 0, 1}, {}});
  m.push_back({"/VMC/Ext/Bone/Pos",
               "sfffffff",
               "Hips",
               {0.1f, 0.95f, -0.2f, 0.0f, 0.7071068f, 0.0f, 0.7071068f},
               {}});
  m.push_back({"/VMC/Ext/Bone/Pos", "sfffffff", "Spine", {0, 0.1f, 0.01f, 0.1f, 0, 0, 0.995f}, {}});
  m.push_back(
      {"/VMC/Ext/Bone/Pos", "sfffffff", "LeftHand", {0.03f, 0, 0, -0.5f, 0.5f, -0.5f, 0.5f}, {}});
  m.push_back({"/VMC/Ext/T", "f", std::nullopt, {12.345678f}, {}});
  m.push_back({"/VMC/Ext/Blend/Apply", "", std::nullopt, {}, {}});
  m.push_back({"/VMC/Ext/OK", "i", std::nullopt, {}, {1}});
  return m;
}

void write(OscWriter& w, const SentMessage& m) {
  if (m.s) {
    w.message(m.address, *m.s, m.f);
  } else if (!m.i.empty()) {
    w.message(m.address, m.i);
  } else if (!m.f.empty()) {
    w.message(m.address, m.f);
  } else {
    w.message(m.address);
  }
}

// The printed arguments against the sent ones: floats print as %f, so within 0.5e-6.
void expect_args(const testing::OscDumpLine& got, const SentMessage& sent) {
  std::size_t k = 0;
  if (sent.s) {
    ASSERT_GE(got.args.size(), 1u);
    EXPECT_EQ(got.args[k++], *sent.s);
  }
  ASSERT_EQ(got.args.size(), k + sent.f.size() + sent.i.size()) << sent.address;
  for (const float v : sent.f) {
    EXPECT_NEAR(std::strtod(got.args[k++].c_str(), nullptr), static_cast<double>(v), 0.51e-6)
        << sent.address;
  }
  for (const std::int32_t v : sent.i) EXPECT_EQ(got.args[k++], std::to_string(v));
}

TEST(OscReceiver, OscdumpReadsAVmcBundle) {
  if (testing::oscdump_path().empty()) GTEST_SKIP() << testing::kNoOscDump;
  const testing::TestTempDir dir("osc");
  testing::OscDump dump(dir.path());
  ASSERT_TRUE(dump.start()) << dump.error();

  const std::vector<SentMessage> frame = vmc_frame();
  std::vector<std::uint8_t> packet;
  OscWriter w(packet);
  w.begin_bundle(kOscImmediately);
  for (const SentMessage& m : frame) write(w, m);
  w.end_bundle();
  ASSERT_TRUE(testing::send_udp(dump.port(), packet));
  // Then a lone message: it must land in another packet/bundle index than the frame.
  std::vector<std::uint8_t> lone;
  OscWriter(lone).message("/VMC/Ext/OK", std::array<std::int32_t, 1>{0});
  ASSERT_TRUE(testing::send_udp(dump.port(), lone));

  ASSERT_TRUE(dump.wait_for_lines(frame.size() + 1)) << dump.output();
  dump.stop();
  const std::vector<testing::OscDumpLine> got = dump.lines();
  ASSERT_EQ(got.size(), frame.size() + 1) << dump.output();
  for (std::size_t k = 0; k < frame.size(); ++k) {
    SCOPED_TRACE(frame[k].address);
    EXPECT_EQ(got[k].address, frame[k].address);
    EXPECT_EQ(got[k].types, frame[k].types);
    expect_args(got[k], frame[k]);
    EXPECT_GE(got[k].bundle_index, 0) << "oscdump printed no timetag";
    EXPECT_EQ(got[k].bundle_index, got[0].bundle_index) << "not one bundle";
  }
  EXPECT_EQ(got.back().address, "/VMC/Ext/OK");
  EXPECT_EQ(got.back().args, std::vector<std::string>{"0"});
  EXPECT_NE(got.back().bundle_index, got[0].bundle_index);
}

}  // namespace
}  // namespace mocap::out
