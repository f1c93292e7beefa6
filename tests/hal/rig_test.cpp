// ReconnectingCamera, CaptureRig and the trigger master/monitor logic with fakes (no
// hardware; the real drivers are exercised by the HIL test in tests/hil).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "hal/board.h"
#include "hal/capture_rig.h"
#include "hal/gpio/trigger_line.h"
#include "hal/reconnecting_camera.h"

namespace mocap::hal {
namespace {

// A scripted camera: each next() takes the next step. A step is a frame, a timeout or a
// failure (Error, as a backend reports a device that went away).
struct Step {
  enum Kind { kFrame, kTimeout, kFail, kEnd } kind = kFrame;
  std::uint64_t sequence = 0;
  std::int64_t timestamp_ns = 0;
};

class ScriptedCamera final : public CameraSource {
 public:
  ScriptedCamera(std::string id, std::deque<Step> steps) : steps_(std::move(steps)) {
    desc_.id = std::move(id);
    desc_.backend = "fake";
    mode_.width_px = 8;
    mode_.height_px = 8;
    mode_.frame_rate_hz = 30;
  }
  const CameraDescription& description() const override { return desc_; }
  const CameraMode& mode() const override { return mode_; }
  Status start() override {
    started = true;
    return Status::Ok();
  }
  void stop() override { started = false; }
  Result<Capture> next(int /*timeout_ms*/) override {
    if (steps_.empty()) return Capture{CaptureStatus::kEnded, {}};
    const Step s = steps_.front();
    steps_.pop_front();
    if (paced_epoch_ns != 0 && s.kind == Step::kFrame) {
      // Like a live camera: the frame is there at its timestamp (relative to the epoch).
      const std::int64_t due = paced_epoch_ns + s.timestamp_ns;
      while (monotonic_ns() < due) std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    switch (s.kind) {
      case Step::kFrame: {
        Frame f;
        f.sequence = s.sequence;
        f.timestamp_ns = s.timestamp_ns;
        return Capture{CaptureStatus::kFrame, f};
      }
      case Step::kTimeout:
        return Capture{CaptureStatus::kTimeout, {}};
      case Step::kFail:
        return Error(ErrorCode::kDevice, "camera " + desc_.id + ": disconnected (No such device)");
      case Step::kEnd:
        return Capture{CaptureStatus::kEnded, {}};
    }
    return Capture{};
  }
  bool started = false;
  std::int64_t paced_epoch_ns = 0;  // 0: frames come at once

 private:
  CameraDescription desc_;
  CameraMode mode_;
  std::deque<Step> steps_;
};

TEST(ReconnectingCameraTest, ReportsTheLossRetriesAndResumes) {
  int opens = 0;
  bool device_present = true;
  CameraFactory factory = [&]() -> Result<std::unique_ptr<CameraSource>> {
    ++opens;
    if (!device_present) return Error(ErrorCode::kNotFound, "camera /dev/video1: no such device");
    std::deque<Step> steps;
    if (opens == 1) {
      steps = {{Step::kFrame, 1, 100}, {Step::kFail}};
    } else {
      steps = {{Step::kFrame, 1, 900}, {Step::kFrame, 2, 933}};
    }
    return std::unique_ptr<CameraSource>(new ScriptedCamera("/dev/video1", steps));
  };
  ReconnectOptions ro;
  ro.retry_interval_ms = 10;
  auto cam = ReconnectingCamera::open(factory, ro);
  ASSERT_TRUE(cam.ok()) << cam.error().message();
  ASSERT_TRUE((*cam)->start().ok());
  auto c = (*cam)->next(0);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->status, CaptureStatus::kFrame);

  device_present = false;
  c = (*cam)->next(0);  // the device fails: reported as kDisconnected, not an error
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->status, CaptureStatus::kDisconnected);
  EXPECT_FALSE((*cam)->stats().connected);
  EXPECT_EQ((*cam)->stats().disconnects, 1);
  EXPECT_NE((*cam)->stats().last_error.find("/dev/video1"), std::string::npos);

  // While the device is absent, retries fail and next() keeps saying kDisconnected.
  for (int i = 0; i < 3; ++i) {
    c = (*cam)->next(20);
    ASSERT_TRUE(c.ok());
    EXPECT_EQ(c->status, CaptureStatus::kDisconnected);
  }
  EXPECT_GE((*cam)->stats().failed_attempts, 1);

  device_present = true;
  std::optional<Capture> frame;
  for (int i = 0; i < 20 && !frame; ++i) {
    c = (*cam)->next(20);
    ASSERT_TRUE(c.ok());
    if (c->status == CaptureStatus::kFrame) frame = *c;
  }
  ASSERT_TRUE(frame.has_value()) << "frames flow again after the device is back";
  EXPECT_EQ(frame->frame.timestamp_ns, 900);
  EXPECT_TRUE((*cam)->stats().connected);
  EXPECT_EQ((*cam)->stats().reconnects, 1);
}

TEST(ReconnectingCameraTest, FirstOpenFailureIsAnError) {
  auto cam = ReconnectingCamera::open(
      []() -> Result<std::unique_ptr<CameraSource>> {
        return Error(ErrorCode::kNotFound, "camera /dev/video7: no such device");
      },
      ReconnectOptions{});
  ASSERT_FALSE(cam.ok());
  EXPECT_NE(cam.error().message().find("/dev/video7"), std::string::npos);
  ReconnectOptions bad;
  bad.retry_interval_ms = 0;
  EXPECT_FALSE(bad.validate().ok());
}

// Three cameras at 10 Hz (a long period, so a busy test machine cannot make a set miss its
// deadline); camera 2 fails after 3 frames. The rig keeps handing out sets from
// the other two, reports camera 2's error, and ends when every camera ended or failed.
TEST(CaptureRigTest, OneFailingCameraDoesNotStopTheOthers) {
  constexpr std::int64_t kPeriod = 100'000'000;
  std::vector<std::unique_ptr<CameraSource>> cams;
  const std::int64_t epoch = monotonic_ns() + 50'000'000;
  for (int c = 0; c < 3; ++c) {
    std::deque<Step> steps;
    const int frames = c == 2 ? 3 : 10;
    for (int k = 0; k < frames; ++k) {
      steps.push_back({Step::kFrame, static_cast<std::uint64_t>(k), k * kPeriod});
    }
    if (c == 2) steps.push_back({Step::kFail});
    auto cam = std::make_unique<ScriptedCamera>("cam" + std::to_string(c), steps);
    cam->paced_epoch_ns = epoch;
    cams.push_back(std::move(cam));
  }
  CaptureRigOptions o;
  o.sync.cameras = 3;
  o.sync.frame_period_ms = 100;
  o.sync.dead_after_sets = 2;
  o.camera_poll_ms = 5;
  auto rig = CaptureRig::create(std::move(cams), o);
  ASSERT_TRUE(rig.ok()) << rig.error().message();
  ASSERT_TRUE((*rig)->start().ok());
  std::vector<FrameSet> sets;
  for (int i = 0; i < 200 && !(*rig)->all_done(); ++i) {
    if (auto s = (*rig)->next_set(20)) sets.push_back(std::move(*s));
  }
  ASSERT_TRUE((*rig)->all_done());
  ASSERT_EQ(sets.size(), 10u);
  for (std::size_t k = 0; k < sets.size(); ++k) {
    EXPECT_EQ(sets[k].frames.size(), k < 3 ? 3u : 2u) << "set " << k;
  }
  const auto states = (*rig)->camera_states();
  EXPECT_TRUE(states[2].failed);
  EXPECT_NE(states[2].error.find("cam2"), std::string::npos);
  EXPECT_TRUE(states[0].ended);
  EXPECT_EQ(states[0].frames, 10u);
  const SyncStats st = (*rig)->sync_stats();
  EXPECT_EQ(st.complete_sets, 3u);
  EXPECT_EQ(st.partial_sets, 7u);
  EXPECT_EQ(st.cameras[2].missing, 7u);
}

TEST(CaptureRigTest, RejectsAMismatchedCameraCount) {
  std::vector<std::unique_ptr<CameraSource>> cams;
  cams.push_back(std::make_unique<ScriptedCamera>("a", std::deque<Step>{}));
  CaptureRigOptions o;
  o.sync.cameras = 2;
  EXPECT_FALSE(CaptureRig::create(std::move(cams), o).ok());
}

// ---------------------------------------------------------------------------- trigger

class FakeOutput final : public OutputLine {
 public:
  std::string name() const override { return "fake:out"; }
  Status set(bool high) override {
    std::lock_guard lock(mu);
    if (fail_after >= 0 && static_cast<int>(changes.size()) >= fail_after) {
      return Error(ErrorCode::kDevice, "GPIO line fake:out: set failed: No such device");
    }
    changes.push_back({monotonic_ns(), high});
    return Status::Ok();
  }
  std::mutex mu;
  std::vector<LineEdge> changes;
  int fail_after = -1;
};

TEST(TriggerMasterTest, PulsesFollowTheAbsoluteScheduleAndEndLow) {
  auto line = std::make_unique<FakeOutput>();
  FakeOutput* fake = line.get();
  TriggerMasterOptions o;
  o.rate_hz = 200;
  o.pulse_width_us = 500;
  o.max_pulses = 30;
  o.realtime = false;
  auto m = TriggerMaster::create(std::move(line), o);
  ASSERT_TRUE(m.ok()) << m.error().message();
  ASSERT_TRUE((*m)->start().ok());
  ASSERT_TRUE((*m)->wait_done(60'000));
  const TriggerMasterStats s = (*m)->stats();
  EXPECT_EQ(s.pulses, 30u);
  EXPECT_TRUE(s.error.empty());
  // create() drives the line low, then each pulse is high then low: 1 + 2 * 30 changes.
  ASSERT_EQ(fake->changes.size(), 61u);
  EXPECT_FALSE(fake->changes.front().rising);
  EXPECT_FALSE(fake->changes.back().rising);
  const std::vector<std::int64_t> rises = (*m)->rise_times();
  ASSERT_EQ(rises.size(), 30u);
  for (std::size_t k = 0; k < 30; ++k) {
    EXPECT_TRUE(fake->changes[1 + 2 * k].rising);
    // Never early; the k-th rise is scheduled at start + k * period whatever happened before
    // (absolute schedule: lateness does not accumulate into later pulses).
    EXPECT_GE(rises[k], (*m)->scheduled_rise_ns(k));
    EXPECT_EQ((*m)->scheduled_rise_ns(k) - (*m)->scheduled_rise_ns(0),
              static_cast<std::int64_t>(k) * 5'000'000);
    // The fall comes at least a pulse width after the rise.
    EXPECT_GE(fake->changes[2 + 2 * k].timestamp_ns - fake->changes[1 + 2 * k].timestamp_ns,
              500'000);
  }
  EXPECT_GE(s.max_late_ns, s.median_late_ns);
}

TEST(TriggerMasterTest, ALineFailureStopsThePulsesAndIsReported) {
  auto line = std::make_unique<FakeOutput>();
  line->fail_after = 5;  // the initial low + 2 pulses, then the line goes away
  TriggerMasterOptions o;
  o.rate_hz = 500;
  o.pulse_width_us = 100;
  o.realtime = false;
  auto m = TriggerMaster::create(std::move(line), o);
  ASSERT_TRUE(m.ok());
  ASSERT_TRUE((*m)->start().ok());
  ASSERT_TRUE((*m)->wait_done(60'000));
  const TriggerMasterStats s = (*m)->stats();
  EXPECT_EQ(s.pulses, 2u);
  EXPECT_NE(s.error.find("fake:out"), std::string::npos) << s.error;
}

TEST(TriggerMasterTest, OptionsAreValidated) {
  TriggerMasterOptions o;
  o.rate_hz = 30;
  o.pulse_width_us = 20'000;  // more than half of 33.3 ms
  EXPECT_FALSE(o.validate().ok());
  o.pulse_width_us = 1000;
  o.rate_hz = 0;
  EXPECT_FALSE(o.validate().ok());
  GpioLineOptions g;
  EXPECT_FALSE(g.validate().ok());
  EXPECT_FALSE(TriggerMaster::create(nullptr, TriggerMasterOptions{}).ok());
}

class FakeInput final : public InputLine {
 public:
  explicit FakeInput(std::deque<std::int64_t> times) : times_(std::move(times)) {}
  std::string name() const override { return "fake:in"; }
  Result<std::optional<LineEdge>> wait_edge(int /*timeout_ms*/) override {
    if (times_.empty()) return std::optional<LineEdge>();
    LineEdge e{times_.front(), true};
    times_.pop_front();
    return std::optional<LineEdge>(e);
  }

 private:
  std::deque<std::int64_t> times_;
};

TEST(TriggerMonitorTest, MeasuresPeriodJitterAndMissedPulses) {
  // 30 Hz with +-0.1 ms jitter and one missed pulse (a double interval).
  std::deque<std::int64_t> t;
  std::int64_t now = 5'000'000'000;
  for (int k = 0; k < 20; ++k) {
    t.push_back(now + (k % 2 == 0 ? 100'000 : -100'000));
    now += k == 9 ? 2 * 33'333'333 : 33'333'333;
  }
  TriggerMonitor mon(std::make_unique<FakeInput>(t));
  for (int k = 0; k < 20; ++k) {
    auto e = mon.wait(10);
    ASSERT_TRUE(e.ok() && e->has_value());
  }
  auto none = mon.wait(10);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  const TriggerMonitorStats s = mon.stats();
  EXPECT_EQ(s.edges, 20u);
  EXPECT_EQ(s.gaps, 1u);
  EXPECT_NEAR(s.period_median_ns, 33'133'333, 1);  // alternating +-0.1 ms: intervals +-0.2 ms
  EXPECT_NEAR(s.period_jitter_ns, 400'000, 1);
}

// Every board under board/ loads and is consistent: GPIO boards name their chip and line
// and have a pulse width that fits their frame period.
TEST(BoardFilesTest, EveryShippedBoardLoads) {
  int boards = 0;
  bool csi_gpio = false;
  for (const auto& dir : std::filesystem::directory_iterator(MOCAP_SOURCE_DIR "/board")) {
    const auto json = dir.path() / "board.json";
    ASSERT_TRUE(std::filesystem::exists(json)) << dir.path();
    auto b = load_board(json);
    ASSERT_TRUE(b.ok()) << b.error().message();
    EXPECT_EQ(b->name, dir.path().filename().string());
    ++boards;
    if (b->trigger.mode == SyncMode::kGpioMaster) {
      TriggerMasterOptions t;
      t.rate_hz = b->frame_rate_hz;
      t.pulse_width_us = b->trigger.pulse_width_us;
      EXPECT_TRUE(t.validate().ok()) << b->name;
      csi_gpio =
          csi_gpio || (!b->cameras.empty() && b->cameras[0].backend == CameraBackend::kLibcamera);
    }
  }
  EXPECT_GE(boards, 3);
  EXPECT_TRUE(csi_gpio) << "an embedded board with a CSI camera and a GPIO trigger";
}

}  // namespace
// Found by fuzz_board_json: a max_cameras of 1e10 was converted to int (undefined behaviour),
// 2.5 silently became 2. Both are refused with the field and the range.
TEST(BoardFilesTest, MaxCamerasMustBeAnIntegerInRange) {
  for (const char* v : {"1e10", "2.5", "0", "33", "-1", "18446744073709551615", "\"8\""}) {
    const std::string text = std::string(R"({"name": "x", "max_cameras": )") + v + "}";
    auto b = parse_board_json(text, "x/board.json");
    ASSERT_FALSE(b.ok()) << v;
    EXPECT_NE(b.error().message().find("x/board.json"), std::string::npos) << v;
    EXPECT_NE(b.error().message().find("max_cameras must be an integer in [1, 32]"),
              std::string::npos)
        << b.error().message();
  }
  auto ok = parse_board_json(R"({"name": "x", "max_cameras": 32})", "x/board.json");
  ASSERT_TRUE(ok.ok()) << ok.error().message();
  EXPECT_EQ(ok->max_cameras, 32);
}

}  // namespace mocap::hal
