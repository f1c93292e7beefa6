// One recording of awkward geometry through the three tools that replay: views of 1080x1920
// (portrait 1080p: its RGB rows are not a multiple of the converter's SIMD width, the case that
// corrupted the heap before), 1088x1920, 638x478 and 641x479 (odd), coded as H.264, VP9, MJPEG
// and VP9, generated here from the first frames of the shared pose2sim_multi clip with a
// calibration that matches each view's crop, scale and padding. `mocapd --recording`, `mocap
// replay` and `mocap bench pipeline` (the binaries of this build: ASan + UBSan in the sanitizer
// suite) must each exit 0 and give the same skeletons, frame by frame: they run one pipeline.
//
// Skips without the data, the model or a Vulkan device, except under CI=true, where it fails.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "hal/camera_source.h"
#include "hal/replay/recorder.h"
#include "hal/replay/video_decoder.h"
#include "runtime/geometry/calibration.h"
#include "runtime/gpu/context.h"
#include "tests/support/data.h"
#include "tests/support/line_client.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kFrames = 10;

// Target view v: size, codec, and the map from source pixels: target = scale * source + offset.
struct ViewSpec {
  int width_px, height_px;
  hal::VideoCodec codec;
  double scale, offset_x_px, offset_y_px;
};

std::vector<ViewSpec> view_specs(int src_w, int src_h) {
  const auto fit = [&](int w, int h, hal::VideoCodec codec) {
    const double s = static_cast<double>(h) / src_h;  // whole height, black bars left and right
    return ViewSpec{w, h, codec, s, (w - src_w * s) / 2.0, 0.0};
  };
  return {
      ViewSpec{1080, 1920, hal::VideoCodec::kH264, 1.0, -4.0, 0.0},  // 4 px cropped off each side
      ViewSpec{1088, 1920, hal::VideoCodec::kVP9, 1.0, 0.0, 0.0},
      fit(638, 478, hal::VideoCodec::kMJPEG),
      fit(641, 479, hal::VideoCodec::kVP9),
  };
}

// Bilinear resampling of a packed RGB24 image into the target view (black outside the source).
Frame resample(const hal::VideoFrame& src, const ViewSpec& v, int view) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(v.width_px) * v.height_px * 3, 0);
  for (int y = 0; y < v.height_px; ++y) {
    for (int x = 0; x < v.width_px; ++x) {
      const double sx = (x + 0.5 - v.offset_x_px) / v.scale - 0.5;
      const double sy = (y + 0.5 - v.offset_y_px) / v.scale - 0.5;
      if (sx < -0.5 || sy < -0.5 || sx > src.width_px - 0.5 || sy > src.height_px - 0.5) continue;
      const double cx = std::clamp(sx, 0.0, src.width_px - 1.0);
      const double cy = std::clamp(sy, 0.0, src.height_px - 1.0);
      const int x0 = static_cast<int>(cx), y0 = static_cast<int>(cy);
      const int x1 = std::min(x0 + 1, src.width_px - 1), y1 = std::min(y0 + 1, src.height_px - 1);
      const double fx = cx - x0, fy = cy - y0;
      for (int c = 0; c < 3; ++c) {
        auto at = [&](int xx, int yy) {
          return static_cast<double>(
              src.rgb[static_cast<std::size_t>(yy) * src.stride_bytes + xx * 3 + c]);
        };
        const double val = (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x1, y0)) +
                           fy * ((1 - fx) * at(x0, y1) + fx * at(x1, y1));
        out[(static_cast<std::size_t>(y) * v.width_px + x) * 3 + c] =
            static_cast<std::uint8_t>(std::lround(val));
      }
    }
  }
  Frame f;
  f.view_id = view;
  f.width_px = v.width_px;
  f.height_px = v.height_px;
  f.stride_bytes = v.width_px * 3;
  f.format = PixelFormat::kRGB24;
  f.buffer = std::make_shared<hal::OwnedFrameBuffer>(std::move(out));
  return f;
}

// The camera seen through the view's crop / scale / padding.
Camera transformed(const Camera& c, const ViewSpec& v) {
  Camera out = c;
  Eigen::Matrix3d K = c.K();
  K.row(0) *= v.scale;
  K.row(1) *= v.scale;
  K(0, 2) += v.offset_x_px;
  K(1, 2) += v.offset_y_px;
  out.set_intrinsics(K);
  out.set_image_size(v.width_px, v.height_px);
  return out;
}

// Writes the recording: kFrames frames of every view, transformed and encoded.
void make_recording(const fs::path& shared, const fs::path& dir) {
  auto calib = load_calibration(shared / "calibration.json");
  ASSERT_TRUE(calib.ok()) << calib.error().message();
  const std::vector<ViewSpec> specs =
      view_specs(calib->cameras[0].width_px(), calib->cameras[0].height_px());
  ASSERT_EQ(calib->size(), specs.size());
  hal::RecorderOptions ro;
  ro.dir = dir;
  ro.views = static_cast<int>(specs.size());
  ro.frame_rate_hz = 60;
  for (const ViewSpec& v : specs) ro.codecs.push_back(v.codec);
  auto rec = hal::Recorder::create(ro);
  ASSERT_TRUE(rec.ok()) << rec.error().message();
  std::vector<std::unique_ptr<hal::VideoDecoder>> decoders;
  for (std::size_t v = 0; v < specs.size(); ++v) {
    auto d = hal::VideoDecoder::open(shared / "videos" / (std::to_string(v) + ".mp4"));
    ASSERT_TRUE(d.ok()) << d.error().message();
    decoders.push_back(std::move(*d));
  }
  hal::VideoFrame vf;
  for (int i = 0; i < kFrames; ++i) {
    FrameSet set;
    set.frame_id = static_cast<std::uint64_t>(i);
    set.timestamp_ns = static_cast<std::int64_t>(i) * 1'000'000'000 / 60;
    for (std::size_t v = 0; v < specs.size(); ++v) {
      auto more = decoders[v]->next(vf);
      ASSERT_TRUE(more.ok() && *more) << "view " << v << " frame " << i;
      set.frames.push_back(resample(vf, specs[v], static_cast<int>(v)));
      set.frames.back().timestamp_ns = set.timestamp_ns;
    }
    ASSERT_TRUE((*rec)->write(set).ok());
  }
  ASSERT_TRUE((*rec)->finish().ok());
  Calibration out = *calib;
  for (std::size_t v = 0; v < specs.size(); ++v) {
    out.cameras[v] = transformed(calib->cameras[v], specs[v]);
  }
  ASSERT_TRUE(save_calibration(out, dir / "calibration.json").ok());
}

int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(fd);
  return ntohs(a.sin_port);
}

// The "persons" of each message line, by frame id.
std::vector<json> persons_by_frame(const std::string& lines, std::string& why) {
  std::vector<json> out;
  std::size_t start = 0;
  while (start < lines.size()) {
    std::size_t nl = lines.find('\n', start);
    if (nl == std::string::npos) nl = lines.size();
    json m = json::parse(lines.substr(start, nl - start), nullptr, false);
    start = nl + 1;
    if (m.is_discarded() || m.value("type", "") != "skeletons") {
      why = "not a skeletons message";
      return {};
    }
    if (m["frame_id"].get<std::size_t>() != out.size()) {
      why = "frame " + m["frame_id"].dump() + " at line " + std::to_string(out.size());
      return {};
    }
    out.push_back(m["persons"]);
  }
  return out;
}

TEST(MixedGeometry, ThreeToolsOnePipelineSameSkeletons) {
  MOCAP_REQUIRE_DATA(shared, "pose2sim_multi");
  const fs::path model = fs::path(MOCAP_SOURCE_DIR) / "models/posenet.mcnn";
  if (!fs::exists(model)) MOCAP_SKIP_OR_FAIL_IN_CI("models/posenet.mcnn missing");
  {
    auto ctx = gpu::Context::create(gpu::GpuOptions{});
    if (!ctx.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + ctx.error().message());
  }
  testing::TestTempDir tmp("mixed");
  const fs::path rec = tmp.path() / "recording";
  make_recording(shared, rec);
  if (HasFatalFailure()) return;
  // The recording is what it should be: sizes and codecs as decoded.
  const char* codecs[] = {"h264", "vp9", "mjpeg", "vp9"};
  const std::vector<ViewSpec> specs = view_specs(1088, 1920);
  for (int v = 0; v < 4; ++v) {
    auto d = hal::VideoDecoder::open(rec / "videos" / (std::to_string(v) + ".mp4"));
    ASSERT_TRUE(d.ok()) << d.error().message();
    EXPECT_EQ((*d)->info().width_px, specs[static_cast<std::size_t>(v)].width_px);
    EXPECT_EQ((*d)->info().height_px, specs[static_cast<std::size_t>(v)].height_px);
    EXPECT_NE((*d)->info().codec.find(codecs[v]), std::string::npos) << (*d)->info().codec;
  }

  const std::string bin = MOCAP_BIN_DIR;
  const fs::path a = tmp.path() / "replay.jsonl", b = tmp.path() / "bench.jsonl";
  const testing::ProcessResult replay =
      testing::run_process({bin + "/mocap", "replay", "--recording", rec.string(), "--model",
                            model.string(), "--quiet", "--skeletons-out", a.string()},
                           tmp.path(), "replay", 600000);
  ASSERT_EQ(replay.exit_code, 0) << replay.how() << "\n" << replay.err << replay.out;
  const testing::ProcessResult bench =
      testing::run_process({bin + "/mocap", "bench", "pipeline", "--recording", rec.string(),
                            "--model", model.string(), "--skeletons-out", b.string()},
                           tmp.path(), "bench", 600000);
  ASSERT_EQ(bench.exit_code, 0) << bench.how() << "\n" << bench.err << bench.out;

  // mocapd: its stream, read by a client that connects before the first frame can be out
  // (decoding and the CNN take far longer than a loopback connect; frame ids are checked).
  const int port = free_port();
  testing::ChildProcess daemon(
      {bin + "/mocapd", "--recording", rec.string(), "--model", model.string(), "--bind-address",
       "127.0.0.1", "--stream-port", std::to_string(port), "--http-port", "-1", "--state-dir",
       (tmp.path() / "state").string()},
      tmp.path(), "mocapd");
  ASSERT_TRUE(daemon.started());
  std::string streamed;
  for (int attempt = 0; attempt < 3000; ++attempt) {  // up to 60 s to load the model
    testing::LineClient client(port);
    if (client.connected()) {
      streamed = client.read_all(600000);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const testing::ProcessResult d = daemon.wait(60000);
  ASSERT_EQ(d.exit_code, 0) << d.how() << "\n" << d.err;

  std::string why;
  const std::vector<json> from_replay = persons_by_frame(testing::read_text(a), why);
  ASSERT_EQ(from_replay.size(), static_cast<std::size_t>(kFrames)) << "mocap replay: " << why;
  const std::vector<json> from_bench = persons_by_frame(testing::read_text(b), why);
  ASSERT_EQ(from_bench.size(), static_cast<std::size_t>(kFrames)) << "bench pipeline: " << why;
  const std::vector<json> from_daemon = persons_by_frame(streamed, why);
  ASSERT_EQ(from_daemon.size(), static_cast<std::size_t>(kFrames)) << "mocapd: " << why;
  int persons = 0;
  for (int i = 0; i < kFrames; ++i) {
    const auto k = static_cast<std::size_t>(i);
    EXPECT_EQ(from_bench[k], from_replay[k]) << "frame " << i;
    EXPECT_EQ(from_daemon[k], from_replay[k]) << "frame " << i;
    persons += static_cast<int>(from_replay[k].size());
  }
  // The views are usable, not only survivable: the two people are found.
  EXPECT_GE(persons, kFrames) << "no skeletons from the recording";
  std::printf("mixed geometry: %d frames, %d persons in all, the same from all three tools\n",
              kFrames, persons);
}

}  // namespace
}  // namespace mocap
