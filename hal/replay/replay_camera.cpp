#include "hal/replay/replay_camera.h"

#include <chrono>
#include <thread>
#include <utility>
#include <vector>

#include "hal/replay/video_decoder.h"

namespace mocap::hal {

Status ReplayCameraOptions::validate() const {
  if (video.empty()) {
    return Error(ErrorCode::kInvalidArgument, "ReplayCameraOptions.video is empty");
  }
  if (view_id < 0) return Error(ErrorCode::kInvalidArgument, "ReplayCameraOptions.view_id < 0");
  if (epoch_ns < 0) return Error(ErrorCode::kInvalidArgument, "ReplayCameraOptions.epoch_ns < 0");
  return Status::Ok();
}

ReplayCamera::~ReplayCamera() = default;

Result<std::unique_ptr<ReplayCamera>> ReplayCamera::open(const ReplayCameraOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  auto dec = VideoDecoder::open(options.video);
  if (!dec.ok()) return dec.error();
  std::unique_ptr<ReplayCamera> cam(new ReplayCamera());
  cam->options_ = options;
  const VideoInfo& info = (*dec)->info();
  cam->mode_ = CameraMode{PixelFormat::kRGB24, info.width_px, info.height_px, info.frame_rate_hz};
  cam->description_ =
      CameraDescription{options.video.string(),
                        "replay of " + options.video.filename().string() + " (" + info.codec + ")",
                        "replay",
                        {cam->mode_}};
  cam->frame_count_ = info.frame_count;
  cam->codec_ = info.codec;
  cam->decoder_ = std::move(*dec);
  return cam;
}

Status ReplayCamera::start() { return start_at(options_.epoch_ns); }

Status ReplayCamera::start_at(std::int64_t epoch_ns) {
  if (started_) return Status::Ok();
  if (!decoder_) {
    return Error(ErrorCode::kInvalidArgument,
                 options_.video.string() + ": replay camera was stopped; open it again");
  }
  started_ = true;
  start_ns_ = epoch_ns > 0 ? epoch_ns : monotonic_ns();
  return Status::Ok();
}

void ReplayCamera::stop() {
  started_ = false;
  have_pending_ = false;
  decoder_.reset();  // a recording is not rewound: open it again to replay
}

Result<Capture> ReplayCamera::next(int timeout_ms) {
  Capture c;
  if (!started_) {
    return Error(ErrorCode::kInvalidArgument, options_.video.string() + ": next() before start()");
  }
  if (!have_pending_) {
    VideoFrame vf;
    auto more = decoder_->next(vf);
    if (!more.ok()) return more.error();
    if (!*more) {
      c.status = CaptureStatus::kEnded;
      return c;
    }
    pending_ = Frame{};
    pending_.view_id = options_.view_id;
    pending_.sequence = static_cast<std::uint64_t>(vf.index);
    pending_.timestamp_ns = start_ns_ + vf.timestamp_ns;
    pending_.width_px = vf.width_px;
    pending_.height_px = vf.height_px;
    pending_.stride_bytes = vf.stride_bytes;
    pending_.format = PixelFormat::kRGB24;
    pending_.buffer = std::make_shared<OwnedFrameBuffer>(std::move(vf.rgb));
    have_pending_ = true;
  }
  if (options_.paced) {
    const std::int64_t wait_ns = pending_.timestamp_ns - monotonic_ns();
    if (wait_ns > 0) {
      const std::int64_t limit_ns = static_cast<std::int64_t>(timeout_ms) * 1'000'000;
      if (wait_ns > limit_ns) {
        std::this_thread::sleep_for(std::chrono::nanoseconds(limit_ns));
        return c;  // kTimeout: the frame is not due yet
      }
      std::this_thread::sleep_for(std::chrono::nanoseconds(wait_ns));
    }
  }
  have_pending_ = false;
  c.status = CaptureStatus::kFrame;
  c.frame = std::move(pending_);
  return c;
}

}  // namespace mocap::hal
