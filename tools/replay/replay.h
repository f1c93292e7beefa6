// Replay of a recorded multi-view capture through the whole pipeline: N synchronised videos
// (hal::VideoDecoder) -> gpu::PoseDetector (all views of a frame in one batch, COCO-17) ->
// assoc::Engine (COCO-17 topology, 4D association, tracking, skeleton fit) -> skeletons; plus
// the statistics `mocap replay` prints and the e2e test asserts (tracks, id switches,
// reprojection error of the 3D joints against the 2D candidates the engine used).
//
// A recording folder holds calibration.json (runtime/geometry/calibration.h) and
// videos/<view>.mp4 with view = 0..N-1, the calibration's view ids; frame n of every video is
// the same instant.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/assoc/options.h"
#include "runtime/core/error.h"
#include "runtime/geometry/camera.h"
#include "runtime/msg/messages.h"

namespace mocap::replay {

// Network input size `mocap replay` uses unless told otherwise. Measured on pose2sim_multi
// (1088x1920 portrait, people 500-1000 px tall): 353 tracks the two people on the treadmill as
// well as 513 (all frames, one id each) at half the time per frame, with a higher
// reprojection error (median 18 vs 14 px); `mocap replay --help` has the figures.
inline constexpr int kDefaultInputSizePx = 353;

struct ReplayOptions {
  std::filesystem::path data_dir;  // calibration.json + videos/
  std::filesystem::path model;     // PoseNet model file (.mcnn) or TF.js model.json
  int input_size_px = kDefaultInputSizePx;
  int max_frames = -1;           // < 0: the whole recording
  std::string backend = "auto";  // vulkan | cpu | auto (gpu::choose_backend)
  std::string device;            // Vulkan device index or name substring
  bool vulkan_validation = false;
  assoc::AssociationOptions assoc = assoc::posenet_coco17_options();
};

struct ReplayFrame {
  std::uint64_t frame_id = 0;
  std::int64_t timestamp_ns = 0;
  DetectionSet detections;
  assoc::FrameResult result;
  double decode_ms = 0;     // all views
  double detect_ms = 0;     // PoseDetector::detect (pre-processing, network, post-processing)
  double associate_ms = 0;  // Engine::process (association, tracking, fitting)
};

class ReplaySession {
 public:
  // Opens the calibration, the videos (view ids checked against the calibration, sizes against
  // imgSize), the model, the detector and the engine. Errors name the file and what is wrong.
  static Result<std::unique_ptr<ReplaySession>> open(const ReplayOptions& options);
  ~ReplaySession();

  // Decodes, detects and associates the next frame. false: the end of the recording (or
  // max_frames reached); an error names the frame and the view.
  Result<bool> next(ReplayFrame& out);

  int view_count() const { return static_cast<int>(cameras_.size()); }
  const std::vector<Camera>& cameras() const { return cameras_; }
  std::int64_t frame_count() const { return frame_count_; }  // as the videos announce it
  const std::string& backend_description() const { return backend_description_; }
  int input_size_px() const { return options_.input_size_px; }

 private:
  struct Impl;
  ReplaySession() = default;

  ReplayOptions options_;
  std::vector<Camera> cameras_;
  std::int64_t frame_count_ = 0;
  std::string backend_description_;
  std::unique_ptr<Impl> impl_;
  std::uint64_t next_frame_ = 0;
};

struct ReprojectionSample {
  int person_id = -1;
  int joint = -1;
  int view = -1;
  double error_px = 0;
};

// Reprojection error (pixels) of each 3D joint the engine output against each 2D candidate it
// used for that joint (PersonEvidence), in every view; appended to `out`.
void reprojection_errors(const ReplayFrame& frame, const std::vector<Camera>& cameras,
                         std::vector<ReprojectionSample>& out);

struct TrackSummary {
  int id = -1;
  int first_frame = -1;
  int last_frame = -1;
  int frames = 0;                  // frames the id was output
  Eigen::Vector3d first_center_m;  // mean of the confident joints, first and last frame
  Eigen::Vector3d last_center_m;
  Eigen::Vector3d mean_center_m;  // over all its frames
};

// A track that ends (while the recording goes on) and a track that starts within
// kSwitchMaxGapFrames frames after it, where the new one's first centre is within
// kSwitchMaxDistM of the old one's last centre: the same person under a new id.
struct IdSwitch {
  int from_id = -1;
  int to_id = -1;
  int frame = -1;  // first frame of to_id
  double distance_m = 0;
};
inline constexpr int kSwitchMaxGapFrames = 15;
inline constexpr double kSwitchMaxDistM = 0.5;
// Tracks shorter than this are not "long" (a flicker of a few frames is not a switch source).
inline constexpr int kLongTrackFrames = 10;

struct ReplaySummary {
  int frames = 0;
  int frames_with_result = 0;
  std::vector<double> decode_ms, detect_ms, associate_ms;  // per frame
  std::map<int, int> persons_histogram;                    // persons in a frame -> frames
  std::map<int, TrackSummary> tracks;                      // by id
  std::vector<IdSwitch> id_switches;                       // among long tracks
  std::vector<ReprojectionSample> reprojection;            // all (person, joint, view) evidence
  std::vector<double> reprojection_px() const;             // the errors alone
};

// Accumulates frames into a ReplaySummary.
class ReplayStats {
 public:
  explicit ReplayStats(std::vector<Camera> cameras) : cameras_(std::move(cameras)) {}
  void add(const ReplayFrame& frame);
  // Completes the track and id-switch analysis; call once after the last add().
  const ReplaySummary& finish();
  const ReplaySummary& summary() const { return s_; }

 private:
  std::vector<Camera> cameras_;
  ReplaySummary s_;
  std::map<int, int> center_count_;
};

// Mean of a person's joints with confidence >= min_confidence (all joints when none).
Eigen::Vector3d person_center(const PersonSkeleton& person, float min_confidence = 0.2f);

double median(std::vector<double> v);
double percentile(std::vector<double> v, double q);  // q in [0, 1]

}  // namespace mocap::replay
