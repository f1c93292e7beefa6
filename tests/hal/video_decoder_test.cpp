// hal::VideoDecoder (hal/replay/video_decoder.h): bad inputs are Errors naming the file, never
// crashes (missing file, a directory, a text file named .mp4, an audio-only WAV, a truncated
// and a damaged copy of a real video, all written to a temp dir at test time), and the
// pose2sim_multi recording decodes to 100 RGB frames of 1088x1920 at 60 fps; frames whose rows
// are not whole SIMD blocks (1080, 638, 641 px wide; H.264, MJPEG, VP9) decode inside their rows.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "hal/camera_source.h"
#include "hal/replay/recorder.h"
#include "hal/replay/video_decoder.h"
#include "tests/support/data.h"
#include "tests/support/temp_dir.h"

namespace mocap::hal {
namespace {

namespace fs = std::filesystem;

class VideoDecoderTest : public ::testing::Test {
 protected:
  fs::path file(const std::string& name) const { return dir_ / name; }

  static void write(const fs::path& p, const std::vector<char>& bytes) {
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(f.good()) << p;
  }
  static std::vector<char> read(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::vector<char>(std::istreambuf_iterator<char>(f), {});
  }

  // Decodes until the end or an error; returns the error text ("" = clean end).
  static std::string decode_all(VideoDecoder& d, std::int64_t* frames) {
    VideoFrame f;
    for (int guard = 0; guard < 100000; ++guard) {
      auto more = d.next(f);
      if (!more.ok()) {
        *frames = d.frames_decoded();
        // A failed decoder keeps failing with the same error.
        auto again = d.next(f);
        EXPECT_FALSE(again.ok());
        if (!again.ok()) {
          EXPECT_EQ(again.error().message(), more.error().message());
        }
        return more.error().message();
      }
      if (!*more) break;
    }
    *frames = d.frames_decoded();
    return "";
  }

  ::mocap::testing::TestTempDir tmp_{"video_decoder_test"};
  const std::filesystem::path dir_ = tmp_.path();
};

std::optional<fs::path> video0() {
  auto data = find_data_subdir("pose2sim_multi");
  if (!data) return std::nullopt;
  const fs::path p = *data / "videos" / "0.mp4";
  if (!fs::exists(p)) return std::nullopt;
  return p;
}

TEST_F(VideoDecoderTest, MissingFileIsNotFoundNamingThePath) {
  const fs::path p = file("nope.mp4");
  auto d = VideoDecoder::open(p);
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.error().code(), ErrorCode::kNotFound);
  EXPECT_NE(d.error().message().find(p.string()), std::string::npos) << d.error().message();
}

TEST_F(VideoDecoderTest, DirectoryIsRejected) {
  auto d = VideoDecoder::open(dir_);
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message().find(dir_.string()), std::string::npos) << d.error().message();
}

TEST_F(VideoDecoderTest, TextFileNamedMp4IsNotAVideo) {
  const fs::path p = file("notes.mp4");
  const std::string text = "this is not a video, just some text\nsecond line\n";
  write(p, std::vector<char>(text.begin(), text.end()));
  auto d = VideoDecoder::open(p);
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.error().code(), ErrorCode::kParse);
  EXPECT_NE(d.error().message().find(p.string()), std::string::npos) << d.error().message();
}

TEST_F(VideoDecoderTest, EmptyFileIsNotAVideo) {
  const fs::path p = file("empty.mp4");
  write(p, {});
  auto d = VideoDecoder::open(p);
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message().find(p.string()), std::string::npos) << d.error().message();
}

// A valid audio-only file: 0.1 s of 8 kHz mono 16-bit silence in a RIFF/WAVE container.
TEST_F(VideoDecoderTest, AudioOnlyFileHasNoVideoStream) {
  const std::uint32_t samples = 800;
  const std::uint32_t data_bytes = samples * 2;
  std::vector<char> wav;
  auto put = [&](const void* p, std::size_t n) {
    const char* c = static_cast<const char*>(p);
    wav.insert(wav.end(), c, c + n);
  };
  auto u32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) wav.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
  };
  auto u16 = [&](std::uint16_t v) {
    wav.push_back(static_cast<char>(v & 0xff));
    wav.push_back(static_cast<char>(v >> 8));
  };
  put("RIFF", 4);
  u32(36 + data_bytes);
  put("WAVEfmt ", 8);
  u32(16);
  u16(1);  // PCM
  u16(1);  // mono
  u32(8000);
  u32(16000);
  u16(2);
  u16(16);
  put("data", 4);
  u32(data_bytes);
  wav.resize(wav.size() + data_bytes, 0);
  const fs::path p = file("audio.mp4");
  write(p, wav);
  auto d = VideoDecoder::open(p);
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.error().code(), ErrorCode::kParse);
  EXPECT_NE(d.error().message().find("no video stream"), std::string::npos) << d.error().message();
  EXPECT_NE(d.error().message().find(p.string()), std::string::npos) << d.error().message();
}

TEST_F(VideoDecoderTest, DecodesTheRealRecording) {
  auto p = video0();
  if (!p) {
    MOCAP_SKIP_OR_FAIL_IN_CI("pose2sim_multi/videos/0.mp4 not found under " +
                             default_data_dir().string());
  }
  auto d = VideoDecoder::open(*p);
  ASSERT_TRUE(d.ok()) << d.error().message();
  const VideoInfo& info = (*d)->info();
  EXPECT_EQ(info.codec, "h264");
  EXPECT_EQ(info.width_px, 1088);
  EXPECT_EQ(info.height_px, 1920);
  EXPECT_EQ(info.frame_count, 100);
  EXPECT_NEAR(info.frame_rate_hz, 60.0, 0.01);
  VideoFrame f;
  std::int64_t last_ts = -1;
  std::vector<double> means;
  while (true) {
    auto more = (*d)->next(f);
    ASSERT_TRUE(more.ok()) << more.error().message();
    if (!*more) break;
    EXPECT_EQ(f.index, static_cast<std::int64_t>(means.size()));
    EXPECT_EQ(f.width_px, 1088);
    EXPECT_EQ(f.height_px, 1920);
    EXPECT_EQ(f.stride_bytes, video_rgb_stride_bytes(1088));
    EXPECT_EQ(f.stride_bytes, 1088 * 3);  // 1088 px rows are already whole 32-pixel blocks
    ASSERT_EQ(f.rgb.size(), 1088u * 1920u * 3u);
    EXPECT_GT(f.timestamp_ns, last_ts);
    last_ts = f.timestamp_ns;
    double sum = 0;
    for (std::size_t i = 0; i < f.rgb.size(); i += 97) sum += f.rgb[i];
    means.push_back(sum / static_cast<double>(f.rgb.size() / 97));
  }
  EXPECT_EQ(means.size(), 100u);
  EXPECT_EQ((*d)->frames_decoded(), 100);
  // 99 frame intervals of 1/60 s.
  EXPECT_NEAR(static_cast<double>(last_ts) * 1e-9, 99.0 / 60.0, 1e-3);
  // A lit lab scene: neither black nor saturated.
  for (double m : means) {
    EXPECT_GT(m, 20.0);
    EXPECT_LT(m, 235.0);
  }
  // The end is repeatable.
  auto again = (*d)->next(f);
  ASSERT_TRUE(again.ok());
  EXPECT_FALSE(*again);
}

// The recording keeps its index (moov) at the end: cutting the file loses it, which open()
// reports. Cutting only the last bytes of the index, or the first half, both must fail cleanly.
TEST_F(VideoDecoderTest, TruncatedCopyFailsNamingTheFile) {
  auto src = video0();
  if (!src) {
    MOCAP_SKIP_OR_FAIL_IN_CI("pose2sim_multi/videos/0.mp4 not found");
  }
  const std::vector<char> bytes = read(*src);
  ASSERT_GT(bytes.size(), 100000u);
  for (std::size_t keep : {bytes.size() / 2, bytes.size() - 1000, std::size_t{4096}}) {
    SCOPED_TRACE(keep);
    const fs::path p = file("cut_" + std::to_string(keep) + ".mp4");
    write(p, std::vector<char>(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(keep)));
    auto d = VideoDecoder::open(p);
    if (!d.ok()) {
      EXPECT_NE(d.error().message().find(p.string()), std::string::npos) << d.error().message();
      continue;
    }
    std::int64_t frames = 0;
    const std::string err = decode_all(**d, &frames);
    ASSERT_FALSE(err.empty()) << "a truncated file decoded " << frames << " frames cleanly";
    EXPECT_NE(err.find(p.string()), std::string::npos) << err;
  }
}

// Found by fuzz_video_probe: a damaged 16x16 MPEG-4 file (555 bytes) made FFmpeg 5.1's
// frame-threaded decoder abort the process (av_assert0 in libavcodec/decode.c) under
// AV_EF_EXPLODE. With slice threads it decodes or fails with an Error naming the file.
TEST_F(VideoDecoderTest, DamagedMpeg4ThatAbortedFrameThreadsIsAnErrorOrFrames) {
  const fs::path p =
      fs::path(MOCAP_SOURCE_DIR) / "tests/fuzz/corpus/video_probe/mpeg4_frame_thread_assert.mp4";
  ASSERT_TRUE(fs::exists(p)) << p;
  auto d = VideoDecoder::open(p);
  if (!d.ok()) {
    EXPECT_NE(d.error().message().find(p.string()), std::string::npos) << d.error().message();
    return;
  }
  std::int64_t frames = 0;
  const std::string err = decode_all(**d, &frames);
  if (!err.empty()) {
    EXPECT_NE(err.find(p.string()), std::string::npos) << err;
  }
}

// Garbage over part of the coded frames (the index intact): decoding stops with an error that
// names the file and the frame, after the undamaged frames before it.
TEST_F(VideoDecoderTest, CorruptDataMidStreamIsAnError) {
  auto src = video0();
  if (!src) {
    MOCAP_SKIP_OR_FAIL_IN_CI("pose2sim_multi/videos/0.mp4 not found");
  }
  std::vector<char> bytes = read(*src);
  ASSERT_GT(bytes.size(), 100000u);
  // Frames are stored from byte ~48 to the index near the end; damage 40-45 % of the file.
  std::uint32_t x = 12345;
  for (std::size_t i = bytes.size() * 40 / 100; i < bytes.size() * 45 / 100; ++i) {
    x = x * 1664525u + 1013904223u;
    bytes[i] = static_cast<char>(x >> 24);
  }
  const fs::path p = file("damaged.mp4");
  write(p, bytes);
  auto d = VideoDecoder::open(p);
  ASSERT_TRUE(d.ok()) << d.error().message();
  std::int64_t frames = 0;
  const std::string err = decode_all(**d, &frames);
  ASSERT_FALSE(err.empty()) << "damaged data decoded cleanly (" << frames << " frames)";
  EXPECT_NE(err.find(p.string()), std::string::npos) << err;
  EXPECT_GT(frames, 10) << "the frames before the damage decode";
  EXPECT_LT(frames, 100);
}

// libswscale's SIMD YUV -> RGB24 converters write whole 16-pixel blocks (24 bytes past the last
// row of a 1080-wide frame, 6 past a 638-wide one: measured with a guard after the buffer). The
// decoder's stride keeps every block inside its own row.
TEST(VideoRgbStride, CoversTheConvertersBlocksForEveryWidth) {
  for (int w = 1; w <= 4096; ++w) {
    const int s = video_rgb_stride_bytes(w);
    ASSERT_EQ(s % 64, 0) << w;
    ASSERT_GE(s, (w + 15) / 16 * 16 * 3) << w;
    ASSERT_LT(s, w * 3 + 32 * 3 + 64) << w;
  }
  EXPECT_EQ(video_rgb_stride_bytes(1080), 3264);
}

// Widths whose rows are not whole SIMD blocks (1080: the portrait 1080p of phones; 638; odd 641)
// in the codecs that allow them decode without error, every pixel inside its row, the last
// column as recorded.
TEST_F(VideoDecoderTest, AwkwardWidthsDecodeWithinTheirRows) {
  struct Case {
    int w, h;
    VideoCodec codec;
  };
  const Case cases[] = {{1080, 32, VideoCodec::kH264},
                        {638, 24, VideoCodec::kMJPEG},
                        {641, 19, VideoCodec::kVP9},
                        {1100, 20, VideoCodec::kVP9}};
  int n = 0;
  for (const Case& c : cases) {
    const fs::path dir = file("rec" + std::to_string(n++));
    RecorderOptions o;
    o.dir = dir;
    o.views = 1;
    o.codecs = {c.codec};
    auto rec = Recorder::create(o);
    ASSERT_TRUE(rec.ok()) << rec.error().message();
    // A horizontal ramp: column x has grey level 40 + 160 x / w.
    std::vector<std::uint8_t> px(static_cast<std::size_t>(c.w) * c.h * 3);
    for (int y = 0; y < c.h; ++y) {
      for (int x = 0; x < c.w; ++x) {
        const auto g = static_cast<std::uint8_t>(40 + 160 * x / c.w);
        for (int k = 0; k < 3; ++k) px[(static_cast<std::size_t>(y) * c.w + x) * 3 + k] = g;
      }
    }
    for (int k = 0; k < 3; ++k) {
      FrameSet set;
      set.timestamp_ns = k * 16'666'667LL;
      Frame f;
      f.view_id = 0;
      f.width_px = c.w;
      f.height_px = c.h;
      f.stride_bytes = c.w * 3;
      f.buffer = std::make_shared<OwnedFrameBuffer>(px);
      set.frames.push_back(f);
      ASSERT_TRUE((*rec)->write(set).ok());
    }
    ASSERT_TRUE((*rec)->finish().ok());
    auto d = VideoDecoder::open(dir / "videos" / "0.mp4");
    ASSERT_TRUE(d.ok()) << d.error().message();
    EXPECT_EQ((*d)->info().width_px, c.w);
    EXPECT_EQ((*d)->info().height_px, c.h);
    VideoFrame f;
    int frames = 0;
    while (true) {
      auto more = (*d)->next(f);
      ASSERT_TRUE(more.ok()) << c.w << "x" << c.h << ": " << more.error().message();
      if (!*more) break;
      ++frames;
      EXPECT_EQ(f.stride_bytes, video_rgb_stride_bytes(c.w));
      ASSERT_EQ(f.rgb.size(), static_cast<std::size_t>(f.stride_bytes) * c.h);
      const std::size_t row = static_cast<std::size_t>(c.h / 2) * f.stride_bytes;
      EXPECT_NEAR(f.rgb[row], 40, 12) << c.w;
      EXPECT_NEAR(f.rgb[row + (c.w - 1) * 3], 40 + 160 * (c.w - 1) / c.w, 12) << c.w;
    }
    EXPECT_EQ(frames, 3) << c.w << "x" << c.h;
  }
}

}  // namespace
}  // namespace mocap::hal
