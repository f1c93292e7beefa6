#include "runtime/boardcal/board_capture.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "runtime/boardcal/board_steps.h"
#include "runtime/core/stats.h"
#include "runtime/image/image.h"

namespace mocap::boardcal {

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

double round_to(double v, double step) { return std::round(v / step) * step; }

// Grid cells where the board has been seen.
int covered_cells(const std::vector<int>& grid) {
  return static_cast<int>(std::count_if(grid.begin(), grid.end(), [](int n) { return n > 0; }));
}

// The luma of an RGB pixel (BT.601 weights, integer).
std::uint8_t luma(std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  return static_cast<std::uint8_t>((77 * r + 150 * g + 29 * b) >> 8);
}

}  // namespace

struct BoardCapture::Image {
  int width_px = 0;
  int height_px = 0;
  std::vector<std::uint8_t> gray;   // width x height, row-major
  std::vector<std::uint8_t> mjpeg;  // compressed: decoded by the worker
};

namespace {

// One frame's luma plane (or its MJPEG bytes); nullopt when the buffer is too small for its
// declared size and layout (a broken frame is skipped, not read past its end).
template <typename Image>
std::optional<Image> copy_luma(const Frame& f) {
  if (!f.buffer || f.width_px <= 0 || f.height_px <= 0) return std::nullopt;
  const auto bytes = f.buffer->bytes();
  Image img;
  img.width_px = f.width_px;
  img.height_px = f.height_px;
  if (f.format == PixelFormat::kMJPEG) {
    img.mjpeg.assign(bytes.begin(), bytes.end());
    return img;
  }
  const int bpp = f.format == PixelFormat::kRGB24 ? 3 : f.format == PixelFormat::kYUYV ? 2 : 1;
  const auto w = static_cast<std::size_t>(f.width_px);
  const auto h = static_cast<std::size_t>(f.height_px);
  const std::size_t stride = f.stride_bytes > 0 ? static_cast<std::size_t>(f.stride_bytes)
                                                : w * static_cast<std::size_t>(bpp);
  if (stride < w * static_cast<std::size_t>(bpp) ||
      bytes.size() < stride * (h - 1) + w * static_cast<std::size_t>(bpp)) {
    return std::nullopt;
  }
  img.gray.resize(w * h);
  for (std::size_t y = 0; y < h; ++y) {
    const std::uint8_t* row = bytes.data() + y * stride;
    std::uint8_t* out = img.gray.data() + y * w;
    if (bpp == 1) {
      std::copy_n(row, w, out);
    } else if (bpp == 2) {
      for (std::size_t x = 0; x < w; ++x) out[x] = row[2 * x];
    } else {
      for (std::size_t x = 0; x < w; ++x) out[x] = luma(row[3 * x], row[3 * x + 1], row[3 * x + 2]);
    }
  }
  return img;
}

}  // namespace

const char* to_string(CapturePhase phase) {
  switch (phase) {
    case CapturePhase::kCollecting:
      return "collecting";
    case CapturePhase::kSolving:
      return "solving";
    case CapturePhase::kSolved:
      return "solved";
    case CapturePhase::kFailed:
      return "failed";
    case CapturePhase::kCancelled:
      return "cancelled";
  }
  return "?";
}

Status BoardCaptureOptions::validate() const {
  auto bad = [](std::string m) { return Error(ErrorCode::kInvalidArgument, std::move(m)); };
  if (!(sample_interval_s > 0 && sample_interval_s <= 10)) {
    return bad("board sample interval " + std::to_string(sample_interval_s) +
               " s is outside (0, 10]");
  }
  if (max_samples < 10 || max_samples > 5000) {
    return bad("max_samples " + std::to_string(max_samples) + " is outside [10, 5000]");
  }
  if (floor_samples < 0 || floor_samples >= max_samples) {
    return bad("floor_samples " + std::to_string(floor_samples) + " is outside [0, max_samples)");
  }
  return calibration.validate();
}

Result<std::unique_ptr<BoardCapture>> BoardCapture::create(const BoardSpec& board,
                                                           std::vector<std::string> view_ids,
                                                           const BoardCaptureOptions& options) {
  if (Status s = board.validate(); !s.ok()) return s.error();
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (view_ids.size() < 2) {
    return Error(ErrorCode::kInvalidArgument, "a board calibration needs at least 2 cameras, " +
                                                  std::to_string(view_ids.size()) + " given");
  }
  auto det = BoardDetector::create(board);
  if (!det.ok()) return det.error();
  return std::unique_ptr<BoardCapture>(
      new BoardCapture(board, std::move(*det), std::move(view_ids), options));
}

BoardCapture::BoardCapture(const BoardSpec& board, BoardDetector detector,
                           std::vector<std::string> view_ids, const BoardCaptureOptions& options)
    : board_(board), detector_(std::move(detector)), options_(options) {
  const std::size_t n = view_ids.size();
  for (std::string& id : view_ids) {
    CameraState c;
    c.view_id = id;
    CameraFrames cf;
    cf.view_id = std::move(id);
    frames_.push_back(std::move(cf));
    c.grid.assign(static_cast<std::size_t>(options_.calibration.grid_cols) *
                      static_cast<std::size_t>(options_.calibration.grid_rows),
                  0);
    cameras_.push_back(std::move(c));
  }
  pair_frames_.assign(n, std::vector<int>(n, 0));
  worker_ = std::thread([this] { run(); });
}

BoardCapture::~BoardCapture() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  wake_.notify_all();
  worker_.join();
}

void BoardCapture::observe(const FrameSet& frames, std::int64_t now_ns) {
  {
    std::lock_guard lock(mu_);
    if (phase_ != CapturePhase::kCollecting || busy_ || pending_) return;
    if (static_cast<int>(samples_) >= options_.max_samples) return;
    if (last_sample_ns_ != 0 &&
        now_ns - last_sample_ns_ < static_cast<std::int64_t>(options_.sample_interval_s * 1e9)) {
      return;
    }
    last_sample_ns_ = now_ns;
  }
  std::vector<Image> images(cameras_.size());
  bool any = false;
  for (const Frame& f : frames.frames) {
    if (f.view_id < 0 || static_cast<std::size_t>(f.view_id) >= images.size()) continue;
    if (auto img = copy_luma<Image>(f)) {
      images[static_cast<std::size_t>(f.view_id)] = std::move(*img);
      any = true;
    }
  }
  if (!any) return;
  {
    std::lock_guard lock(mu_);
    pending_ = std::move(images);
    pending_frame_id_ = frames.frame_id;
  }
  wake_.notify_one();
}

void BoardCapture::run() {
  std::unique_lock lock(mu_);
  for (;;) {
    wake_.wait(lock, [this] { return stopping_ || pending_ || solve_requested_; });
    if (stopping_) return;
    busy_ = true;
    if (solve_requested_) {
      solve_requested_ = false;
      pending_.reset();
      lock.unlock();
      run_solve();
    } else {
      std::vector<Image> images = std::move(*pending_);
      pending_.reset();
      const std::uint64_t frame_id = pending_frame_id_;
      lock.unlock();
      detect_sample(images, frame_id);
    }
    lock.lock();
    busy_ = false;
    idle_.notify_all();
  }
}

// Without mu_: detection takes tens of milliseconds per image; the results go in under it.
void BoardCapture::detect_sample(std::vector<Image>& images, std::uint64_t frame_id) {
  const auto t0 = Clock::now();
  std::vector<BoardObservation> obs(images.size());
  std::vector<std::pair<int, int>> sizes(images.size(), {0, 0});
  for (std::size_t c = 0; c < images.size(); ++c) {
    Image& img = images[c];
    if (!img.mjpeg.empty()) {
      auto rgb = image::decode_image(img.mjpeg, "camera " + cameras_[c].view_id + " MJPEG frame");
      if (!rgb.ok()) continue;
      img.width_px = rgb->width_px;
      img.height_px = rgb->height_px;
      img.gray.resize(static_cast<std::size_t>(rgb->width_px) *
                      static_cast<std::size_t>(rgb->height_px));
      for (std::size_t i = 0; i < img.gray.size(); ++i) {
        img.gray[i] = luma(rgb->rgb[3 * i], rgb->rgb[3 * i + 1], rgb->rgb[3 * i + 2]);
      }
    }
    if (img.gray.empty()) continue;
    sizes[c] = {img.width_px, img.height_px};
    obs[c] = detector_.detect({img.gray.data(), img.width_px, img.height_px, img.width_px});
  }
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  std::lock_guard lock(mu_);
  ++sampled_;
  detect_ms_.push_back(ms);
  if (detect_ms_.size() > 64) detect_ms_.erase(detect_ms_.begin());
  if (phase_ != CapturePhase::kCollecting) return;  // cancelled or solving meanwhile
  const int cols = options_.calibration.grid_cols;
  const int rows = options_.calibration.grid_rows;
  bool seen = false;
  for (std::size_t c = 0; c < obs.size(); ++c) {
    CameraState& cam = cameras_[c];
    if (sizes[c].first > 0) {
      cam.width_px = sizes[c].first;
      cam.height_px = sizes[c].second;
    }
    cam.last_frame_id = frame_id;
    cam.last = obs[c];
    if (obs[c].size() < 4) continue;
    seen = true;
    ++cam.frames_seen;
    for (const Eigen::Vector2d& p : obs[c].px) {
      const int gx =
          std::clamp(static_cast<int>(p.x() * cols / std::max(1, cam.width_px)), 0, cols - 1);
      const int gy =
          std::clamp(static_cast<int>(p.y() * rows / std::max(1, cam.height_px)), 0, rows - 1);
      ++cam.grid[static_cast<std::size_t>(gy * cols + gx)];
    }
  }
  if (!seen) return;
  const auto min_corners = static_cast<std::size_t>(options_.calibration.min_corners);
  for (std::size_t a = 0; a < obs.size(); ++a) {
    for (std::size_t b = a + 1; b < obs.size(); ++b) {
      if (obs[a].size() >= min_corners && obs[b].size() >= min_corners) ++pair_frames_[a][b];
    }
  }
  ++samples_;
  // The views the solve will take (distinct, adding coverage): a camera shown the board many
  // times at one place is not ready (CI: "ready" at 5 usable frames, the solve found 4 distinct).
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    CameraFrames& cf = frames_[c];
    cf.frames.push_back(std::move(obs[c]));
    cf.width_px = cameras_[c].width_px;
    cf.height_px = cameras_[c].height_px;
    cameras_[c].usable_views =
        cf.width_px > 0 && cf.height_px > 0
            ? static_cast<int>(detail::choose_frames(cf, board_, options_.calibration).size())
            : 0;
  }
}

Status BoardCapture::solve() {
  std::lock_guard lock(mu_);
  if (phase_ != CapturePhase::kCollecting) {
    return Error(ErrorCode::kInvalidArgument, std::string("the board calibration is ") +
                                                  to_string(phase_) +
                                                  ", not collecting: start a new one");
  }
  bool pair = false;
  for (std::size_t a = 0; a < cameras_.size(); ++a) {
    for (std::size_t b = a + 1; b < cameras_.size(); ++b) pair = pair || pair_frames_[a][b] > 0;
  }
  if (!pair) {
    return Error(ErrorCode::kInvalidArgument,
                 "no two cameras have seen the board at the same moment yet (" +
                     std::to_string(samples_) +
                     " frames with the board): hold it where two cameras see it, then Solve");
  }
  phase_ = CapturePhase::kSolving;
  solve_requested_ = true;
  wake_.notify_one();
  return {};
}

void BoardCapture::cancel() {
  std::lock_guard lock(mu_);
  phase_ = CapturePhase::kCancelled;
  solve_requested_ = false;
  pending_.reset();
}

void BoardCapture::wait_idle() {
  std::unique_lock lock(mu_);
  idle_.wait(lock, [this] { return stopping_ || (!busy_ && !pending_ && !solve_requested_); });
}

std::vector<CameraFrames> BoardCapture::frames_for_solve() const {
  std::vector<CameraFrames> out = frames_;
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    out[c].width_px = cameras_[c].width_px;
    out[c].height_px = cameras_[c].height_px;
  }
  return out;
}

void BoardCapture::run_solve() {
  std::vector<CameraFrames> frames;
  BoardCalibrationOptions o = options_.calibration;
  {
    std::lock_guard lock(mu_);
    frames = frames_for_solve();
    o.floor_frames = std::min(options_.floor_samples, static_cast<int>(samples_));
  }
  const auto t0 = Clock::now();
  auto r = calibrate_board(board_, frames, o);
  const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
  std::lock_guard lock(mu_);
  solve_s_ = secs;
  if (phase_ == CapturePhase::kCancelled) return;
  if (r.ok()) {
    result_ = std::move(*r);
    phase_ = CapturePhase::kSolved;
  } else {
    error_ = r.error().message();
    phase_ = CapturePhase::kFailed;
  }
}

CapturePhase BoardCapture::phase() const {
  std::lock_guard lock(mu_);
  return phase_;
}

std::optional<BoardCalibrationResult> BoardCapture::result() const {
  std::lock_guard lock(mu_);
  if (phase_ != CapturePhase::kSolved) return std::nullopt;
  return result_;
}

std::string BoardCapture::what_to_do() const {
  switch (phase_) {
    case CapturePhase::kSolving:
      return "solving in the background (the stream goes on)";
    case CapturePhase::kSolved:
      return "check each camera's residual, then Save (or Discard)";
    case CapturePhase::kFailed:
      return "fix what the error says and start again";
    case CapturePhase::kCancelled:
      return "discarded: start again to calibrate";
    case CapturePhase::kCollecting:
      break;
  }
  const BoardCalibrationOptions& o = options_.calibration;
  const int cells = o.grid_cols * o.grid_rows;
  for (const CameraState& c : cameras_) {
    const int covered = covered_cells(c.grid);
    if (c.usable_views < o.min_frames) {
      return "show the board to camera " + c.view_id + ", whole and closer (" +
             std::to_string(c.usable_views) + " of " + std::to_string(o.min_frames) +
             " usable views so far)";
    }
    if (covered < o.warn_coverage * cells) {
      return "camera " + c.view_id + " has seen the board in " + std::to_string(covered) + " of " +
             std::to_string(cells) +
             " parts of its image: show it near the edges and corners, tilted";
    }
  }
  return "every camera is covered: keep moving the board through the volume where two cameras "
         "see it at once, then Solve";
}

json BoardCapture::status_json() const {
  std::lock_guard lock(mu_);
  const BoardCalibrationOptions& o = options_.calibration;
  json j;
  j["phase"] = to_string(phase_);
  j["board"] = board_.to_spec();
  j["samples"] = samples_;
  j["sampled"] = sampled_;
  j["max_samples"] = options_.max_samples;
  j["floor_samples"] = options_.floor_samples;
  j["detect_ms_median"] = round_to(sample_median(detect_ms_), 0.1);
  json cams = json::array();
  const int cells = o.grid_cols * o.grid_rows;
  for (const CameraState& c : cameras_) {
    const int covered = covered_cells(c.grid);
    const double coverage = cells > 0 ? static_cast<double>(covered) / cells : 0;
    json px = json::array();
    for (const Eigen::Vector2d& p : c.last.px)
      px.push_back({round_to(p.x(), 0.1), round_to(p.y(), 0.1)});
    cams.push_back({{"view_id", c.view_id},
                    {"width_px", c.width_px},
                    {"height_px", c.height_px},
                    {"frames_seen", c.frames_seen},
                    {"usable_views", c.usable_views},
                    {"coverage", round_to(coverage, 0.001)},
                    {"grid", {{"cols", o.grid_cols}, {"rows", o.grid_rows}, {"corners", c.grid}}},
                    {"ready", c.usable_views >= o.min_frames && coverage >= o.min_coverage},
                    {"last", {{"frame_id", c.last_frame_id}, {"corners_px", px}}}});
  }
  j["cameras"] = cams;
  json pairs = json::array();
  for (std::size_t a = 0; a < cameras_.size(); ++a) {
    for (std::size_t b = a + 1; b < cameras_.size(); ++b) {
      pairs.push_back(
          {{"a", cameras_[a].view_id}, {"b", cameras_[b].view_id}, {"frames", pair_frames_[a][b]}});
    }
  }
  j["pairs"] = pairs;
  j["what_to_do"] = what_to_do();
  if (phase_ == CapturePhase::kSolved || phase_ == CapturePhase::kFailed) {
    j["solve_s"] = round_to(solve_s_, 0.01);
  }
  if (phase_ == CapturePhase::kSolved && result_) {
    j["result"] = json::parse(board_report_json(*result_), nullptr, false);
  }
  if (phase_ == CapturePhase::kFailed) j["error"] = error_;
  return j;
}

}  // namespace mocap::boardcal
