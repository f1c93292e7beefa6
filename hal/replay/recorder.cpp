#include "hal/replay/recorder.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <cmath>
#include <system_error>
#include <utility>

#include "hal/replay/video_decoder.h"
#include "runtime/core/log.h"
#include "runtime/geometry/calibration.h"

namespace mocap::hal {
namespace {

MOCAP_LOG_CATEGORY(Recorder)

std::string av_error(int err) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(err, buf, sizeof buf);
  return buf;
}

AVPixelFormat av_format(PixelFormat f) {
  switch (f) {
    case PixelFormat::kRGB24:
      return AV_PIX_FMT_RGB24;
    case PixelFormat::kYUYV:
      return AV_PIX_FMT_YUYV422;
    case PixelFormat::kNV12:
      return AV_PIX_FMT_NV12;
    case PixelFormat::kGREY:
      return AV_PIX_FMT_GRAY8;
    case PixelFormat::kMJPEG:
      return AV_PIX_FMT_NONE;
  }
  return AV_PIX_FMT_NONE;
}

// Timestamps in microseconds.
constexpr AVRational kTimeBase{1, 1'000'000};

// The encoder of a codec (H.264 falls back to MPEG-4 part 2 when the build lacks libx264).
const AVCodec* find_encoder(VideoCodec codec) {
  switch (codec) {
    case VideoCodec::kH264: {
      const AVCodec* c = avcodec_find_encoder_by_name("libx264");
      return c != nullptr ? c : avcodec_find_encoder(AV_CODEC_ID_MPEG4);
    }
    case VideoCodec::kVP9:
      return avcodec_find_encoder_by_name("libvpx-vp9");
    case VideoCodec::kMJPEG:
      return avcodec_find_encoder(AV_CODEC_ID_MJPEG);
    case VideoCodec::kMPEG4:
      return avcodec_find_encoder(AV_CODEC_ID_MPEG4);
  }
  return nullptr;
}

// High quality for the pose CNN's purposes, at a speed that keeps up with capture.
void set_quality(const AVCodec* codec, AVCodecContext* ctx, AVDictionary** opts) {
  const std::string name = codec->name;
  if (name == "libx264") {
    av_dict_set(opts, "preset", "veryfast", 0);
    av_dict_set(opts, "crf", "18", 0);  // visually lossless
  } else if (name == "libvpx-vp9") {
    av_dict_set(opts, "deadline", "realtime", 0);
    av_dict_set(opts, "cpu-used", "8", 0);
    av_dict_set(opts, "crf", "20", 0);
    ctx->bit_rate = 0;  // constant quality
  } else {
    ctx->flags |= AV_CODEC_FLAG_QSCALE;
    ctx->global_quality = FF_QP2LAMBDA * 2;
  }
}

}  // namespace

std::string_view to_string(VideoCodec codec) {
  switch (codec) {
    case VideoCodec::kH264:
      return "h264";
    case VideoCodec::kVP9:
      return "vp9";
    case VideoCodec::kMJPEG:
      return "mjpeg";
    case VideoCodec::kMPEG4:
      return "mpeg4";
  }
  return "?";
}

// One view: container, encoder and converter.
class Recorder::ViewEncoder {
 public:
  ~ViewEncoder() {
    if (sws_ != nullptr) sws_freeContext(sws_);
    if (frame_ != nullptr) av_frame_free(&frame_);
    if (packet_ != nullptr) av_packet_free(&packet_);
    if (codec_ != nullptr) avcodec_free_context(&codec_);
    if (out_ != nullptr) {
      if (out_->pb != nullptr) avio_closep(&out_->pb);
      avformat_free_context(out_);
    }
  }

  Status open(const std::filesystem::path& path, const Frame& first, double rate_hz,
              VideoCodec wanted, std::string* codec_name) {
    path_ = path.string();
    width_ = first.width_px;
    height_ = first.height_px;
    if (avformat_alloc_output_context2(&out_, nullptr, "mp4", path_.c_str()) < 0 ||
        out_ == nullptr) {
      return fail("cannot create an mp4 container");
    }
    const AVCodec* codec = find_encoder(wanted);
    if (codec == nullptr) {
      return fail("this FFmpeg build has no " + std::string(to_string(wanted)) + " encoder");
    }
    const bool yuv420 = codec->id == AV_CODEC_ID_H264 || codec->id == AV_CODEC_ID_MPEG4;
    if (yuv420 && (width_ % 2 != 0 || height_ % 2 != 0)) {
      return fail(std::string(codec->name) + " needs an even width and height, the frames are " +
                  std::to_string(width_) + "x" + std::to_string(height_) +
                  ": record this view as VP9 or MJPEG");
    }
    *codec_name = codec->name;
    pix_fmt_ = codec->id == AV_CODEC_ID_MJPEG ? AV_PIX_FMT_YUVJ420P : AV_PIX_FMT_YUV420P;
    codec_ = avcodec_alloc_context3(codec);
    codec_->width = width_;
    codec_->height = height_;
    codec_->pix_fmt = pix_fmt_;
    codec_->time_base = kTimeBase;
    codec_->framerate = av_d2q(rate_hz, 1000);
    codec_->gop_size = static_cast<int>(std::lround(rate_hz));  // a keyframe every second
    if ((out_->oformat->flags & AVFMT_GLOBALHEADER) != 0)
      codec_->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    AVDictionary* opts = nullptr;
    set_quality(codec, codec_, &opts);
    int r = avcodec_open2(codec_, codec, &opts);
    av_dict_free(&opts);
    if (r < 0) return fail("encoder " + std::string(codec->name) + ": " + av_error(r));
    stream_ = avformat_new_stream(out_, nullptr);
    stream_->time_base = kTimeBase;
    avcodec_parameters_from_context(stream_->codecpar, codec_);
    if ((r = avio_open(&out_->pb, path_.c_str(), AVIO_FLAG_WRITE)) < 0) return fail(av_error(r));
    if ((r = avformat_write_header(out_, nullptr)) < 0) return fail(av_error(r));
    header_written_ = true;
    frame_ = av_frame_alloc();
    frame_->format = pix_fmt_;
    frame_->width = width_;
    frame_->height = height_;
    if (av_frame_get_buffer(frame_, 0) < 0) return fail("out of memory");
    packet_ = av_packet_alloc();
    return Status::Ok();
  }

  Status encode(const Frame& f, std::int64_t pts_us) {
    if (f.width_px != width_ || f.height_px != height_) {
      return fail("frame size " + std::to_string(f.width_px) + "x" + std::to_string(f.height_px) +
                  " differs from the first frame's " + std::to_string(width_) + "x" +
                  std::to_string(height_));
    }
    const AVPixelFormat in = av_format(f.format);
    if (in == AV_PIX_FMT_NONE || !f.buffer)
      return fail("frame format " + std::string(to_string(f.format)) + " cannot be encoded");
    if (pts_us <= last_pts_) pts_us = last_pts_ + 1;  // strictly increasing for the muxer
    last_pts_ = pts_us;
    sws_ = sws_getCachedContext(sws_, width_, height_, in, width_, height_, pix_fmt_, SWS_BILINEAR,
                                nullptr, nullptr, nullptr);
    if (sws_ == nullptr) return fail("no conversion to the encoder's pixel format");
    const std::uint8_t* src[4] = {f.buffer->bytes().data(), nullptr, nullptr, nullptr};
    int src_stride[4] = {f.stride_bytes, 0, 0, 0};
    const std::size_t luma = static_cast<std::size_t>(f.stride_bytes) * height_;
    const std::size_t uv = f.uv_offset_bytes > 0 ? f.uv_offset_bytes : luma;
    const std::size_t need = f.format == PixelFormat::kNV12 ? uv + luma / 2 : luma;
    if (f.buffer->bytes().size() < need)
      return fail("frame buffer is shorter than its format needs");
    if (f.format == PixelFormat::kNV12) {
      src[1] = src[0] + uv;
      src_stride[1] = f.stride_bytes;
    }
    if (av_frame_make_writable(frame_) < 0) return fail("out of memory");
    sws_scale(sws_, src, src_stride, 0, height_, frame_->data, frame_->linesize);
    frame_->pts = pts_us;
    return send(frame_);
  }

  Status finish() {
    // An encoder whose open() failed part-way has nothing to flush (and maybe no codec).
    if (!header_written_ || finished_) return Status::Ok();
    finished_ = true;
    if (Status s = send(nullptr); !s.ok()) return s;
    if (const int r = av_write_trailer(out_); r < 0) return fail(av_error(r));
    if (out_->pb != nullptr) avio_closep(&out_->pb);
    return Status::Ok();
  }

 private:
  Status send(AVFrame* f) {
    int r = avcodec_send_frame(codec_, f);
    if (r < 0) return fail("encode: " + av_error(r));
    for (;;) {
      r = avcodec_receive_packet(codec_, packet_);
      if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return Status::Ok();
      if (r < 0) return fail("encode: " + av_error(r));
      // Every sample gets a duration (one nominal frame period when the encoder gave none):
      // the mp4 muxer sizes the edit list by the samples' durations, and a last sample without
      // one was cut off by demuxers (a 10-frame take read back as 9 frames).
      if (packet_->duration <= 0) {
        packet_->duration = av_rescale_q(1, av_inv_q(codec_->framerate), codec_->time_base);
      }
      av_packet_rescale_ts(packet_, codec_->time_base, stream_->time_base);
      packet_->stream_index = stream_->index;
      r = av_interleaved_write_frame(out_, packet_);
      if (r < 0) return fail("write: " + av_error(r));
    }
  }

  Status fail(const std::string& what) const { return Error(ErrorCode::kIo, path_ + ": " + what); }

  std::string path_;
  int width_ = 0;
  int height_ = 0;
  std::int64_t last_pts_ = -1;
  bool finished_ = false;
  AVFormatContext* out_ = nullptr;
  AVCodecContext* codec_ = nullptr;
  AVStream* stream_ = nullptr;
  AVFrame* frame_ = nullptr;
  AVPacket* packet_ = nullptr;
  SwsContext* sws_ = nullptr;
  AVPixelFormat pix_fmt_ = AV_PIX_FMT_YUV420P;
  bool header_written_ = false;  // open() got as far as the container header
};

Status RecorderOptions::validate() const {
  if (dir.empty()) return Error(ErrorCode::kInvalidArgument, "recorder: no output folder given");
  if (views < 1 || views > 16)
    return Error(ErrorCode::kInvalidArgument, "recorder: views must be in 1..16");
  if (!(frame_rate_hz > 0) || frame_rate_hz > 1000) {
    return Error(ErrorCode::kInvalidArgument, "recorder: frame_rate_hz must be in (0, 1000]");
  }
  if (!codecs.empty() && static_cast<int>(codecs.size()) != views) {
    return Error(ErrorCode::kInvalidArgument, "recorder: " + std::to_string(codecs.size()) +
                                                  " codecs for " + std::to_string(views) +
                                                  " views (one per view, or none for H.264)");
  }
  return Status::Ok();
}

Result<std::unique_ptr<Recorder>> Recorder::create(const RecorderOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  install_av_log();
  std::error_code ec;
  if (std::filesystem::exists(options.dir / "videos", ec) ||
      std::filesystem::exists(options.dir / "calibration.json", ec)) {
    return Error(ErrorCode::kInvalidArgument, options.dir.string() +
                                                  " already holds a recording; pick a new folder "
                                                  "(recordings are never overwritten)");
  }
  if (options.calibration) {
    Result<Calibration> calib = load_calibration(*options.calibration);
    if (!calib) return calib.error();
    if (static_cast<int>(calib->size()) != options.views) {
      return Error(ErrorCode::kInvalidArgument,
                   options.calibration->string() + " has " + std::to_string(calib->size()) +
                       " views, the recording " + std::to_string(options.views) +
                       " cameras: use the calibration of this rig");
    }
  }
  std::filesystem::create_directories(options.dir / "videos", ec);
  if (ec)
    return Error(ErrorCode::kIo, options.dir.string() + "/videos: cannot create: " + ec.message());
  if (options.calibration) {
    std::filesystem::copy_file(*options.calibration, options.dir / "calibration.json", ec);
    if (ec) return Error(ErrorCode::kIo, "copying the calibration: " + ec.message());
  }
  std::unique_ptr<Recorder> r(new Recorder());
  r->options_ = options;
  r->encoders_.resize(static_cast<std::size_t>(options.views));
  r->last_.resize(static_cast<std::size_t>(options.views));
  r->stats_.frames.assign(static_cast<std::size_t>(options.views), 0);
  r->stats_.repeated.assign(static_cast<std::size_t>(options.views), 0);
  r->stats_.encoders.assign(static_cast<std::size_t>(options.views), "");
  return r;
}

Recorder::~Recorder() {
  if (Status s = finish(); !s.ok()) {
    MOCAP_LOG(Recorder, Error) << s.error().message();
  }
}

Status Recorder::write(const FrameSet& set) {
  if (finished_) return Error(ErrorCode::kInvalidArgument, "recorder: write() after finish()");
  if (stats_.sets == 0) first_ts_ns_ = set.timestamp_ns;
  const std::int64_t pts_us = (set.timestamp_ns - first_ts_ns_) / 1000;
  std::vector<const Frame*> by_view(static_cast<std::size_t>(options_.views), nullptr);
  for (const Frame& f : set.frames) {
    if (f.view_id < 0 || f.view_id >= options_.views) {
      return Error(ErrorCode::kInvalidArgument,
                   "recorder: frame of view " + std::to_string(f.view_id) + " in a " +
                       std::to_string(options_.views) + "-view recording");
    }
    by_view[static_cast<std::size_t>(f.view_id)] = &f;
  }
  for (int v = 0; v < options_.views; ++v) {
    const auto vi = static_cast<std::size_t>(v);
    const Frame* f = by_view[vi];
    if (f == nullptr) {
      if (!last_[vi]) {
        return Error(ErrorCode::kInvalidArgument,
                     "recorder: view " + std::to_string(v) +
                         " has no frame yet; start recording once every camera delivers");
      }
      f = &*last_[vi];
      ++stats_.repeated[vi];
    }
    if (!encoders_[vi]) {
      encoders_[vi] = std::make_unique<ViewEncoder>();
      const auto path = options_.dir / "videos" / (std::to_string(v) + ".mp4");
      const VideoCodec codec = options_.codecs.empty() ? VideoCodec::kH264 : options_.codecs[vi];
      if (Status s =
              encoders_[vi]->open(path, *f, options_.frame_rate_hz, codec, &stats_.encoders[vi]);
          !s.ok()) {
        encoders_[vi].reset();  // half-open: nothing to flush
        return s;
      }
      if (v == 0) stats_.codec = stats_.encoders[0];
    }
    if (Status s = encoders_[vi]->encode(*f, pts_us); !s.ok()) return s;
    ++stats_.frames[vi];
    if (by_view[vi] != nullptr) last_[vi] = *by_view[vi];
  }
  ++stats_.sets;
  return Status::Ok();
}

Status Recorder::finish() {
  if (finished_) return Status::Ok();
  finished_ = true;
  last_.clear();  // buffers back to the cameras
  for (auto& e : encoders_) {
    if (e) {
      if (Status s = e->finish(); !s.ok()) return s;
    }
  }
  return Status::Ok();
}

}  // namespace mocap::hal
