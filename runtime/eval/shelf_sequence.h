// Runs the association engine over the Shelf sequence (detections + calibration from the data
// folder) and collects what the evaluator and the benchmark need: the Shelf-15 estimates per
// frame and per-frame timings.
#pragma once

#include <filesystem>
#include <optional>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/assoc/options.h"
#include "runtime/core/error.h"
#include "runtime/eval/shelf_mapping.h"
#include "runtime/eval/shelf_pcp.h"
#include "runtime/geometry/calibration.h"
#include "runtime/io/shelf_gt.h"

namespace mocap {

struct ShelfRunOptions {
  std::vector<int> views;  // empty = all views of the calibration
  assoc::AssociationOptions association;
  Shelf15MappingOptions mapping;
  int repeat = 1;  // run the sequence this many times (benchmarks; tracks reset in between)
  // Cameras to use instead of <data>/calibration.json (already in Shelf's world frame).
  std::optional<Calibration> calibration;
};

struct ShelfFrameTiming {
  double association_ms = 0;  // graph + parsing + assembling
  double fitting_ms = 0;      // reconstruction: triangulation, tracking, (fitting)
};

struct ShelfRun {
  std::vector<ShelfEstimateFrame> estimates;  // per frame (last repetition)
  std::vector<ShelfFrameTiming> timings;      // per frame and repetition
  std::vector<assoc::FrameStats> stats;       // per frame (last repetition)
  int views_used = 0;
  std::vector<double> rss_mb_after_repetition;  // resident memory after each repetition
};

// Loads <data>/calibration.json (or uses options.calibration) and <data>/detection/<v>.txt and runs
// the engine on body19.
Result<ShelfRun> run_shelf_sequence(const std::filesystem::path& data_dir,
                                    const ShelfRunOptions& options);

}  // namespace mocap
