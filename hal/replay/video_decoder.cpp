#include "hal/replay/video_decoder.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/error.h>
#include <libavutil/imgutils.h>
#include <libavutil/log.h>
#include <libswscale/swscale.h>
}

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <mutex>
#include <system_error>
#include <utility>

#include "runtime/core/log.h"

namespace mocap::hal {

MOCAP_LOG_CATEGORY(Video)

namespace {

std::string av_error_text(int code) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(code, buf, sizeof buf);
  return buf;
}

// FFmpeg's own messages (e.g. "error while decoding MB ...") go to the Video log category at
// debug level: the decoder reports failures as Errors, so its chatter stays off stderr.
void forward_av_log(void* avcl, int level, const char* fmt, std::va_list args) {
  if (level > AV_LOG_WARNING || !log_category_Video().enabled(LogLevel::Debug)) return;
  char line[1024];
  int print_prefix = 1;
  std::va_list copy;
  va_copy(copy, args);
  av_log_format_line2(avcl, level, fmt, copy, line, sizeof line, &print_prefix);
  va_end(copy);
  std::string text(line);
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  if (!text.empty()) {
    MOCAP_LOG(Video, Debug) << "ffmpeg: " << text;
  }
}

}  // namespace

void install_av_log() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_callback(forward_av_log); });
}

namespace {

constexpr std::size_t kGuardBytes = 64;
constexpr std::uint8_t kGuardByte = 0xA5;

}  // namespace

int video_rgb_stride_bytes(int width_px) {
  const int row_px = (width_px + 31) / 32 * 32;
  return (row_px * 3 + 63) / 64 * 64;
}

struct VideoDecoder::Impl {
  AVFormatContext* format = nullptr;
  AVCodecContext* codec = nullptr;
  AVPacket* packet = nullptr;
  AVFrame* frame = nullptr;
  SwsContext* sws = nullptr;
  int stream_index = -1;
  AVRational time_base{1, 1};
  std::int64_t start_pts = 0;
  bool input_done = false;  // av_read_frame reached the end; the decoder is being drained
  std::int64_t packets = 0;

  ~Impl() {
    sws_freeContext(sws);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&codec);
    avformat_close_input(&format);
  }
};

VideoDecoder::VideoDecoder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
VideoDecoder::~VideoDecoder() = default;

Result<std::unique_ptr<VideoDecoder>> VideoDecoder::open(const std::filesystem::path& path) {
  install_av_log();
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return Error(ErrorCode::kNotFound, name + ": no such file");
  }
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Error(ErrorCode::kInvalidArgument, name + ": not a regular file");
  }
  auto impl = std::make_unique<Impl>();
  if (int rc = avformat_open_input(&impl->format, name.c_str(), nullptr, nullptr); rc < 0) {
    impl->format = nullptr;  // freed by avformat_open_input on failure
    return Error(ErrorCode::kParse,
                 name + ": not a readable video file (FFmpeg: " + av_error_text(rc) + ")");
  }
  if (int rc = avformat_find_stream_info(impl->format, nullptr); rc < 0) {
    return Error(ErrorCode::kParse,
                 name + ": cannot read the stream information (FFmpeg: " + av_error_text(rc) + ")");
  }
  const AVCodec* decoder = nullptr;
  const int best =
      av_find_best_stream(impl->format, AVMEDIA_TYPE_VIDEO, -1, -1, &decoder, /*flags=*/0);
  if (best == AVERROR_STREAM_NOT_FOUND) {
    return Error(ErrorCode::kParse, name + ": no video stream (" +
                                        std::to_string(impl->format->nb_streams) +
                                        " stream(s) of other kinds)");
  }
  if (best == AVERROR_DECODER_NOT_FOUND || (best >= 0 && decoder == nullptr)) {
    // The stream exists but this FFmpeg build cannot decode it: name the codec.
    std::string codec_name = "unknown";
    for (unsigned i = 0; i < impl->format->nb_streams; ++i) {
      const AVCodecParameters* par = impl->format->streams[i]->codecpar;
      if (par->codec_type == AVMEDIA_TYPE_VIDEO) {
        codec_name = avcodec_get_name(par->codec_id);
        break;
      }
    }
    return Error(ErrorCode::kUnsupported, name + ": no decoder for video codec '" + codec_name +
                                              "' in this FFmpeg build (" LIBAVCODEC_IDENT ")");
  }
  if (best < 0) {
    return Error(ErrorCode::kParse,
                 name + ": cannot select a video stream (FFmpeg: " + av_error_text(best) + ")");
  }
  impl->stream_index = best;
  AVStream* stream = impl->format->streams[best];
  impl->time_base = stream->time_base;
  impl->start_pts = stream->start_time == AV_NOPTS_VALUE ? 0 : stream->start_time;

  impl->codec = avcodec_alloc_context3(decoder);
  if (impl->codec == nullptr) return Error(ErrorCode::kInternal, name + ": out of memory");
  if (int rc = avcodec_parameters_to_context(impl->codec, stream->codecpar); rc < 0) {
    return Error(ErrorCode::kParse,
                 name + ": bad codec parameters (FFmpeg: " + av_error_text(rc) + ")");
  }
  // Report damaged data instead of concealing it.
  impl->codec->err_recognition |= AV_EF_EXPLODE;
  impl->codec->thread_count = 0;  // FFmpeg picks (one per core)
  // Slice threads, not frame threads: FFmpeg 5.1's frame-threaded MPEG-4 decoder aborts the
  // process (av_assert0 "frame->buf[0]", decode.c:502) on some damaged streams with
  // AV_EF_EXPLODE (found by fuzz_video_probe; tests/fuzz/corpus/video_probe/
  // mpeg4_frame_thread_assert.mp4). Decoding the 1088x1920 pose2sim recording runs as fast
  // here (2 cores: 117-141 vs 94-140 frames/s), and the views decode in parallel anyway.
  impl->codec->thread_type = FF_THREAD_SLICE;
  impl->codec->pkt_timebase = stream->time_base;
  if (int rc = avcodec_open2(impl->codec, decoder, nullptr); rc < 0) {
    return Error(ErrorCode::kUnsupported, name + ": cannot open the " + decoder->name +
                                              " decoder (FFmpeg: " + av_error_text(rc) + ")");
  }
  if (impl->codec->width <= 0 || impl->codec->height <= 0) {
    return Error(ErrorCode::kParse, name + ": video stream without a frame size");
  }
  impl->packet = av_packet_alloc();
  impl->frame = av_frame_alloc();
  if (impl->packet == nullptr || impl->frame == nullptr) {
    return Error(ErrorCode::kInternal, name + ": out of memory");
  }

  VideoInfo info;
  info.path = name;
  info.container = impl->format->iformat->name;
  info.codec = decoder->name;
  info.width_px = impl->codec->width;
  info.height_px = impl->codec->height;
  if (stream->avg_frame_rate.num > 0 && stream->avg_frame_rate.den > 0) {
    info.frame_rate_hz = av_q2d(stream->avg_frame_rate);
  }
  info.frame_count = stream->nb_frames > 0 ? stream->nb_frames : 0;

  std::unique_ptr<VideoDecoder> d(new VideoDecoder(std::move(impl)));
  d->info_ = std::move(info);
  return d;
}

Error VideoDecoder::fail(ErrorCode code, const std::string& what) {
  Error e(code, info_.path + ": " + what);
  failed_ = std::make_unique<Error>(e);
  return e;
}

Result<bool> VideoDecoder::next(VideoFrame& out) {
  if (failed_) return *failed_;
  if (ended_) return false;
  Result<bool> got = receive_frame();
  if (!got.ok() || !*got) return got;
  if (Status s = convert_frame(out); !s.ok()) return s.error();
  ++decoded_;
  return true;
}

// Feeds packets to the decoder until it gives a frame (impl_->frame): true; false at the end.
Result<bool> VideoDecoder::receive_frame() {
  Impl& m = *impl_;
  while (true) {
    const int rc = avcodec_receive_frame(m.codec, m.frame);
    if (rc == 0) return true;
    if (rc == AVERROR_EOF) {
      ended_ = true;
      if (info_.frame_count > 0 && decoded_ < info_.frame_count) {
        return fail(ErrorCode::kParse, "stream ended after " + std::to_string(decoded_) + " of " +
                                           std::to_string(info_.frame_count) +
                                           " frames (truncated or corrupt file)");
      }
      return false;
    }
    if (rc != AVERROR(EAGAIN)) {
      return fail(ErrorCode::kParse, "corrupt video data at frame " + std::to_string(decoded_) +
                                         " (FFmpeg: " + av_error_text(rc) + ")");
    }
    // The decoder wants input.
    if (m.input_done) {
      return fail(ErrorCode::kInternal, "decoder stalled while draining");
    }
    const int rd = av_read_frame(m.format, m.packet);
    if (rd == AVERROR_EOF) {
      m.input_done = true;
      if (int s = avcodec_send_packet(m.codec, nullptr); s < 0 && s != AVERROR_EOF) {
        return fail(ErrorCode::kParse,
                    "cannot drain the decoder (FFmpeg: " + av_error_text(s) + ")");
      }
      continue;
    }
    if (rd < 0) {
      return fail(rd == AVERROR(EIO) ? ErrorCode::kIo : ErrorCode::kParse,
                  "cannot read packet " + std::to_string(m.packets) + " after frame " +
                      std::to_string(decoded_) + " (FFmpeg: " + av_error_text(rd) + ")");
    }
    if (m.packet->stream_index != m.stream_index) {
      av_packet_unref(m.packet);
      continue;
    }
    ++m.packets;
    const int s = avcodec_send_packet(m.codec, m.packet);
    av_packet_unref(m.packet);
    if (s < 0 && s != AVERROR(EAGAIN)) {
      return fail(ErrorCode::kParse, "corrupt video data in packet " +
                                         std::to_string(m.packets - 1) + " (after frame " +
                                         std::to_string(decoded_) +
                                         "; FFmpeg: " + av_error_text(s) + ")");
    }
  }
}

// impl_->frame as packed RGB24 into `out` (the frame is released).
Status VideoDecoder::convert_frame(VideoFrame& out) {
  Impl& m = *impl_;
  AVFrame* f = m.frame;
  if ((f->flags & AV_FRAME_FLAG_CORRUPT) != 0 || f->decode_error_flags != 0) {
    av_frame_unref(f);
    return fail(ErrorCode::kParse, "frame " + std::to_string(decoded_) + " decoded with errors");
  }
  if (f->width <= 0 || f->height <= 0) {
    av_frame_unref(f);
    return fail(ErrorCode::kParse, "frame " + std::to_string(decoded_) + " has no size");
  }
  m.sws = sws_getCachedContext(m.sws, f->width, f->height, static_cast<AVPixelFormat>(f->format),
                               f->width, f->height, AV_PIX_FMT_RGB24, SWS_BILINEAR, nullptr,
                               nullptr, nullptr);
  if (m.sws == nullptr) {
    const char* fmt_name = av_get_pix_fmt_name(static_cast<AVPixelFormat>(f->format));
    av_frame_unref(f);
    return fail(ErrorCode::kUnsupported, std::string("cannot convert pixel format ") +
                                             (fmt_name ? fmt_name : "unknown") + " to RGB24");
  }
  out.width_px = f->width;
  out.height_px = f->height;
  out.stride_bytes = video_rgb_stride_bytes(f->width);
  const std::size_t image_bytes =
      static_cast<std::size_t>(out.stride_bytes) * static_cast<std::size_t>(f->height);
  // A guard past the image, checked after the conversion: a converter that writes past the rows
  // it was given is an error here, never a corrupted heap later.
  out.rgb.resize(image_bytes + kGuardBytes);
  std::fill(out.rgb.begin() + static_cast<std::ptrdiff_t>(image_bytes), out.rgb.end(), kGuardByte);
  std::uint8_t* dst[4] = {out.rgb.data(), nullptr, nullptr, nullptr};
  int dst_stride[4] = {out.stride_bytes, 0, 0, 0};
  const int rows = sws_scale(m.sws, f->data, f->linesize, 0, f->height, dst, dst_stride);
  const bool guard_intact =
      std::all_of(out.rgb.begin() + static_cast<std::ptrdiff_t>(image_bytes), out.rgb.end(),
                  [](std::uint8_t b) { return b == kGuardByte; });
  out.rgb.resize(image_bytes);  // keeps the capacity: the next frame reuses the buffer
  std::int64_t pts = f->best_effort_timestamp;
  av_frame_unref(f);
  if (!guard_intact) {
    return fail(ErrorCode::kInternal, "RGB conversion of frame " + std::to_string(decoded_) +
                                          " wrote past the " + std::to_string(out.width_px) + "x" +
                                          std::to_string(out.height_px) + " image");
  }
  if (rows != out.height_px) {
    return fail(ErrorCode::kInternal, "RGB conversion of frame " + std::to_string(decoded_) +
                                          " wrote " + std::to_string(rows) + " rows");
  }
  out.index = decoded_;
  if (pts == AV_NOPTS_VALUE) {
    out.timestamp_ns =
        info_.frame_rate_hz > 0
            ? static_cast<std::int64_t>(static_cast<double>(decoded_) * 1e9 / info_.frame_rate_hz)
            : 0;
  } else {
    out.timestamp_ns = av_rescale_q(pts - m.start_pts, m.time_base, AVRational{1, 1000000000});
  }
  return {};
}

}  // namespace mocap::hal
