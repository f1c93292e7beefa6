#include "runtime/box/problems.h"

#include <algorithm>

namespace mocap::box {

std::string_view to_string(ProblemCode code) {
  switch (code) {
    case ProblemCode::kNoCamera:
      return "no_camera";
    case ProblemCode::kCalibrationMissing:
      return "calibration_missing";
    case ProblemCode::kCalibrationInvalid:
      return "calibration_invalid";
    case ProblemCode::kCalibrationMismatch:
      return "calibration_mismatch";
    case ProblemCode::kRecalibrating:
      return "recalibrating";
    case ProblemCode::kCalibrationNotSaved:
      return "calibration_not_saved";
    case ProblemCode::kCalibrationRefused:
      return "calibration_refused";
    case ProblemCode::kCameraMoved:
      return "camera_moved";
    case ProblemCode::kCropsOff:
      return "crops_off";
    case ProblemCode::kCnnOnCpu:
      return "cnn_on_cpu";
    case ProblemCode::kAccessToken:
      return "access_token";
    case ProblemCode::kPipelineStopped:
      return "pipeline_stopped";
    case ProblemCode::kTake:
      return "take";
    case ProblemCode::kVmc:
      return "vmc";
  }
  return "unknown";
}

void ProblemList::add(Problem problem) {
  std::lock_guard<std::mutex> lock(mu_);
  problems_.push_back(std::move(problem));
}

bool ProblemList::replace(ProblemCode code, Problem problem) {
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = std::find_if(problems_.begin(), problems_.end(),
                               [code](const Problem& p) { return p.code == code; });
  if (it == problems_.end()) return false;
  *it = std::move(problem);
  return true;
}

void ProblemList::remove(std::initializer_list<ProblemCode> codes) {
  std::lock_guard<std::mutex> lock(mu_);
  std::erase_if(problems_, [&codes](const Problem& p) {
    return std::find(codes.begin(), codes.end(), p.code) != codes.end();
  });
}

bool ProblemList::has(ProblemCode code) const {
  std::lock_guard<std::mutex> lock(mu_);
  return std::any_of(problems_.begin(), problems_.end(),
                     [code](const Problem& p) { return p.code == code; });
}

std::vector<Problem> ProblemList::snapshot() const {
  std::lock_guard<std::mutex> lock(mu_);
  return problems_;
}

std::vector<std::string> problem_texts(const std::vector<Problem>& problems) {
  std::vector<std::string> out;
  out.reserve(problems.size());
  for (const Problem& p : problems) out.push_back(p.text);
  return out;
}

}  // namespace mocap::box
