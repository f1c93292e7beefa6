// The pipeline with fake plug-ins (tests/pipeline/fakes.h), no hardware: ordering under both
// drop policies, drops counted per queue, backpressure bounding what is in flight, the CNN
// stage (detector errors skip a frame, images without a detector stop it, camera buffers are
// let go, also while the sink stalls), the engine stage (a real engine on the simulator; its errors
// skip a frame), sinks (called in order; a failing one stops the pipeline with its name), stop()
// and bad options.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/core/clock.h"
#include "runtime/pipeline/pipeline.h"
#include "runtime/pipeline/recovering_detector.h"
#include "runtime/pipeline/sinks.h"
#include "runtime/sim/simulator_source.h"
#include "runtime/skeleton/topology.h"
#include "tests/pipeline/fakes.h"
#include "tests/support/cameras.h"

namespace mocap::pipeline {
namespace {

using testing::FakeDetector;
using testing::FakeSource;

// A sink that records frame ids (and sleeps `delay_ms` every `every`-th frame).
struct Recorder {
  std::mutex mu;
  std::vector<std::uint64_t> ids;
  CallbackSink sink(int delay_ms = 0, int every = 1) {
    return CallbackSink("recorder", [this, delay_ms, every](const PipelineFrame& f) {
      std::size_t n = 0;
      {
        std::lock_guard<std::mutex> lock(mu);
        ids.push_back(f.detections.frame_id);
        n = ids.size();
      }
      if (delay_ms > 0 && n % static_cast<std::size_t>(every) == 0) {
        std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
      }
      return Status{};
    });
  }
};

std::unique_ptr<Pipeline> make(std::unique_ptr<FrameSource> source, Detector* detector,
                               std::vector<Sink*> sinks, PipelineOptions o,
                               assoc::Engine* engine = nullptr) {
  auto p =
      Pipeline::create(PipelineParts{std::move(source), detector, engine, std::move(sinks), {}}, o);
  EXPECT_TRUE(p.ok()) << p.error().message();
  return p.ok() ? std::move(*p) : nullptr;
}

PipelineOptions blocking(int depth = 2) {
  PipelineOptions o;
  o.drop_policy = DropPolicy::kBlock;
  o.queue_depth = depth;
  return o;
}

bool in_order(const std::vector<std::uint64_t>& ids) {
  return std::is_sorted(ids.begin(), ids.end()) &&
         std::adjacent_find(ids.begin(), ids.end()) == ids.end();
}

TEST(Pipeline, BlockPolicyProcessesEveryFrameInOrder) {
  Recorder rec;
  CallbackSink sink = rec.sink(5, 50);
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 200}), nullptr, {&sink},
                blocking(1));
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(30000));
  const PipelineMetrics m = p->metrics();
  EXPECT_TRUE(m.ended);
  EXPECT_TRUE(m.error.empty());
  EXPECT_EQ(m.frames_in, 200u);
  EXPECT_EQ(m.frames_out, 200u);
  EXPECT_EQ(m.dropped_assoc_queue + m.dropped_cnn_queue, 0u);
  ASSERT_EQ(rec.ids.size(), 200u);
  for (std::size_t i = 0; i < rec.ids.size(); ++i) EXPECT_EQ(rec.ids[i], i);
  EXPECT_EQ(m.end_to_end.count, 200u);
  EXPECT_LE(m.end_to_end.median_ms, m.end_to_end.p99_ms);
}

TEST(Pipeline, DropOldestCountsDropsUnderASlowSink) {
  Recorder rec;
  CallbackSink sink = rec.sink(2, 1);
  PipelineOptions o;
  o.drop_policy = DropPolicy::kDropOldest;
  auto p =
      make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 300}), nullptr, {&sink}, o);
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(60000));
  const PipelineMetrics m = p->metrics();
  EXPECT_EQ(m.frames_in, 300u);
  // The source never waits: what the sink could not take was dropped, and counted.
  EXPECT_GT(m.dropped_assoc_queue, 0u);
  EXPECT_EQ(m.frames_out + m.dropped_assoc_queue, 300u);
  EXPECT_EQ(rec.ids.size(), m.frames_out);
  EXPECT_TRUE(in_order(rec.ids));
  EXPECT_EQ(rec.ids.back(), 299u);  // the newest frame always gets through
}

TEST(Pipeline, ImagesGoThroughTheDetectorInOrderAndTheirBuffersAreLetGo) {
  Recorder rec;
  CallbackSink sink = rec.sink(1, 1);
  FakeDetector det({}, 2);
  auto src = std::make_unique<FakeSource>(FakeSource::Options{.frames = 60, .images = true});
  FakeSource* s = src.get();
  std::atomic<int> most_alive{0};
  CallbackSink watch("watch", [&](const PipelineFrame&) {
    most_alive = std::max(most_alive.load(), s->alive_buffers.load());
    return Status{};
  });
  auto p = make(std::move(src), &det, {&sink, &watch}, blocking(2));
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(60000));
  const PipelineMetrics m = p->metrics();
  EXPECT_TRUE(m.ended) << m.error;
  EXPECT_EQ(det.calls.load(), 60);
  ASSERT_EQ(rec.ids.size(), 60u);
  for (std::size_t i = 0; i < rec.ids.size(); ++i) EXPECT_EQ(rec.ids[i], i);
  EXPECT_EQ(m.cnn.count, 60u);
  EXPECT_GE(m.cnn.median_ms, 1.0);  // the detector's 2 ms are measured as the CNN stage
  // Buffers: every one released at the end; while running, at most the sets in the CNN queue,
  // the one being detected and the one the source holds (2 views each).
  EXPECT_EQ(s->alive_buffers.load(), 0);
  EXPECT_LE(most_alive.load(), 2 * (2 + 1 + 1));
}

TEST(Pipeline, AStalledSinkHoldsNoCameraBufferPastTheCnnQueue) {
  // The sink stalls: the engine queue fills, the CNN stage waits to hand its detections over and
  // the source waits on a full CNN queue. The camera buffers held are then the CNN queue's and
  // the source's own set only: the CNN stage let go of its images once they were detected.
  constexpr int kDepth = 2;
  std::atomic<bool> open{false};
  CallbackSink gate("gate", [&](const PipelineFrame&) {
    while (!open) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return Status{};
  });
  FakeDetector det;
  auto src = std::make_unique<FakeSource>(FakeSource::Options{.frames = 20, .images = true});
  FakeSource* s = src.get();
  auto p = make(std::move(src), &det, {&gate}, blocking(kDepth));
  ASSERT_TRUE(p->start().ok());
  // Stalled: one set in the sink, kDepth in the engine queue, one at the CNN stage, kDepth in
  // the CNN queue and one at the source.
  constexpr int kStalled = 1 + kDepth + 1 + kDepth + 1;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (s->handed_out.load() < kStalled && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(s->handed_out.load(), kStalled);
  EXPECT_EQ(s->alive_buffers.load(), 2 * (kDepth + 1));  // 2 views per set
  open = true;
  ASSERT_TRUE(p->wait(60000));
  EXPECT_EQ(p->metrics().frames_out, 20u);
  EXPECT_EQ(s->alive_buffers.load(), 0);
}

TEST(Pipeline, DetectorErrorsSkipTheFrameAndAreCounted) {
  Recorder rec;
  CallbackSink sink = rec.sink();
  FakeDetector det({3, 7});
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 10, .images = true}),
                &det, {&sink}, blocking());
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(30000));
  const PipelineMetrics m = p->metrics();
  EXPECT_TRUE(m.ended);
  EXPECT_EQ(m.errors, 2u);
  EXPECT_EQ(rec.ids, (std::vector<std::uint64_t>{0, 1, 2, 4, 5, 6, 8, 9}));
}

// A detector whose device is lost at frame `lost_at`: that call and every later one fail with
// kDeviceLost, as a lost GPU does.
class LosingDetector final : public Detector {
 public:
  explicit LosingDetector(std::uint64_t lost_at) : lost_at_(lost_at) {}
  Result<DetectionSet> detect(const FrameSet& frames) override {
    if (frames.frame_id >= lost_at_) {
      return Error(ErrorCode::kDeviceLost, "Vulkan: waiting for the GPU failed (fake lost device)");
    }
    return ok_.detect(frames);
  }
  std::string description() const override { return "losing detector"; }

 private:
  std::uint64_t lost_at_;
  FakeDetector ok_;
};

// Opens the scripted detectors in turn (a null entry: that open fails); records cpu_only.
struct ScriptedOpener {
  std::vector<std::unique_ptr<Detector>> script;
  std::vector<bool> cpu_only;
  RecoveringDetector::Opener opener() {
    return [this](bool cpu) -> Result<std::unique_ptr<Detector>> {
      cpu_only.push_back(cpu);
      const std::size_t i = cpu_only.size() - 1;
      if (i >= script.size() || script[i] == nullptr) {
        return Error(ErrorCode::kDevice, "no Vulkan device (scripted)");
      }
      return std::move(script[i]);
    };
  }
};

std::vector<std::uint64_t> run_ten_frames(Detector& det, PipelineMetrics* m = nullptr) {
  Recorder rec;
  CallbackSink sink = rec.sink();
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 10, .images = true}),
                &det, {&sink}, blocking());
  EXPECT_TRUE(p->start().ok());
  EXPECT_TRUE(p->wait(30000));
  if (m != nullptr) *m = p->metrics();
  return rec.ids;
}

TEST(RecoveringDetector, ALostDeviceIsOpenedAgainAndNoFrameIsLost) {
  ScriptedOpener o;
  o.script.push_back(std::make_unique<LosingDetector>(4));
  o.script.push_back(std::make_unique<FakeDetector>());
  auto det = RecoveringDetector::open(o.opener());
  ASSERT_TRUE(det.ok()) << det.error().message();
  EXPECT_EQ((*det)->description(), "losing detector");
  PipelineMetrics m;
  EXPECT_EQ(run_ten_frames(**det, &m), (std::vector<std::uint64_t>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));
  EXPECT_EQ(m.errors, 0u);
  const DetectorRecoveryStats s = (*det)->stats();
  EXPECT_EQ(s.devices_lost, 1u);
  EXPECT_EQ(s.reopened, 1u);
  EXPECT_FALSE(s.on_cpu);
  EXPECT_EQ(s.active, "fake detector");
  EXPECT_NE(s.last_error.find("lost device"), std::string::npos) << s.last_error;
  EXPECT_EQ(o.cpu_only, (std::vector<bool>{false, false}));
}

TEST(RecoveringDetector, WhenTheGpuCannotBeOpenedAgainTheCpuTakesOver) {
  ScriptedOpener o;
  o.script.push_back(std::make_unique<LosingDetector>(2));
  o.script.push_back(nullptr);  // the GPU does not come back
  o.script.push_back(std::make_unique<FakeDetector>());
  auto det = RecoveringDetector::open(o.opener());
  ASSERT_TRUE(det.ok());
  PipelineMetrics m;
  EXPECT_EQ(run_ten_frames(**det, &m).size(), 10u);
  EXPECT_EQ(m.errors, 0u);
  EXPECT_TRUE((*det)->stats().on_cpu);
  EXPECT_EQ(o.cpu_only, (std::vector<bool>{false, false, true}));
}

TEST(RecoveringDetector, NothingOpensThatFrameIsAnErrorAndTheNextTriesAgain) {
  ScriptedOpener o;
  o.script.push_back(std::make_unique<LosingDetector>(4));
  o.script.push_back(nullptr);  // neither the GPU
  o.script.push_back(nullptr);  // nor the CPU, this time
  o.script.push_back(std::make_unique<FakeDetector>());
  auto det = RecoveringDetector::open(o.opener());
  ASSERT_TRUE(det.ok());
  PipelineMetrics m;
  EXPECT_EQ(run_ten_frames(**det, &m), (std::vector<std::uint64_t>{0, 1, 2, 3, 5, 6, 7, 8, 9}));
  EXPECT_EQ(m.errors, 1u);
  const DetectorRecoveryStats s = (*det)->stats();
  EXPECT_EQ(s.failed_reopens, 1u);
  EXPECT_EQ(s.reopened, 1u);
  EXPECT_EQ(s.devices_lost, 2u);
}

TEST(RecoveringDetector, OtherErrorsPassThroughAndABadOpenerIsRefused) {
  ScriptedOpener o;
  o.script.push_back(std::make_unique<FakeDetector>(std::set<std::uint64_t>{3}));
  auto det = RecoveringDetector::open(o.opener());
  ASSERT_TRUE(det.ok());
  PipelineMetrics m;
  EXPECT_EQ(run_ten_frames(**det, &m).size(), 9u);
  EXPECT_EQ(m.errors, 1u);
  EXPECT_EQ((*det)->stats().devices_lost, 0u);
  EXPECT_EQ(o.cpu_only.size(), 1u);
  EXPECT_FALSE(RecoveringDetector::open(nullptr).ok());
  ScriptedOpener none;
  EXPECT_FALSE(RecoveringDetector::open(none.opener()).ok());
}

TEST(Pipeline, ImagesWithoutADetectorStopWithTheReason) {
  Recorder rec;
  CallbackSink sink = rec.sink();
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 10, .images = true}),
                nullptr, {&sink}, blocking());
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(30000));
  const PipelineMetrics m = p->metrics();
  EXPECT_FALSE(m.ended);
  EXPECT_NE(m.error.find("no detector"), std::string::npos) << m.error;
  EXPECT_TRUE(rec.ids.empty());
}

TEST(Pipeline, BackpressureBoundsWhatIsInFlight) {
  // A slow detector and a blocking policy: the source is held back, never more than the two
  // queues, the detector and the source's own item ahead of the sinks.
  constexpr int kDepth = 2;
  FakeDetector det({}, 3);
  auto src = std::make_unique<FakeSource>(FakeSource::Options{.frames = 40, .images = true});
  FakeSource* s = src.get();
  std::atomic<int> most_ahead{0};
  std::atomic<int> out{0};
  CallbackSink sink("ahead", [&](const PipelineFrame&) {
    ++out;
    most_ahead = std::max(most_ahead.load(), s->handed_out.load() - out.load());
    return Status{};
  });
  auto p = make(std::move(src), &det, {&sink}, blocking(kDepth));
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(60000));
  EXPECT_EQ(out.load(), 40);
  EXPECT_LE(most_ahead.load(), 2 * kDepth + 2);
  EXPECT_GT(most_ahead.load(), 0);
}

TEST(Pipeline, DropOldestInTheCnnQueueUnderASlowDetector) {
  FakeDetector det({}, 5);
  std::vector<std::uint64_t> ids;
  CallbackSink sink("ids", [&](const PipelineFrame& f) {
    ids.push_back(f.detections.frame_id);
    return Status{};
  });
  PipelineOptions o;
  o.drop_policy = DropPolicy::kDropOldest;
  o.queue_depth = 1;
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 100, .images = true}),
                &det, {&sink}, o);
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(60000));
  const PipelineMetrics m = p->metrics();
  EXPECT_GT(m.dropped_cnn_queue, 0u);
  EXPECT_EQ(m.frames_out + m.dropped_cnn_queue + m.dropped_assoc_queue, 100u);
  EXPECT_TRUE(in_order(ids));
  EXPECT_EQ(ids.back(), 99u);
}

TEST(Pipeline, SinksRunInOrderAndAFailingSinkStopsThePipeline) {
  std::vector<std::string> calls;
  CallbackSink first("first", [&](const PipelineFrame& f) {
    calls.push_back("first " + std::to_string(f.detections.frame_id));
    return Status{};
  });
  CallbackSink second("second", [&](const PipelineFrame& f) -> Status {
    calls.push_back("second " + std::to_string(f.detections.frame_id));
    if (f.detections.frame_id == 2) return Error(ErrorCode::kIo, "disk full");
    return {};
  });
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 10}), nullptr,
                {&first, &second}, blocking());
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(30000));
  const PipelineMetrics m = p->metrics();
  EXPECT_FALSE(m.ended);
  EXPECT_NE(m.error.find("second sink, frame 2: disk full"), std::string::npos) << m.error;
  EXPECT_EQ(m.frames_out, 2u);
  EXPECT_EQ(calls, (std::vector<std::string>{"first 0", "second 0", "first 1", "second 1",
                                             "first 2", "second 2"}));
}

TEST(Pipeline, AFileSinkOnAFullDiskStopsThePipelineNamingTheFile) {
  auto file = MessageFileSink::open("/dev/full", 0);
  ASSERT_TRUE(file.ok()) << file.error().message();
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 10}), nullptr,
                {file->get()}, blocking());
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(30000));
  const PipelineMetrics m = p->metrics();
  EXPECT_FALSE(m.ended);
  EXPECT_NE(m.error.find("/dev/full: write failed"), std::string::npos) << m.error;
  EXPECT_EQ(m.frames_out, 0u);
}

TEST(Pipeline, SourceErrorStopsWithTheReason) {
  CallbackSink sink("none", [](const PipelineFrame&) { return Status{}; });
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = -1, .error_at = 10}),
                nullptr, {&sink}, PipelineOptions{});
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(30000));
  const PipelineMetrics m = p->metrics();
  EXPECT_FALSE(m.ended);
  EXPECT_NE(m.error.find("fake source: fake device unplugged"), std::string::npos) << m.error;
  EXPECT_EQ(m.frames_in, 10u);
}

TEST(Pipeline, StopReturnsWhileTheSinkIsSlowAndTheSourceEndless) {
  auto src = std::make_unique<FakeSource>(FakeSource::Options{.frames = -1});
  FakeSource* s = src.get();
  CallbackSink slow("slow", [](const PipelineFrame&) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    return Status{};
  });
  auto p = make(std::move(src), nullptr, {&slow}, blocking());
  ASSERT_TRUE(p->start().ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  p->stop();
  EXPECT_TRUE(s->stopped);
  EXPECT_TRUE(p->finished());
  EXPECT_FALSE(p->metrics().running);
  EXPECT_FALSE(p->metrics().ended);
}

TEST(Pipeline, MaxFramesAndBadParts) {
  PipelineOptions o = blocking();
  o.max_frames = 7;
  int n = 0;
  CallbackSink count("count", [&](const PipelineFrame&) {
    ++n;
    return Status{};
  });
  auto p =
      make(std::make_unique<FakeSource>(FakeSource::Options{.frames = -1}), nullptr, {&count}, o);
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(30000));
  EXPECT_EQ(n, 7);
  EXPECT_TRUE(p->metrics().ended);

  auto fake = [] { return std::make_unique<FakeSource>(FakeSource::Options{}); };
  PipelineOptions bad;
  bad.queue_depth = 0;
  auto q = Pipeline::create(PipelineParts{fake(), nullptr, nullptr, {&count}, {}}, bad);
  ASSERT_FALSE(q.ok());
  EXPECT_NE(q.error().message().find("queue_depth"), std::string::npos);
  auto no_sink =
      Pipeline::create(PipelineParts{fake(), nullptr, nullptr, {}, {}}, PipelineOptions{});
  ASSERT_FALSE(no_sink.ok());
  EXPECT_NE(no_sink.error().message().find("no sink"), std::string::npos);
  auto null_sink =
      Pipeline::create(PipelineParts{fake(), nullptr, nullptr, {nullptr}, {}}, PipelineOptions{});
  EXPECT_FALSE(null_sink.ok());
  auto no_source =
      Pipeline::create(PipelineParts{nullptr, nullptr, nullptr, {&count}, {}}, PipelineOptions{});
  EXPECT_FALSE(no_source.ok());
}

// The engine stage with a real engine: the simulator's detections, unpaced, every frame
// associated and fitted; then detections the engine refuses (another topology) are counted
// and skipped while the pipeline goes on.
TEST(Pipeline, TheEngineAssociatesTheSimulatorAndItsErrorsSkipAFrame) {
  sim::SimulatorSourceOptions so;
  so.people = 2;
  so.views = 4;
  so.paced = false;
  so.frames = 60;
  auto src = sim::SimulatorSource::open(so);
  ASSERT_TRUE(src.ok()) << src.error().message();
  auto engine = assoc::Engine::create((*src)->topology(), (*src)->calibration().cameras,
                                      assoc::AssociationOptions{});
  ASSERT_TRUE(engine.ok()) << engine.error().message();
  std::vector<int> persons;
  CallbackSink sink("persons", [&](const PipelineFrame& f) {
    EXPECT_TRUE(f.result.has_value());
    persons.push_back(f.result ? static_cast<int>(f.result->skeletons.persons.size()) : -1);
    return Status{};
  });
  auto p = make(std::move(*src), nullptr, {&sink}, blocking(), engine->get());
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(60000));
  PipelineMetrics m = p->metrics();
  EXPECT_TRUE(m.ended) << m.error;
  ASSERT_EQ(persons.size(), 60u);
  EXPECT_GE(std::count(persons.begin() + 20, persons.end(), 2), 38);
  EXPECT_EQ(m.assoc.count, 60u);

  // Detections without a topology: the engine refuses each, the pipeline skips them.
  persons.clear();
  auto q = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 5}), nullptr, {&sink},
                blocking(), engine->get());
  ASSERT_TRUE(q->start().ok());
  ASSERT_TRUE(q->wait(30000));
  m = q->metrics();
  EXPECT_TRUE(m.ended);
  EXPECT_EQ(m.errors, 5u);
  EXPECT_EQ(m.frames_out, 0u);
  EXPECT_TRUE(persons.empty());
}

// A detector that uses the tracks gets every frame's skeletons, and in a replay (block policy)
// frame t is detected only after frame t-1 was associated: it sees exactly t-1's skeletons, on
// every run, however slow the association. Without an engine nothing is observed, and nothing
// waits forever.
TEST(Pipeline, ATrackingDetectorSeesThePreviousFramesSkeletonsInAReplay) {
  Camera cam = testing::ring_camera(0, 4, 1.5, Eigen::Vector3d(0, 0, 1));
  auto engine = assoc::Engine::create(coco17_topology(), {cam, cam}, assoc::AssociationOptions{});
  ASSERT_TRUE(engine.ok()) << engine.error().message();
  testing::TrackingDetector detector(&coco17_topology(), 1);
  Recorder rec;
  CallbackSink sink = rec.sink(3);  // association slower than detection
  auto p = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 12, .images = true}),
                &detector, {&sink}, blocking(), engine->get());
  ASSERT_TRUE(p->start().ok());
  ASSERT_TRUE(p->wait(30000));
  EXPECT_TRUE(p->metrics().ended) << p->metrics().error;
  ASSERT_EQ(detector.seen.size(), 12u);
  for (std::size_t t = 0; t < detector.seen.size(); ++t) {
    EXPECT_EQ(detector.seen[t], static_cast<long>(t) - 1) << "frame " << t;
  }

  testing::TrackingDetector alone(&coco17_topology());
  auto q = make(std::make_unique<FakeSource>(FakeSource::Options{.frames = 5, .images = true}),
                &alone, {&sink}, blocking());
  ASSERT_TRUE(q->start().ok());
  ASSERT_TRUE(q->wait(30000));
  EXPECT_TRUE(q->metrics().ended);
  EXPECT_EQ(alone.seen, std::vector<long>(5, -1));
}

// The paced simulator: frame k is due k periods after start() and not given before; a caller
// that cannot wait that long gets kTimeout, not an early frame.
TEST(SimulatorSource, PacedFramesComeOnTheirScheduleNeverEarly) {
  sim::SimulatorSourceOptions so;
  so.frame_rate_hz = 2;  // a 500 ms period: far longer than any scheduling delay
  so.frames = 2;
  auto src = sim::SimulatorSource::open(so);
  ASSERT_TRUE(src.ok()) << src.error().message();
  ASSERT_TRUE((*src)->start().ok());
  SourceItem first;
  ASSERT_EQ(*(*src)->next(first, 5000), SourceStatus::kItem);
  SourceItem second;
  ASSERT_EQ(*(*src)->next(second, 0), SourceStatus::kTimeout);
  ASSERT_EQ(*(*src)->next(second, 5000), SourceStatus::kItem);
  EXPECT_GE(monotonic_ns(), second.detections->timestamp_ns);
  EXPECT_EQ(second.detections->timestamp_ns - first.detections->timestamp_ns, 500'000'000);
  EXPECT_EQ(second.detections->frame_id, 1u);
  SourceItem end;
  EXPECT_EQ(*(*src)->next(end, 0), SourceStatus::kEnded);
}

}  // namespace
}  // namespace mocap::pipeline
