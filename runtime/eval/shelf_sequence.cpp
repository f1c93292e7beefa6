#include "runtime/eval/shelf_sequence.h"

#include <algorithm>
#include <string>
#include <utility>

#include "runtime/assoc/adapt.h"
#include "runtime/core/memory.h"
#include "runtime/geometry/calibration.h"
#include "runtime/io/shelf_detections.h"
#include "runtime/skeleton/topology.h"

namespace mocap {

Result<ShelfRun> run_shelf_sequence(const std::filesystem::path& data_dir,
                                    const ShelfRunOptions& options) {
  Result<Calibration> calib = options.calibration ? Result<Calibration>(*options.calibration)
                                                  : load_calibration(data_dir / "calibration.json");
  if (!calib.ok()) return calib.error();
  const int n_cams = static_cast<int>(calib->cameras.size());
  for (std::size_t i = 0; i < calib->view_ids.size(); ++i) {
    if (calib->view_ids[i] != std::to_string(i)) {
      return Error(ErrorCode::kParse, (data_dir / "calibration.json").string() +
                                          ": Shelf views must be keyed \"0\"..\"" +
                                          std::to_string(n_cams - 1) + "\"");
    }
  }
  std::vector<int> views = options.views;
  if (views.empty()) {
    for (int v = 0; v < n_cams; ++v) views.push_back(v);
  }
  std::vector<std::pair<int, int>> sizes;
  for (int v : views) {
    if (v < 0 || v >= n_cams) {
      return Error(ErrorCode::kInvalidArgument,
                   "view " + std::to_string(v) + " is not in the calibration (" +
                       std::to_string(n_cams) + " views: 0.." + std::to_string(n_cams - 1) + ")");
    }
    const Camera& c = calib->cameras[static_cast<std::size_t>(v)];
    sizes.emplace_back(c.width_px(), c.height_px());
  }
  {
    std::vector<int> sorted = views;
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
      return Error(ErrorCode::kInvalidArgument, "a view is listed twice");
    }
  }
  auto detections = load_shelf_detections(data_dir / "detection", views, sizes);
  if (!detections.ok()) return detections.error();

  auto engine = assoc::Engine::create(body19_topology(), calib->cameras, options.association);
  if (!engine.ok()) return engine.error();

  ShelfRun run;
  run.views_used = static_cast<int>(views.size());
  DetectionSet body19;
  const assoc::AffinityAdaptOptions adapt;
  for (int rep = 0; rep < std::max(1, options.repeat); ++rep) {
    (*engine)->reset();
    const bool last = rep + 1 >= std::max(1, options.repeat);
    if (last) {
      run.estimates.clear();
      run.stats.clear();
    }
    for (const DetectionSet& d : *detections) {
      if (Status s = assoc::remap_detections(d, body25_to_body19(), adapt, body19); !s.ok()) {
        return s.error();
      }
      auto r = (*engine)->process(body19);
      if (!r.ok()) return r.error();
      const assoc::FrameStats& st = r->stats;
      run.timings.push_back(
          ShelfFrameTiming{st.graph_ms + st.parse_ms + st.assemble_ms, st.reconstruct_ms});
      if (!last) continue;
      auto est = shelf15_estimates_from_skeletons(r->skeletons, options.mapping);
      if (!est.ok()) return est.error();
      run.estimates.push_back(std::move(*est));
      run.stats.push_back(st);
    }
    run.rss_mb_after_repetition.push_back(static_cast<double>(current_rss_bytes()) / (1 << 20));
  }
  return run;
}

}  // namespace mocap
