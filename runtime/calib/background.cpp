#include "runtime/calib/background.h"

#include <filesystem>
#include <utility>

#include "runtime/calib/compare.h"
#include "runtime/core/atomic_file.h"
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
  if (refine_until_frames < 0 || refine_until_frames > 1000000 || !(converged_rotation_deg >= 0) ||
      !(converged_center_m >= 0)) {
    return Error(ErrorCode::kInvalidArgument,
                 "background calibration: refine_until_frames must be in [0, 1000000] and the "
                 "convergence limits >= 0");
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

BackgroundCalibrator::~BackgroundCalibrator() {
  cancel_.store(true);
  wait();
}

void BackgroundCalibrator::wait() {
  if (thread_.joinable()) thread_.join();
}

void BackgroundCalibrator::add(const DetectionSet& set) {
  std::lock_guard<std::mutex> lock(mu_);
  if (done_) return;
  if (!refining_ && keypoints_->frame_count() >= options_.max_frames && !solving_) {
    keypoints_ = std::make_unique<KeypointCollector>(*topology_, view_ids_, options_.people);
    next_attempt_frames_ = options_.first_attempt_frames;
  }
  // Refining stops collecting at its cap; the last solve still starts once the one before ends.
  if (!refining_ || keypoints_->frame_count() < options_.refine_until_frames) keypoints_->add(set);
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
  SelfCalibrationOptions o = options_.solve;
  o.hypotheses.cancel = &cancel_;
  auto r = self_calibrate(snapshot, priors, o);
  // How far a refined result moved the cameras (outside the lock: a comparison is quick, but
  // progress() must not wait for it).
  double change_deg = -1, change_m = -1;
  std::optional<Calibration> previous;
  {
    std::lock_guard<std::mutex> lock(mu_);
    previous = last_;
  }
  if (previous && r.ok() && r->calibration) {
    if (auto c = compare_calibrations(*previous, *r->calibration); c.ok()) {
      change_deg = c->max_rotation_deg;
      change_m = c->median_center_m;
    }
  }
  std::lock_guard<std::mutex> lock(mu_);
  ++attempts_;
  solving_ = false;
  const int frames = snapshot.frame_count();
  const bool last_chance = frames >= options_.refine_until_frames;
  if (!r.ok()) {
    last_refusal_ = r.error().message();
  } else if (!r->calibration) {
    last_refusal_ = r->quality.refusal;
  } else {
    last_refusal_.clear();
    if (refining_) {
      last_change_deg_ = change_deg;
      last_change_m_ = change_m;
      const bool converged = change_deg >= 0 && change_deg <= options_.converged_rotation_deg &&
                             change_m <= options_.converged_center_m;
      if (converged) {
        done_ = true;
        MOCAP_LOG(Calib, Info) << "self-calibration converged at " << frames << " frames (moved "
                               << change_deg << " deg, " << change_m << " m)";
        return;
      }
      ++refinements_;
    }
    last_ = *r->calibration;
    result_ = std::move(*r);
    refining_ = !last_chance && options_.refine_until_frames > frames;
    done_ = !refining_;
    next_attempt_frames_ = std::min(2 * frames, options_.refine_until_frames);
    return;
  }
  if (refining_) {  // a refusal while refining: the last result stands; once more, or done
    done_ = last_chance;
    next_attempt_frames_ = std::min(2 * frames, options_.refine_until_frames);
    return;
  }
  MOCAP_LOG(Calib, Info) << "self-calibration attempt " << attempts_ << " ("
                         << snapshot.frame_count() << " frames): " << last_refusal_;
}

bool BackgroundCalibrator::refining() const {
  std::lock_guard<std::mutex> lock(mu_);
  return refining_ && !done_;
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
  p.state = done_ ? "done" : refining_ ? "refining" : solving_ ? "solving" : "collecting";
  p.frames = keypoints_->frame_count();
  for (std::size_t v = 0; v < view_ids_.size(); ++v) {
    p.view_ids.push_back(std::to_string(view_ids_[v]));
    p.frames_with_people.push_back(keypoints_->frames_with_people(static_cast<int>(v)));
  }
  p.attempts = attempts_;
  p.last_refusal = last_refusal_;
  p.refinements = refinements_;
  p.last_change_deg = last_change_deg_;
  p.last_change_m = last_change_m_;
  p.solving = solving_;
  p.next_solve_frames = done_ ? 0 : next_attempt_frames_;
  p.hint = done_       ? ""
           : refining_ ? "calibrated; keep walking around the whole area: the calibration is "
                         "solved again with more frames while that still moves the cameras"
                       : hint_locked();
  return p;
}

Status write_calibration_durably(const Calibration& calibration, const fs::path& path) {
  auto text = calibration_to_json(calibration);
  if (!text.ok()) return text.error();
  std::error_code ec;
  if (fs::exists(path, ec)) {
    fs::copy_file(path, path.string() + ".bak", fs::copy_options::overwrite_existing, ec);
    if (ec) {
      return Error(ErrorCode::kIo,
                   path.string() + ".bak: cannot keep the previous calibration: " + ec.message());
    }
  }
  if (Status s = write_file_atomically(path, *text, Durability::kDurable); !s.ok()) {
    return Error(ErrorCode::kIo, s.error().message() +
                                     " (make the folder writable, or write it elsewhere: "
                                     "mocapd's state_dir, the command's --out)");
  }
  return {};
}

}  // namespace mocap::calib
