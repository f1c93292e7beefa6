// VMC frames (runtime/out/vmc.h) and the sender (runtime/out/vmc_sender.h):
// - a person's frame is split into bundles that each fit one Ethernet frame, with OK, T, Root
//   first and Apply last, every bone once;
// - slots: lowest free slot, kept through gaps, freed after the release time, never shared;
// - targets parse and bad ones are named; an unresolvable host is a problem, not an error;
// - oscdump (liblo, a real OSC parser) receives what the sender sends: types 's'/'f'/'i',
//   one port per person, Apply in every frame.
// - bench: encode + send of 5 people per frame, median printed.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <thread>

#include "runtime/out/vmc.h"
#include "runtime/out/vmc_sender.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/oscdump.h"
#include "tests/support/temp_dir.h"

namespace mocap::out {
namespace {

using Eigen::Vector3d;

// A body19 person standing at x with arms out (a T-pose) and the ears and nose in place.
PersonSkeleton standing(int id, double x) {
  const SkeletonTopology& t = body19_topology();
  PersonSkeleton p;
  p.person_id = id;
  p.joints_m.assign(19, Vector3d::Zero());
  p.confidence.assign(19, 1.f);
  auto set = [&](const char* name, Vector3d v) {
    p.joints_m[t.find_joint(name)] = v + Vector3d(x, 0, 0);
  };
  set("pelvis", {0, 0, 1.0});
  set("neck", {0, 0, 1.5});
  set("nose", {0, -0.1, 1.62});
  set("l_ear", {0.07, 0, 1.65});
  set("r_ear", {-0.07, 0, 1.65});
  for (int s = 0; s < 2; ++s) {
    const double sx = s == 0 ? 1 : -1;
    const std::string side = s == 0 ? "l_" : "r_";
    set((side + "shoulder").c_str(), {sx * 0.18, 0, 1.5});
    set((side + "elbow").c_str(), {sx * 0.47, 0, 1.5});
    set((side + "wrist").c_str(), {sx * 0.73, -0.05, 1.5});
    set((side + "hip").c_str(), {sx * 0.1, 0, 1.0});
    set((side + "knee").c_str(), {sx * 0.1, 0.02, 0.58});
    set((side + "ankle").c_str(), {sx * 0.1, 0, 0.17});
    set((side + "big_toe").c_str(), {sx * 0.1, -0.15, 0.05});
  }
  return p;
}

TEST(VmcFrame, SplitsIntoEthernetSizedBundlesWithApplyLast) {
  VmcPacket packet;
  HumanoidPose pose;
  encode_vmc_frame(make_shape(BodyLengths{}), pose, 1.5f, kEthernetUdpPayloadBytes, packet);
  ASSERT_GE(packet.ends.size(), 2u) << "21 bones do not fit one Ethernet frame";
  std::size_t begin = 0, total = 0;
  for (std::size_t end : packet.ends) {
    EXPECT_LE(end - begin, kEthernetUdpPayloadBytes);
    EXPECT_EQ(std::string(packet.bytes.begin() + static_cast<long>(begin),
                          packet.bytes.begin() + static_cast<long>(begin) + 7),
              "#bundle");
    total += end - begin;
    begin = end;
  }
  std::printf("one person's VMC frame: %zu bytes in %zu datagrams\n", total, packet.ends.size());
  // With a large limit it is one bundle.
  VmcPacket one;
  encode_vmc_frame(make_shape(BodyLengths{}), pose, 1.5f, 65507, one);
  EXPECT_EQ(one.ends.size(), 1u);
}

TEST(VmcSlots, LowestFreeKeptThroughGapsReleasedAfterTimeout) {
  VmcSlots slots(2, 1.0);
  constexpr std::int64_t s = 1'000'000'000;
  EXPECT_EQ(slots.assign(7, 0), 0);
  EXPECT_EQ(slots.assign(3, 0), 1);
  EXPECT_EQ(slots.assign(9, 0), -1);  // full
  EXPECT_TRUE(slots.release_stale(s / 2).empty());
  EXPECT_EQ(slots.assign(3, s), 1);  // person 7 unseen for 0.5 s: keeps slot 0
  const auto freed = slots.release_stale(s + s / 2 + 1);
  ASSERT_EQ(freed.size(), 1u);
  EXPECT_EQ(freed[0], std::make_pair(0, 7));
  EXPECT_EQ(slots.assign(9, 2 * s), 0);  // the new person takes the freed slot
  EXPECT_EQ(slots.assign(3, 2 * s), 1);
  EXPECT_EQ(slots.in_use(), 2);
}

TEST(VmcTargets, ParseAndNameTheBadEntry) {
  auto t = parse_vmc_targets("127.0.0.1:39539, studio-pc:39600,[::1]:40000,host");
  ASSERT_TRUE(t.ok()) << t.error().message();
  ASSERT_EQ(t->size(), 4u);
  EXPECT_EQ((*t)[1].host, "studio-pc");
  EXPECT_EQ((*t)[1].base_port, 39600);
  EXPECT_EQ((*t)[2].host, "::1");
  EXPECT_EQ((*t)[3].base_port, kVmcDefaultPort);
  for (const char* bad : {"host:0", "host:99999", "host:abc", ":39539", "a:1,,b:2", "[::1"}) {
    auto r = parse_vmc_targets(bad);
    EXPECT_FALSE(r.ok()) << bad;
  }
  auto r = parse_vmc_targets("box:70000");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("box:70000"), std::string::npos) << r.error().message();
}

TEST(VmcSender, UnresolvableTargetIsAProblemOthersAreServed) {
  VmcOptions o;
  o.targets = *parse_vmc_targets("no-such-host.invalid:39539,127.0.0.1:39539");
  auto v = VmcSender::create(o);
  ASSERT_TRUE(v.ok()) << v.error().message();
  ASSERT_EQ((*v)->problems().size(), 1u);
  EXPECT_NE((*v)->problems()[0].find("no-such-host.invalid"), std::string::npos);
  EXPECT_EQ((*v)->active_targets(), std::vector<std::string>{"127.0.0.1:39539"});
}

// What oscdump printed for one port, as frames: each from its /VMC/Ext/T to its Apply.
struct ReceivedFrame {
  std::map<std::string, std::vector<float>> bones;  // name -> 7 floats
  bool ok = false, root = false, apply = false;
};
std::vector<ReceivedFrame> frames_of(const std::vector<testing::OscDumpLine>& lines) {
  std::vector<ReceivedFrame> out;
  ReceivedFrame cur;
  for (const testing::OscDumpLine& m : lines) {
    if (m.address == "/VMC/Ext/OK" && m.types == "iiii") cur.ok = true;
    if (m.address == "/VMC/Ext/Root/Pos" && m.types == "sfffffff") cur.root = true;
    if (m.address == "/VMC/Ext/Bone/Pos" && m.types == "sfffffff" && m.args.size() == 8) {
      std::vector<float> f;
      for (std::size_t i = 1; i < 8; ++i) f.push_back(std::stof(m.args[i]));
      cur.bones[m.args[0]] = f;
    }
    if (m.address == "/VMC/Ext/Blend/Apply" && m.types.empty()) {
      cur.apply = true;
      out.push_back(cur);
      cur = ReceivedFrame{};
    }
  }
  return out;
}

TEST(VmcSender, OscdumpReceivesOnePortPerPerson) {
  testing::TestTempDir dir("vmc");
  std::filesystem::create_directories(dir.path() / "a");
  std::filesystem::create_directories(dir.path() / "b");
  testing::OscDump first(dir.path() / "a");
  if (!first.start()) GTEST_SKIP() << first.error();
  testing::OscDump second(dir.path() / "b");
  if (!second.start_on(first.port() + 1)) GTEST_SKIP() << "port+1 busy: " << second.error();
  VmcOptions o;
  o.targets = {VmcTarget{"127.0.0.1", first.port()}};
  o.slots = 2;
  auto v = VmcSender::create(o);
  ASSERT_TRUE(v.ok()) << v.error().message();
  SkeletonSet set;
  set.topology = &body19_topology();
  set.persons = {standing(4, 0.0), standing(9, 2.0)};
  for (int f = 0; f < 5; ++f) {
    set.timestamp_ns = std::int64_t{f} * 33'000'000;
    (*v)->send(set);
    // The send thread takes the newest frame: give it each one (a real source is paced too).
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
  }
  ASSERT_TRUE(first.wait_for_lines(5 * 25)) << first.output();
  ASSERT_TRUE(second.wait_for_lines(5 * 25)) << second.output();
  for (testing::OscDump* d : {&first, &second}) {
    const std::vector<ReceivedFrame> frames = frames_of(d->lines());
    ASSERT_EQ(frames.size(), 5u) << d->output();
    for (const ReceivedFrame& fr : frames) {
      EXPECT_TRUE(fr.ok && fr.root && fr.apply);
      EXPECT_EQ(fr.bones.size(), static_cast<std::size_t>(kHumanBoneCount));
    }
  }
  // Person 4 (slot 0) stands at x = 0, person 9 (slot 1) at x = 2: Unity x = -world x.
  EXPECT_NEAR(frames_of(first.lines())[0].bones["Hips"][0], 0.0f, 1e-4);
  EXPECT_NEAR(frames_of(second.lines())[0].bones["Hips"][0], -2.0f, 1e-4);
  const VmcStats s = (*v)->stats();
  EXPECT_EQ(s.send_errors, 0u);
  EXPECT_EQ(s.frames, 5u);
}

TEST(VmcSender, BenchFivePeoplePerFrame) {
  VmcOptions o;
  o.targets = {VmcTarget{"127.0.0.1", 39539}};  // nobody listens: the kernel drops them
  o.slots = 8;
  auto v = VmcSender::create(o);
  ASSERT_TRUE(v.ok());
  SkeletonSet set;
  set.topology = &body19_topology();
  for (int i = 0; i < 5; ++i) set.persons.push_back(standing(i, i * 1.0));
  std::vector<double> us;
  for (int f = 0; f < 2000; ++f) {
    set.timestamp_ns = std::int64_t{f} * 16'000'000;
    const auto t0 = std::chrono::steady_clock::now();
    (*v)->send(set);
    us.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  std::nth_element(us.begin(), us.begin() + static_cast<long>(us.size() / 2), us.end());
  std::printf(
      "VMC on the pipeline thread, 5 people per frame (humanoid + OSC + hand-off): median "
      "%.1f us; frames the send thread skipped at this (unpaced) rate: %llu of 2000\n",
      us[us.size() / 2], static_cast<unsigned long long>((*v)->stats().frames_replaced));
  EXPECT_EQ((*v)->stats().frames, 2000u);
}

}  // namespace
}  // namespace mocap::out
