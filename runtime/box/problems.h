// What is degraded in the box and how to fix it, typed: a code a program can act on, the
// camera(s) it concerns, the sentence /health shows and the fix on its own. Problems are kept
// in the order they arose (the page lists them so).
#pragma once

#include <initializer_list>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace mocap::box {

enum class ProblemCode {
  kNoCamera,             // no camera found: the simulator streams
  kCalibrationMissing,   // cameras without a calibration (2D detections, or calibrating)
  kCalibrationInvalid,   // a calibration file that cannot be read
  kCalibrationMismatch,  // a calibration of other cameras (count or frame size)
  kRecalibrating,        // a recalibration on request runs beside the current calibration
  kCalibrationNotSaved,  // a calibration in use that could not be written to the state folder
  kCalibrationRefused,   // a calibration the engine cannot run on
  kCameraMoved,          // the continuous check: a camera's residuals grew
  kCropsOff,             // 3D-guided crops asked for but not possible
  kCnnOnCpu,             // the CNN fell back to the CPU
  kAccessToken,          // the access token could not be kept in the state folder
  kPipelineStopped,      // the pipeline failed
  kTake,                 // a take stopped or cannot be written
  kVmc,                  // a VMC receiver cannot be reached
};
std::string_view to_string(ProblemCode code);  // "no_camera", "calibration_missing", ...

struct Problem {
  ProblemCode code = ProblemCode::kNoCamera;
  std::string camera;  // the camera id(s) it concerns ("0,1"); empty = the box
  std::string text;    // the whole sentence, fix included (what /health lists)
  std::string fix;     // what to do, on its own (empty when the text says it)
};

// Thread-safe: the daemon's setup, the HTTP thread and the association thread add and remove.
class ProblemList {
 public:
  void add(Problem problem);
  // The first problem with `code` replaced in place (its position kept); false when none.
  bool replace(ProblemCode code, Problem problem);
  void remove(std::initializer_list<ProblemCode> codes);
  bool has(ProblemCode code) const;
  std::vector<Problem> snapshot() const;

 private:
  mutable std::mutex mu_;
  std::vector<Problem> problems_;
};

// The sentences, in order (what /health's "problems" lists).
std::vector<std::string> problem_texts(const std::vector<Problem>& problems);

}  // namespace mocap::box
