#include "runtime/calib/background.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <utility>

#include "runtime/core/log.h"

MOCAP_LOG_CATEGORY(Calib);

namespace mocap::calib {

namespace fs = std::filesystem;

Status BackgroundCalibratorOptions::validate() const {
  if (Status s = solve.validate(); !s.ok()) return s;
  if (Status s = people.validate(); !s.ok()) return s;
  if (first_attempt_frames < 30 || first_attempt_frames > 100000 || retry_frames < 1 ||
      max_frames < first_attempt_frames) {
    return Error(ErrorCode::kInvalidArgument,
                 "background calibration: first_attempt_frames must be in [30, 100000], "
                 "retry_frames >= 1 and max_frames >= first_attempt_frames");
  }
  return {};
}

BackgroundCalibrator::BackgroundCalibrator(const SkeletonTopology& topology,
                                           std::vector<int> view_ids,
                                           std::vector<CameraPrior> priors,
                                           const BackgroundCalibratorOptions& options)
    : topology_(&topology),
      view_ids_(std::move(view_ids)),
      priors_(std::move(priors)),
      options_(options),
      keypoints_(std::make_unique<KeypointCollector>(topology, view_ids_, options.people)),
      next_attempt_frames_(options.first_attempt_frames) {}

BackgroundCalibrator::~BackgroundCalibrator() { wait(); }

void BackgroundCalibrator::wait() {
  if (thread_.joinable()) thread_.join();
}

void BackgroundCalibrator::add(const DetectionSet& set) {
  std::lock_guard<std::mutex> lock(mu_);
  if (done_) return;
  if (keypoints_->frame_count() >= options_.max_frames && !solving_) {
    keypoints_ = std::make_unique<KeypointCollector>(*topology_, view_ids_, options_.people);
    next_attempt_frames_ = options_.first_attempt_frames;
  }
  keypoints_->add(set);
  if (solving_ || keypoints_->frame_count() < next_attempt_frames_) return;
  std::vector<CameraPrior> priors = priors_;
  for (std::size_t v = 0; v < priors.size(); ++v) {
    if (priors[v].width_px <= 0) priors[v].width_px = keypoints_->width_px(static_cast<int>(v));
    if (priors[v].height_px <= 0) priors[v].height_px = keypoints_->height_px(static_cast<int>(v));
  }
  solving_ = true;
  next_attempt_frames_ = keypoints_->frame_count() + options_.retry_frames;
  if (thread_.joinable()) thread_.join();  // the previous solve has finished (solving_ was false)
  thread_ = std::thread(&BackgroundCalibrator::solve, this, *keypoints_, std::move(priors));
}

void BackgroundCalibrator::solve(KeypointCollector snapshot, std::vector<CameraPrior> priors) {
  auto r = self_calibrate(snapshot, priors, options_.solve);
  std::lock_guard<std::mutex> lock(mu_);
  ++attempts_;
  solving_ = false;
  if (!r.ok()) {
    last_refusal_ = r.error().message();
  } else if (!r->calibration) {
    last_refusal_ = r->quality.refusal;
  } else {
    done_ = true;
    last_refusal_.clear();
    result_ = std::move(*r);
    return;
  }
  MOCAP_LOG(Calib, Info) << "self-calibration attempt " << attempts_ << " ("
                         << snapshot.frame_count() << " frames): " << last_refusal_;
}

std::optional<SelfCalibrationResult> BackgroundCalibrator::take_result() {
  std::lock_guard<std::mutex> lock(mu_);
  return std::exchange(result_, std::nullopt);
}

std::string BackgroundCalibrator::hint_locked() const {
  for (std::size_t v = 0; v < view_ids_.size(); ++v) {
    if (keypoints_->frames_with_people(static_cast<int>(v)) == 0) {
      return "walk through the area seen by camera " + std::to_string(view_ids_[v]);
    }
  }
  if (!last_refusal_.empty()) return last_refusal_;
  return "walk around the whole area (about a minute; several people are fine)";
}

CalibrationProgress BackgroundCalibrator::progress() const {
  std::lock_guard<std::mutex> lock(mu_);
  CalibrationProgress p;
  p.state = done_ ? "done" : solving_ ? "solving" : "collecting";
  p.frames = keypoints_->frame_count();
  for (std::size_t v = 0; v < view_ids_.size(); ++v) {
    p.view_ids.push_back(std::to_string(view_ids_[v]));
    p.frames_with_people.push_back(keypoints_->frames_with_people(static_cast<int>(v)));
  }
  p.attempts = attempts_;
  p.last_refusal = last_refusal_;
  p.hint = done_ ? "" : hint_locked();
  return p;
}

namespace {

Error io_error(const fs::path& path, const std::string& what) {
  return Error(ErrorCode::kIo, path.string() + ": " + what + ": " + std::strerror(errno) +
                                   " (make the folder writable, or give mocapd another "
                                   "state_dir)");
}

}  // namespace

Status write_calibration_durably(const Calibration& calibration, const fs::path& path) {
  auto text = calibration_to_json(calibration);
  if (!text.ok()) return text.error();
  const fs::path tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return io_error(tmp, "cannot create");
  std::size_t done = 0;
  while (done < text->size()) {
    const ssize_t n = ::write(fd, text->data() + done, text->size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const Error e = io_error(tmp, "cannot write");
      ::close(fd);
      ::unlink(tmp.c_str());
      return e;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const Error e = io_error(tmp, "cannot flush");
    ::close(fd);
    ::unlink(tmp.c_str());
    return e;
  }
  ::close(fd);
  std::error_code ec;
  if (fs::exists(path, ec)) {
    fs::copy_file(path, path.string() + ".bak", fs::copy_options::overwrite_existing, ec);
    if (ec) {
      ::unlink(tmp.c_str());
      return Error(ErrorCode::kIo,
                   path.string() + ".bak: cannot keep the previous calibration: " + ec.message());
    }
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const Error e = io_error(path, "cannot replace");
    ::unlink(tmp.c_str());
    return e;
  }
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  return {};
}

}  // namespace mocap::calib
