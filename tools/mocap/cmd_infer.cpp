// mocap infer --model NAME|FILE --input-f32 FILE --input-size-px S --dump DIR [--gpu vulkan|cpu]
// mocap infer --model NAME|FILE --image PATH [--input-size-px S] --detections-out FILE [--gpu
// vulkan|cpu] mocap bench cnn --model NAME|FILE --input-size-px S --batch B
#include <unistd.h>
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "runtime/core/stats.h"
#include "runtime/gpu/backend.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/network.h"
#include "runtime/gpu/pose_detector.h"
#include "runtime/image/image.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/movenet.h"
#include "runtime/nn/postprocess.h"
#include "runtime/nn_import/tfjs_import.h"
#include "runtime/skeleton/topology.h"
#include "tools/common/cli.h"
#include "tools/common/paths.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

namespace fs = std::filesystem;

// A .json model is imported from TF.js on the fly; anything else is a project model file.
Result<std::vector<float>> read_f32(const std::string& path, long expected) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) return Error(ErrorCode::kNotFound, path + ": cannot read (" + ec.message() + ")");
  if (static_cast<long>(size) != expected * 4) {
    return Error(ErrorCode::kInvalidArgument,
                 path + ": holds " + std::to_string(size) + " bytes, the input needs " +
                     std::to_string(expected * 4) + " (" + std::to_string(expected) +
                     " float32 values, NHWC)");
  }
  std::vector<float> v(static_cast<std::size_t>(expected));
  std::ifstream f(path, std::ios::binary);
  if (!f.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(size))) {
    return Error(ErrorCode::kIo, path + ": read failed");
  }
  return v;
}

Status write_f32(const fs::path& path, const std::vector<float>& v) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f || !f.write(reinterpret_cast<const char*>(v.data()),
                     static_cast<std::streamsize>(v.size() * sizeof(float)))) {
    return Error(ErrorCode::kIo, path.string() + ": cannot write");
  }
  return Status::Ok();
}

// The network for an input shape; timestamps only for a profiling pass (the detector runs
// without them).
gpu::NetworkOptions network_options(const nn::Shape& s, bool timestamps) {
  gpu::NetworkOptions no;
  no.batch = s.n;
  no.height_px = s.h;
  no.width_px = s.w;
  no.timestamps = timestamps;
  return no;
}

// Runs the model on `input` with the chosen backend; outputs in Model::outputs order.
struct Runner {
  std::string backend;
  std::unique_ptr<gpu::Context> ctx;
  std::unique_ptr<gpu::Network> net;
  const nn::Model* model = nullptr;
  nn::Shape shape;

  Status init(const nn::Model& m, const nn::Shape& s, const std::string& device) {
    model = &m;
    shape = s;
    gpu::GpuOptions go;
    go.device = device;
    auto request = gpu::parse_backend_request(backend);
    if (!request.ok()) return request.error().with_context("--gpu");
    auto b = gpu::choose_backend(*request, go);
    if (!b.ok()) return b.error();
    std::fprintf(stderr, "backend: %s\n", b->description.c_str());
    if (b->backend == gpu::PoseBackend::kCpu) {
      backend = "cpu";
      return Status::Ok();
    }
    backend = "vulkan";
    ctx = std::move(b->context);
    auto n = gpu::Network::create(*ctx, m, network_options(s, /*timestamps=*/false));
    if (!n.ok()) return n.error();
    net = std::move(*n);
    return Status::Ok();
  }

  Status run(const std::vector<float>& input, std::vector<nn::Tensor>* outputs) {
    if (net) {
      if (Status s = net->run(input); !s.ok()) return s;
      if (outputs) {
        outputs->resize(net->output_count());
        for (std::size_t i = 0; i < net->output_count(); ++i) {
          if (Status s = net->read_output(i, (*outputs)[i]); !s.ok()) return s;
        }
      }
      return Status::Ok();
    }
    nn::Tensor in(shape);
    in.data = input;
    auto r = nn::run_model_cpu(*model, in);
    if (!r.ok()) return r.error();
    if (outputs) {
      outputs->clear();
      for (const nn::ModelOutput& o : model->outputs) {
        outputs->push_back(std::move((*r)[static_cast<std::size_t>(o.value)]));
      }
    }
    return Status::Ok();
  }
};

// mocap infer --image: the whole detection path on one photo; writes the detections as JSON
// (docs/detections-format.md) and prints candidates per joint and the limb chains.
int infer_image(const std::string& model_path, const std::string& image_path, int size,
                const std::string& backend, const std::string& device, const std::string& out) {
  if (out.empty()) {
    return cli::fail(Error(ErrorCode::kInvalidArgument, "--image needs --detections-out FILE"));
  }
  if (size < gpu::kMinInputSizePx || size > gpu::kMaxInputSizePx) {
    return cli::fail(Error(ErrorCode::kInvalidArgument,
                           "--size must be in [" + std::to_string(gpu::kMinInputSizePx) + ", " +
                               std::to_string(gpu::kMaxInputSizePx) + "] with --image"));
  }
  auto model = nn::load_model(model_path);
  if (!model.ok()) return cli::fail(model.error());
  auto img = image::load_image(image_path);
  if (!img.ok()) return cli::fail(img.error());
  gpu::PoseDetectorOptions o;
  o.input_size_px = size;
  gpu::GpuOptions go;
  go.device = device;
  auto request = gpu::parse_backend_request(backend);
  if (!request.ok()) return cli::fail(request.error().with_context("--gpu"));
  auto b = gpu::choose_backend(*request, go);
  if (!b.ok()) return cli::fail(b.error());
  std::fprintf(stderr, "backend: %s\n", b->description.c_str());
  o.backend = b->backend;
  const std::string used = b->backend == gpu::PoseBackend::kVulkan ? "vulkan" : "cpu";
  std::unique_ptr<gpu::Context> ctx = std::move(b->context);
  auto det = gpu::PoseDetector::create(*model, o, ctx.get());
  if (!det.ok()) return cli::fail(det.error());
  const nn::FrameView frame{img->rgb, img->width_px, img->height_px, 0, PixelFormat::kRGB24};
  const int view_id = 0;
  auto set = (*det)->detect({&frame, 1}, {&view_id, 1});
  if (!set.ok()) return cli::fail(set.error());
  const SkeletonTopology& topo = *set->topology;
  const ViewDetections& v = set->views[0];
  nlohmann::json j;
  j["format"] = "mocap-detections";
  j["version"] = 1;
  j["topology"] = topo.name();
  j["image"] = image_path;
  j["model"] = model->name;
  j["input_size_px"] = size;
  j["backend"] = used;
  j["score_threshold"] = o.post.score_threshold;
  j["max_candidates_per_joint"] = o.post.max_candidates_per_joint;
  j["affinity_sigma_strides"] = o.post.affinity_sigma_strides;
  j["dropped_candidates"] = (*det)->last_times().dropped_candidates;
  nlohmann::json view;
  view["view_id"] = v.view_id;
  view["width_px"] = v.width_px;
  view["height_px"] = v.height_px;
  nlohmann::json joints = nlohmann::json::array();
  for (int k = 0; k < topo.joint_count(); ++k) {
    nlohmann::json cands = nlohmann::json::array();
    for (const JointCandidate& c : v.candidates[static_cast<std::size_t>(k)]) {
      cands.push_back({c.x_px, c.y_px, c.score});
    }
    joints.push_back({{"name", topo.joint_name(k)}, {"candidates", cands}});
  }
  view["joints"] = joints;
  nlohmann::json limbs = nlohmann::json::array();
  for (int l = 0; l < topo.limb_count(); ++l) {
    const AffinityMatrix& m = v.affinities[static_cast<std::size_t>(l)];
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < m.rows; ++r) {
      nlohmann::json row = nlohmann::json::array();
      for (int c = 0; c < m.cols; ++c) row.push_back(m.at(r, c));
      rows.push_back(row);
    }
    limbs.push_back({{"joint_a", topo.joint_name(topo.limb(l).joint_a)},
                     {"joint_b", topo.joint_name(topo.limb(l).joint_b)},
                     {"affinity", rows}});
  }
  view["limbs"] = limbs;
  j["views"] = nlohmann::json::array({view});
  {
    std::ofstream f(out, std::ios::trunc);
    if (!(f << j.dump(1) << "\n")) return cli::fail(Error(ErrorCode::kIo, out + ": cannot write"));
  }
  const auto& t = (*det)->last_times();
  std::printf("%s: %dx%d px, input %d, %s: pre %.1f ms, network %.1f ms, post %.1f ms\n",
              image_path.c_str(), img->width_px, img->height_px, size, used.c_str(),
              t.preprocess_ms, t.network_ms, t.postprocess_ms);
  int total = 0;
  for (int k = 0; k < topo.joint_count(); ++k) {
    const auto& list = v.candidates[static_cast<std::size_t>(k)];
    total += static_cast<int>(list.size());
    std::printf(
        "  %-11s %2zu candidate%s%s\n", topo.joint_name(k).c_str(), list.size(),
        list.size() == 1 ? "" : "s",
        list.empty() ? "" : (" (best " + std::to_string(list[0].score).substr(0, 4) + ")").c_str());
  }
  const auto chains = nn::limb_chains(v, topo);
  std::printf(
      "candidates=%d dropped=%d limb_chains=%zu (>= 4 joints, mutual-best affinity >= 0.5)\n",
      total, t.dropped_candidates, chains.size());
  std::printf("detections written to %s\n", out.c_str());
  return 0;
}

// A layer name as a file name, as tools/tfjs_ref/posenet_ref.mjs --dump-layers writes it.
std::string sanitise(const std::string& name) {
  std::string out = name;
  for (char& ch : out) {
    const bool keep =
        std::isalnum(static_cast<unsigned char>(ch)) || ch == '.' || ch == '_' || ch == '-';
    if (!keep) ch = '_';
  }
  return out;
}

// --dump-layers / --compare-layers: every layer's output of the run that just finished (the
// Vulkan network's device buffers, or the CPU reference), written as DIR/<sanitised>.f32 and/or
// compared with a TF.js dump of the same input (posenet_ref.mjs --dump-layers): per layer the
// largest |ours - tfjs| relative to the TF.js tensor's largest magnitude.
int layer_debug(Runner& r, const nn::Model& model, const std::vector<float>& input,
                const std::string& dump_dir, const std::string& compare_dir) {
  std::vector<nn::Tensor> values;
  if (r.net) {
    values.resize(r.net->value_count());
    for (std::size_t v = 1; v < values.size(); ++v) {
      if (Status s = r.net->read_value(static_cast<int>(v), values[v]); !s.ok()) {
        return cli::fail(s.error());
      }
    }
  } else {
    nn::Tensor in(r.shape);
    in.data = input;
    auto all = nn::run_model_cpu(model, in, /*keep_all_values=*/true);
    if (!all.ok()) return cli::fail(all.error());
    values = std::move(*all);
  }
  std::error_code ec;
  if (!dump_dir.empty()) fs::create_directories(dump_dir, ec);
  double worst = 0;
  std::string worst_layer;
  int compared = 0;
  if (!compare_dir.empty()) std::printf("%-4s %-66s %12s\n", "#", "layer", "rel_err");
  for (std::size_t li = 0; li < model.layers.size(); ++li) {
    const nn::Tensor& t = values[li + 1];
    const std::string file = sanitise(model.layers[li].name) + ".f32";
    if (!dump_dir.empty()) {
      if (Status s = write_f32(fs::path(dump_dir) / file, t.data); !s.ok())
        return cli::fail(s.error());
    }
    if (compare_dir.empty()) continue;
    const fs::path ref_path = fs::path(compare_dir) / file;
    std::string verdict;
    if (!fs::exists(ref_path)) {
      verdict = "no reference";
    } else if (fs::file_size(ref_path, ec) != t.data.size() * sizeof(float)) {
      verdict = "size differs";
    } else {
      auto ref = read_f32(ref_path.string(), static_cast<long>(t.data.size()));
      if (!ref.ok()) return cli::fail(ref.error());
      double max_ref = 1e-12, max_err = 0;
      for (std::size_t i = 0; i < t.data.size(); ++i) {
        max_ref = std::max(max_ref, static_cast<double>(std::fabs((*ref)[i])));
        max_err = std::max(max_err, static_cast<double>(std::fabs(t.data[i] - (*ref)[i])));
      }
      const double rel = max_err / max_ref;
      ++compared;
      if (rel >= worst) {
        worst = rel;
        worst_layer = model.layers[li].name;
      }
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.3e", rel);
      verdict = buf;
    }
    std::printf("%-4zu %-66s %12s\n", li, model.layers[li].name.c_str(), verdict.c_str());
  }
  if (!dump_dir.empty()) {
    std::printf("%zu layer outputs written to %s\n", model.layers.size(), dump_dir.c_str());
  }
  if (!compare_dir.empty()) {
    if (compared == 0) {
      return cli::fail(Error(ErrorCode::kNotFound,
                             "no layer of the model has a same-sized file in " + compare_dir +
                                 " (make one with: node tools/tfjs_ref/posenet_ref.mjs ... "
                                 "--dump-layers " +
                                 compare_dir + ")"));
    }
    std::printf("layers_compared=%d worst_layer=%s worst_rel_err=%.3e\n", compared,
                worst_layer.c_str(), worst);
  }
  return 0;
}

}  // namespace

int run_infer(Args args) {
  std::string model_path, input_path, image_path, dump_dir, detections_out, dump_layers,
      compare_layers;
  std::string backend = "auto", device;
  int size = 257;
  cli::ArgParser p("mocap infer",
                   "Runs the pose CNN. With --input-f32: on a raw NHWC float32 tensor [1,S,S,C]\n"
                   "(already normalised), writing each output as DIR/<name>.f32 (raw NHWC\n"
                   "float32; PoseNet: heatmap, offsets, displacement_fwd, displacement_bwd).\n"
                   "With --image: the whole detection path (pre-processing, CNN, peaks, limb\n"
                   "affinities) on a JPEG/PNG photo, writing the COCO-17 candidates (image\n"
                   "pixels) and affinity matrices as JSON (docs/detections-format.md).");
  p.option("--model", &model_path, "NAME|FILE",
           "posenet, movenet, thunder, lightning, or a model file (.mcnn) or a TF.js model.json");
  p.option("--input-f32", &input_path, "FILE", "raw float32 NHWC input tensor");
  p.option("--input-size-px", &size, "S", "input height and width (default 257)");
  p.option("--dump", &dump_dir, "DIR", "write the outputs here");
  p.option("--dump-layers", &dump_layers, "DIR",
           "with --input-f32: also write every layer's output as DIR/<layer name>.f32 (names "
           "sanitised as tools/tfjs_ref/posenet_ref.mjs --dump-layers does)");
  p.option("--compare-layers", &compare_layers, "DIR",
           "with --input-f32: compare every layer's output with a TF.js --dump-layers DIR of "
           "the same input and print the relative error per layer");
  p.option("--image", &image_path, "PATH", "photo input (full GPU path with detections)");
  p.option("--detections-out", &detections_out, "FILE", "candidates + affinities (with --image)");
  p.option("--gpu", &backend, "NAME",
           "auto (default: Vulkan, or the CPU backend with a warning when no Vulkan device "
           "can be opened), vulkan or cpu");
  p.option("--gpu-device", &device, "NAME", "Vulkan device index or name substring");
  p.deprecated("--size", "--input-size-px");
  p.deprecated("--backend", "--gpu");
  p.deprecated("--device", "--gpu-device");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (model_path.empty()) return cli::usage_error("--model is required");
  model_path = model_path_for(model_path).string();
  if (!image_path.empty()) {
    return infer_image(model_path, image_path, size, backend, device, detections_out);
  }
  if (input_path.empty() || dump_dir.empty()) {
    return cli::usage_error("--input-f32 FILE and --dump DIR are required");
  }
  if (size < 1 || size > 4096) return cli::usage_error("--input-size-px must be in [1, 4096]");
  auto model = nn::load_model(model_path);
  if (!model.ok()) return cli::fail(model.error());
  const nn::Shape shape{1, size, size, model->input_channels};
  auto input = read_f32(input_path, shape.elements());
  if (!input.ok()) return cli::fail(input.error());
  Runner r{backend, nullptr, nullptr, nullptr, {}};
  if (Status s = r.init(*model, shape, device); !s.ok()) return cli::fail(s.error());
  std::vector<nn::Tensor> outs;
  if (Status s = r.run(*input, &outs); !s.ok()) return cli::fail(s.error());
  std::error_code ec;
  fs::create_directories(dump_dir, ec);
  for (std::size_t i = 0; i < outs.size(); ++i) {
    const fs::path out = fs::path(dump_dir) / (model->outputs[i].name + ".f32");
    if (Status s = write_f32(out, outs[i].data); !s.ok()) return cli::fail(s.error());
    const nn::Shape& s = outs[i].shape;
    std::printf("%s [%d,%d,%d,%d]\n", out.string().c_str(), s.n, s.h, s.w, s.c);
  }
  if (!dump_layers.empty() || !compare_layers.empty()) {
    return layer_debug(r, *model, *input, dump_layers, compare_layers);
  }
  return 0;
}

int run_bench_cnn(Args args) {
  std::string model_path, backend = "vulkan", device;
  std::string tfjs_model;  // default: the model's own (posenet.json or movenet-multipose.json)
  int size = 257, batch = 1, runs = 20, warmup = 3, tfjs_threads = 1;
  bool no_tfjs = false;
  cli::ArgParser p("mocap bench cnn",
                   "Per-frame time of the pose CNN: median (and p90) of --runs runs after\n"
                   "--warmup, wall clock per submission (input upload to outputs read back, as\n"
                   "the detector runs it) divided by the batch; then the GPU time of every layer\n"
                   "(timestamps, median) from a separate profiling pass. When Node and\n"
                   "tools/tfjs_ref are installed, runs the TF.js wasm reference on the same input\n"
                   "in the same run and ends with vulkan_over_tfjs_wasm=R.RR (< 1: faster).");
  p.option("--model", &model_path, "NAME|FILE",
           "posenet, movenet, thunder, lightning, or a model file (.mcnn) or a TF.js model.json");
  p.option("--input-size-px", &size, "S", "input height and width (default 257)");
  p.option("--batch", &batch, "B", "views per submission (default 1)");
  p.option("--runs", &runs, "N", "timed runs (default 20, at least 20)");
  p.option("--warmup", &warmup, "N", "untimed runs first (default 3)");
  p.option("--gpu", &backend, "NAME", "vulkan (default) or cpu");
  p.option("--gpu-device", &device, "NAME", "Vulkan device index or name substring");
  p.deprecated("--size", "--input-size-px");
  p.deprecated("--backend", "--gpu");
  p.deprecated("--device", "--gpu-device");
  p.option("--tfjs-model", &tfjs_model, "FILE",
           "TF.js model.json for the reference (default models/posenet.json, or "
           "models/movenet-multipose.json for a MoveNet model)");
  p.option("--tfjs-threads", &tfjs_threads, "N", "TF.js wasm threads (default 1)");
  p.flag("--no-tfjs", &no_tfjs, "skip the TF.js reference");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (model_path.empty()) return cli::usage_error("--model is required");
  model_path = model_path_for(model_path).string();
  const char* bad = runs < 20                 ? "--runs must be >= 20"
                    : warmup < 0              ? "--warmup must be >= 0"
                    : batch < 1 || batch > 64 ? "--batch must be in [1, 64]"
                    : size < 1 || size > 4096 ? "--input-size-px must be in [1, 4096]"
                                              : nullptr;
  if (bad != nullptr) return cli::usage_error(bad);
  auto model = nn::load_model(model_path);
  if (!model.ok()) return cli::fail(model.error());
  const nn::Shape shape{batch, size, size, model->input_channels};
  std::vector<float> input(static_cast<std::size_t>(shape.elements()));
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (float& v : input) v = u(rng);
  Runner r{backend, nullptr, nullptr, nullptr, {}};
  if (Status s = r.init(*model, shape, device); !s.ok()) return cli::fail(s.error());
  const char* threads = std::getenv("LP_NUM_THREADS");
  std::printf("cnn: %s, input %dx%d, batch %d, backend %s%s%s\n", model->name.c_str(), size, size,
              batch, backend.c_str(), r.ctx ? (" on " + r.ctx->device_info().name).c_str() : "",
              threads ? (std::string(", LP_NUM_THREADS=") + threads).c_str() : "");
  for (int i = 0; i < warmup; ++i) {
    if (Status s = r.run(input, nullptr); !s.ok()) return cli::fail(s.error());
  }
  // Timed runs as the detector runs the network: no timestamps, outputs read back to the host
  // (as the TF.js reference does with data()).
  std::vector<double> wall_ms;
  std::vector<nn::Tensor> outputs;
  for (int i = 0; i < runs; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    if (Status s = r.run(input, &outputs); !s.ok()) return cli::fail(s.error());
    wall_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  // Per-layer GPU times from a separate profiling pass with a timestamp after every layer
  // (timestamps cost lavapipe ~1 ms per frame at 257, so they stay out of the timed runs).
  if (r.net) {
    auto prof = gpu::Network::create(*r.ctx, *model, network_options(shape, /*timestamps=*/true));
    if (!prof.ok()) return cli::fail(prof.error());
    std::vector<double> gpu_ms;
    std::vector<std::vector<double>> layer_ms((*prof)->layer_times().size());
    for (int i = 0; i < warmup + runs; ++i) {
      if (Status s = (*prof)->run(input); !s.ok()) return cli::fail(s.error());
      if (i < warmup || (*prof)->gpu_ms() <= 0) continue;
      gpu_ms.push_back((*prof)->gpu_ms());
      for (std::size_t l = 0; l < layer_ms.size(); ++l) {
        layer_ms[l].push_back((*prof)->layer_times()[l].ms);
      }
    }
    if (!gpu_ms.empty()) {
      std::printf("profiling pass (timestamp after every layer), median of %d:\n", runs);
      std::printf("%-4s %-62s %-18s %9s\n", "#", "layer", "kernel", "gpu ms");
      for (std::size_t l = 0; l < layer_ms.size(); ++l) {
        std::printf("%-4zu %-62s %-18s %9.3f\n", l, (*prof)->layer_times()[l].name.c_str(),
                    (*prof)->layer_times()[l].kernel.c_str(), median(layer_ms[l]));
      }
      std::printf("gpu_total_ms=%.3f (median, whole command buffer, profiling pass)\n",
                  median(gpu_ms));
    }
  }
  const double med = median(wall_ms) / batch;
  std::printf(
      "ms_per_frame=%.3f (median of %d, p90 %.3f; wall clock per submission incl. input upload "
      "and output read-back / batch, no timestamps)\n",
      med, runs, percentile(wall_ms, 0.9) / batch);
  // Achieved throughput: 2 FLOPs per multiply-add of the network at this input.
  if (auto macs = model->multiply_adds({1, size, size, model->input_channels}); macs.ok()) {
    std::printf("gflop_per_s=%.2f (%.3f GMAC per frame)\n", 2 * *macs / (med * 1e6), *macs * 1e-9);
  }

  if (no_tfjs || batch != 1) {
    if (!no_tfjs) std::printf("tfjs reference: only at --batch 1\n");
    return 0;
  }
  const bool movenet = nn::is_movenet(*model);
  if (tfjs_model.empty()) {
    tfjs_model = std::string(MOCAP_SOURCE_DIR) +
                 (movenet ? "/models/movenet-multipose.json" : "/models/posenet.json");
  }
  const fs::path script = fs::path(MOCAP_SOURCE_DIR) / (movenet ? "tools/tfjs_ref/movenet_ref.mjs"
                                                                : "tools/tfjs_ref/posenet_ref.mjs");
  const fs::path modules = fs::path(MOCAP_SOURCE_DIR) / "tools/tfjs_ref/node_modules";
  if (!fs::exists(script) || !fs::exists(modules) || !fs::exists(tfjs_model) ||
      std::system("command -v node >/dev/null 2>&1") != 0) {
    std::printf(
        "tfjs reference: not installed (node, tools/tfjs_ref/node_modules and %s are "
        "needed; tools/setup.sh installs them)\n",
        tfjs_model.c_str());
    return 0;
  }
  const fs::path tmp =
      fs::temp_directory_path() / ("mocap-bench-cnn-" + std::to_string(::getpid()));
  std::error_code ec;
  fs::create_directories(tmp, ec);
  if (Status s = write_f32(tmp / "input.f32", input); !s.ok()) return cli::fail(s.error());
  const std::string cmd =
      "node '" + script.string() + "' --model '" + tfjs_model + "' --input-f32 '" +
      (tmp / "input.f32").string() + "' --size " + std::to_string(size) + " --out '" +
      (tmp / "out").string() + "' --backend wasm --threads " + std::to_string(tfjs_threads) +
      " --bench " + std::to_string(runs) + " --warmup " + std::to_string(warmup) + " 2>/dev/null";
  std::FILE* pipe = popen(cmd.c_str(), "r");
  std::string out;
  if (pipe) {
    char buf[512];
    while (std::fgets(buf, sizeof buf, pipe)) out += buf;
    pclose(pipe);
  }
  fs::remove_all(tmp, ec);
  const auto pos = out.find("\"median_ms\":");
  if (pos == std::string::npos) {
    std::printf("tfjs reference: failed to run (%s)\n", cmd.c_str());
    return 1;
  }
  const double tfjs_ms = std::atof(out.c_str() + pos + 12);
  std::printf("tfjs_wasm_ms_per_frame=%.3f (%d thread%s, median of %d)\n", tfjs_ms, tfjs_threads,
              tfjs_threads == 1 ? "" : "s", runs);
  std::printf("vulkan_over_tfjs_wasm=%.2f\n", tfjs_ms > 0 ? med / tfjs_ms : 0.0);
  return 0;
}

}  // namespace mocap::tools
