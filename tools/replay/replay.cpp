#include "tools/replay/replay.h"

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>

#include "hal/replay/recording.h"
#include "hal/replay/video_decoder.h"
#include "runtime/geometry/calibration.h"
#include "runtime/gpu/backend.h"
#include "runtime/gpu/pose_detector.h"
#include "runtime/nn/tfjs_import.h"
#include "runtime/skeleton/topology.h"

namespace mocap::replay {
namespace {

namespace fs = std::filesystem;
inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

struct ReplaySession::Impl {
  std::vector<std::unique_ptr<hal::VideoDecoder>> decoders;
  std::vector<hal::VideoFrame> frames;
  std::vector<int> view_ids;
  gpu::BackendChoice backend;
  std::unique_ptr<gpu::PoseDetector> detector;
  std::unique_ptr<assoc::Engine> engine;
};

ReplaySession::~ReplaySession() = default;

Result<std::unique_ptr<ReplaySession>> ReplaySession::open(const ReplayOptions& options) {
  if (options.input_size_px < 17 || options.input_size_px > 1025) {
    return Error(ErrorCode::kInvalidArgument, "network input size must be in [17, 1025], got " +
                                                  std::to_string(options.input_size_px));
  }
  auto rec = hal::open_recording(options.data_dir);
  if (!rec.ok()) return rec.error();
  const Calibration* calib = &rec->calibration;

  std::unique_ptr<ReplaySession> s(new ReplaySession());
  s->options_ = options;
  s->cameras_ = calib->cameras;
  s->impl_ = std::make_unique<Impl>();
  Impl& m = *s->impl_;
  const int V = static_cast<int>(calib->size());
  for (int v = 0; v < V; ++v) {
    const fs::path& p = rec->videos[ix(v)];
    auto d = hal::VideoDecoder::open(p);
    if (!d.ok()) return d.error();
    const hal::VideoInfo& info = (*d)->info();
    const Camera& cam = s->cameras_[ix(v)];
    if (info.width_px != cam.width_px() || info.height_px != cam.height_px()) {
      return Error(ErrorCode::kInvalidArgument,
                   p.string() + ": frames are " + std::to_string(info.width_px) + "x" +
                       std::to_string(info.height_px) + " but calibration.json view \"" +
                       std::to_string(v) + "\" has imgSize " + std::to_string(cam.width_px()) +
                       "x" + std::to_string(cam.height_px()));
    }
    s->frame_count_ = v == 0 ? info.frame_count : std::min(s->frame_count_, info.frame_count);
    m.decoders.push_back(std::move(*d));
    m.view_ids.push_back(v);
  }
  m.frames.resize(ix(V));

  Result<nn::Model> model = nn::load_model(options.model);
  if (!model.ok()) return model.error();
  gpu::GpuOptions go;
  go.device = options.device;
  go.validation = options.vulkan_validation;
  auto b = gpu::choose_backend(options.backend, go);
  if (!b.ok()) return b.error();
  m.backend = std::move(*b);
  s->backend_description_ = m.backend.description;
  gpu::PoseDetectorOptions po;
  po.backend = m.backend.backend;
  po.input_size_px = options.input_size_px;
  po.max_views = V;
  auto det = gpu::PoseDetector::create(*model, po, m.backend.context.get());
  if (!det.ok()) return det.error();
  m.detector = std::move(*det);
  auto eng = assoc::Engine::create(coco17_topology(), s->cameras_, options.assoc);
  if (!eng.ok()) return eng.error();
  m.engine = std::move(*eng);
  return s;
}

Result<bool> ReplaySession::next(ReplayFrame& out) {
  Impl& m = *impl_;
  if (options_.max_frames >= 0 && next_frame_ >= static_cast<std::uint64_t>(options_.max_frames)) {
    return false;
  }
  const int V = view_count();
  auto t0 = std::chrono::steady_clock::now();
  int ended = 0;
  for (int v = 0; v < V; ++v) {
    auto more = m.decoders[ix(v)]->next(m.frames[ix(v)]);
    if (!more.ok()) return more.error();
    if (!*more) ++ended;
  }
  if (ended == V) return false;
  if (ended > 0) {
    std::string which;
    for (int v = 0; v < V; ++v) {
      which += " view " + std::to_string(v) + ": " +
               std::to_string(m.decoders[ix(v)]->frames_decoded()) + " frames;";
    }
    return Error(ErrorCode::kInvalidArgument, "frame " + std::to_string(next_frame_) +
                                                  ": the videos end at different frames (" + which +
                                                  " they must be synchronised)");
  }
  out.decode_ms = ms_since(t0);
  out.frame_id = next_frame_;
  out.timestamp_ns = m.frames[0].timestamp_ns;

  std::vector<nn::FrameView> views(ix(V));
  for (int v = 0; v < V; ++v) {
    const hal::VideoFrame& f = m.frames[ix(v)];
    views[ix(v)] =
        nn::FrameView{f.rgb, f.width_px, f.height_px, f.stride_bytes, PixelFormat::kRGB24};
  }
  t0 = std::chrono::steady_clock::now();
  auto det = m.detector->detect(views, m.view_ids, out.frame_id, out.timestamp_ns);
  if (!det.ok()) return det.error().with_context("frame " + std::to_string(out.frame_id));
  out.detect_ms = ms_since(t0);
  out.detections = std::move(*det);

  t0 = std::chrono::steady_clock::now();
  auto res = m.engine->process(out.detections);
  if (!res.ok()) return res.error();
  out.associate_ms = ms_since(t0);
  out.result = std::move(*res);
  ++next_frame_;
  return true;
}

void reprojection_errors(const ReplayFrame& frame, const std::vector<Camera>& cameras,
                         std::vector<ReprojectionSample>& out) {
  const SkeletonSet& sk = frame.result.skeletons;
  const int V = static_cast<int>(cameras.size());
  for (std::size_t p = 0; p < sk.persons.size() && p < frame.result.evidence.size(); ++p) {
    const PersonSkeleton& person = sk.persons[p];
    const assoc::PersonEvidence& ev = frame.result.evidence[p];
    const int J = static_cast<int>(person.joints_m.size());
    for (int j = 0; j < J; ++j) {
      for (int v = 0; v < V; ++v) {
        const std::size_t slot = ix(j * V + v);
        if (slot >= ev.candidate.size() || ev.candidate[slot] < 0) continue;
        // The DetectionSet view with this view id.
        const ViewDetections* view = nullptr;
        for (const ViewDetections& d : frame.detections.views) {
          if (d.view_id == v) view = &d;
        }
        if (view == nullptr) continue;
        const auto& list = view->candidates[ix(j)];
        const int k = ev.candidate[slot];
        if (k >= static_cast<int>(list.size())) continue;
        const auto px = cameras[ix(v)].project(person.joints_m[ix(j)]);
        if (!px) continue;
        out.push_back(
            ReprojectionSample{person.person_id, j, v,
                               (*px - Eigen::Vector2d(list[ix(k)].x_px, list[ix(k)].y_px)).norm()});
      }
    }
  }
}

Eigen::Vector3d person_center(const PersonSkeleton& person, float min_confidence) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (std::size_t j = 0; j < person.joints_m.size(); ++j) {
    if (j < person.confidence.size() && person.confidence[j] >= min_confidence) {
      sum += person.joints_m[j];
      ++n;
    }
  }
  if (n == 0) {
    for (const Eigen::Vector3d& x : person.joints_m) sum += x;
    n = static_cast<int>(person.joints_m.size());
  }
  return n > 0 ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Zero();
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double pos = std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(pos);
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

void ReplayStats::add(const ReplayFrame& frame) {
  const int f = s_.frames++;
  ++s_.frames_with_result;
  s_.decode_ms.push_back(frame.decode_ms);
  s_.detect_ms.push_back(frame.detect_ms);
  s_.associate_ms.push_back(frame.associate_ms);
  const auto& persons = frame.result.skeletons.persons;
  ++s_.persons_histogram[static_cast<int>(persons.size())];
  for (const PersonSkeleton& p : persons) {
    const Eigen::Vector3d c = person_center(p);
    auto [it, fresh] = s_.tracks.try_emplace(p.person_id);
    TrackSummary& t = it->second;
    if (fresh) {
      t.id = p.person_id;
      t.first_frame = f;
      t.first_center_m = c;
      t.mean_center_m = Eigen::Vector3d::Zero();
    }
    t.last_frame = f;
    t.last_center_m = c;
    t.mean_center_m += c;
    ++t.frames;
  }
  reprojection_errors(frame, cameras_, s_.reprojection);
}

std::vector<double> ReplaySummary::reprojection_px() const {
  std::vector<double> v;
  v.reserve(reprojection.size());
  for (const ReprojectionSample& r : reprojection) v.push_back(r.error_px);
  return v;
}

const ReplaySummary& ReplayStats::finish() {
  for (auto& [id, t] : s_.tracks) {
    if (t.frames > 0) t.mean_center_m /= t.frames;
  }
  s_.id_switches.clear();
  for (const auto& [a_id, a] : s_.tracks) {
    if (a.frames < kLongTrackFrames || a.last_frame >= s_.frames - 1) continue;  // ran to the end
    for (const auto& [b_id, b] : s_.tracks) {
      if (b_id == a_id || b.first_frame <= a.first_frame) continue;
      const int gap = b.first_frame - a.last_frame;
      if (gap < -kSwitchMaxGapFrames || gap > kSwitchMaxGapFrames) continue;
      const double d = (b.first_center_m - a.last_center_m).norm();
      if (d > kSwitchMaxDistM) continue;
      s_.id_switches.push_back(IdSwitch{a_id, b_id, b.first_frame, d});
    }
  }
  return s_;
}

}  // namespace mocap::replay
