// mocap model convert|info: turn a TF.js graph model into a model file and inspect model
// files (runtime/nn/model_file.h, docs/model-format.md).
#include <cinttypes>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/atomic_file.h"
#include "runtime/nn/model.h"
#include "runtime/nn/model_file.h"
#include "runtime/nn/movenet.h"
#include "runtime/nn_import/blazepose_cut.h"
#include "runtime/nn_import/movenet_cuts.h"
#include "runtime/nn_import/tfjs_import.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

constexpr int kDefaultInputSize_px = 257;  // PoseNet's usual input (output stride 16 -> 17x17)
constexpr int kMaxInputSize_px = 16384;

constexpr const char* kUsage =
    "usage: mocap model <convert|info> ...   (mocap model <convert|info> --help for details)\n"
    "\n"
    "subcommands:\n"
    "  convert  import a TF.js graph model (model.json + weights) and write a model file\n"
    "  info     print a model file's layers, output shapes and parameter counts\n";

std::string with_commas(long long n) {
  constexpr std::size_t kGroup = 3;
  const std::string digits = std::to_string(n < 0 ? -n : n);
  std::string out = n < 0 ? "-" : "";
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % kGroup == 0) out += ',';
    out += digits[i];
  }
  return out;
}

std::string shape_text(const nn::Shape& s) {
  std::string out = std::to_string(s.h);
  out += 'x';
  out += std::to_string(s.w);
  out += 'x';
  out += std::to_string(s.c);
  return out;
}

long tensor_elements(const nn::Model& m, int index) {
  return index >= 0 ? m.tensors[static_cast<std::size_t>(index)].elements() : 0;
}

std::string window_text(const nn::Layer& l) {
  std::string s;
  switch (l.op) {
    case nn::OpType::kConv2D:
    case nn::OpType::kDepthwiseConv2D:
    case nn::OpType::kMaxPool:
      s += std::to_string(l.kernel_h);
      s += 'x';
      s += std::to_string(l.kernel_w);
      s += '/';
      s += std::to_string(l.stride_h);
      if (l.stride_w != l.stride_h) {
        s += 'x';
        s += std::to_string(l.stride_w);
      }
      s += l.padding == nn::Padding::kSame ? " same" : " valid";
      if (l.has_explicit_pad()) {
        s += " +pad " + std::to_string(l.pad_top) + "," + std::to_string(l.pad_bottom) + "," +
             std::to_string(l.pad_left) + "," + std::to_string(l.pad_right);
      }
      return s;
    case nn::OpType::kResizeBilinear:
    case nn::OpType::kResizeNearest:
      s += 'x';
      s += std::to_string(l.resize_factor);
      return s;
    case nn::OpType::kAdd:
    case nn::OpType::kConcat:
    case nn::OpType::kActivation:
      break;
  }
  return "-";
}

// The layer table and outputs, with shapes for a size_px x size_px input.
void print_model(const nn::Model& m, int size_px) {
  const nn::Shape input{1, size_px, size_px, m.input_channels};
  Result<std::vector<nn::Shape>> shapes = m.infer_shapes(input);
  std::printf("model '%s': input %s, %zu layers, %s parameters\n", m.name.c_str(),
              shape_text(input).c_str(), m.layers.size(), with_commas(m.parameter_count()).c_str());
  if (!shapes.ok()) {
    std::printf("note: no output shapes for a %dx%d input: %s\n", size_px, size_px,
                shapes.error().message().c_str());
  }
  std::printf("  %3s  %-16s  %-13s  %-7s  %-12s  %9s  %s\n", "#", "op", "kernel/stride", "act",
              "output", "params", "name");
  for (std::size_t i = 0; i < m.layers.size(); ++i) {
    const nn::Layer& l = m.layers[i];
    const long params =
        tensor_elements(m, l.weights) + tensor_elements(m, l.bias) + tensor_elements(m, l.alpha);
    const std::string out = shapes.ok() ? shape_text((*shapes)[i + 1]) : "?";
    std::printf("  %3zu  %-16s  %-13s  %-7s  %-12s  %9s  %s\n", i, nn::to_string(l.op),
                window_text(l).c_str(), nn::to_string(l.activation), out.c_str(),
                with_commas(params).c_str(), l.name.c_str());
  }
  std::printf("outputs:\n");
  for (const nn::ModelOutput& o : m.outputs) {
    const std::string out =
        shapes.ok() ? shape_text((*shapes)[static_cast<std::size_t>(o.value)]) : "?";
    std::printf("  %-18s  layer %-3d  %s\n", o.name.c_str(), o.value - 1, out.c_str());
  }
}

// --cut NAME: where to cut a known graph ("" = the whole graph).
Result<nn::TfjsImportOptions> cut_options(const std::string& name) {
  if (name.empty()) return nn::TfjsImportOptions{};
  if (name == "movenet-multipose") return nn::movenet_multipose_cut();
  if (name == "movenet-singlepose") return nn::movenet_singlepose_cut();
  if (name == "blazepose") return nn::blazepose_landmarks_cut();
  return Error(
      ErrorCode::kInvalidArgument,
      "--cut '" + name + "' is unknown (known: movenet-multipose, movenet-singlepose, blazepose)");
}

Status check_size(int size_px) {
  if (size_px < 1 || size_px > kMaxInputSize_px) {
    return Error(ErrorCode::kInvalidArgument, "--input-size-px must be in [1, " +
                                                  std::to_string(kMaxInputSize_px) + "], got " +
                                                  std::to_string(size_px));
  }
  return Status::Ok();
}

int run_convert(Args args) {
  std::string tfjs;
  std::string out;
  std::string cut;
  int size_px = kDefaultInputSize_px;
  cli::ArgParser parser(
      "mocap model convert",
      "Import a TF.js graph model (model.json; its weight files are found relative to it) and "
      "write it as a model file (docs/model-format.md). Prints the layers, the parameter "
      "count, the output names, the file size and its CRC-32.");
  parser.option("--tfjs", &tfjs, "MODEL_JSON", "TF.js graph model to import (required)");
  parser.option("--out", &out, "FILE", "model file to write, e.g. models/posenet.mcnn (required)");
  parser.option("--input-size-px", &size_px, "S",
                "input size in pixels for the printed output shapes (default " +
                    std::to_string(kDefaultInputSize_px) + ")");
  parser.deprecated("--size", "--input-size-px");
  parser.option("--cut", &cut, "NAME",
                "import a known graph cut at its heads: movenet-multipose (MoveNet MultiPose "
                "from the normalised image to its four heads, runtime/nn/movenet.h) or "
                "movenet-singlepose (MoveNet Thunder or Lightning, the same four heads) or "
                "blazepose (BlazePose lite or full: landmarks, person flag and heatmaps, "
                "without the segmentation)");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (tfjs.empty() || out.empty()) {
    return cli::usage_error("--tfjs and --out are required (see mocap model convert --help)");
  }
  if (Status s = check_size(size_px); !s.ok()) {
    return cli::usage_error(s.error().message());
  }

  Result<nn::TfjsImportOptions> import_options = cut_options(cut);
  if (!import_options.ok()) {
    return cli::usage_error(import_options.error().message());
  }
  Result<nn::Model> model = nn::import_tfjs(tfjs, *import_options);
  if (!model.ok()) {
    return cli::fail(model.error().message());
  }
  std::printf("imported %s\n", tfjs.c_str());
  print_model(*model, size_px);
  const std::vector<std::uint8_t> bytes = nn::serialize_model(*model);
  if (Status s = write_file_atomically(
          out, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
          Durability::kDurable);
      !s.ok()) {
    return cli::fail(s.error().message());
  }
  std::printf("wrote %s: %s bytes, format version %" PRIu32 ", CRC-32 0x%08" PRIx32 "\n",
              out.c_str(), with_commas(static_cast<long long>(bytes.size())).c_str(),
              nn::kModelFormatVersion, nn::stored_checksum(bytes));
  return 0;
}

int run_info(Args args) {
  std::string file;
  int size_px = kDefaultInputSize_px;
  cli::ArgParser parser("mocap model info",
                        "Check a model file and print its layer table: index, op, kernel/stride "
                        "and padding (or resize factor), activation, output shape for an SxS "
                        "input, parameter count and name; then the outputs.");
  parser.positional("FILE", &file, "model file (.mcnn)");
  parser.option("--input-size-px", &size_px, "S",
                "input size in pixels for the output shapes (default " +
                    std::to_string(kDefaultInputSize_px) + ")");
  parser.deprecated("--size", "--input-size-px");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (Status s = check_size(size_px); !s.ok()) {
    return cli::usage_error(s.error().message());
  }
  Result<std::vector<std::uint8_t>> bytes = nn::read_file_bytes(file);
  if (!bytes.ok()) {
    return cli::fail(bytes.error().message());
  }
  Result<nn::Model> model = nn::parse_model_bytes(*bytes, file);
  if (!model.ok()) {
    return cli::fail(model.error().message());
  }
  std::printf("%s: %s bytes, format version %" PRIu32 ", CRC-32 0x%08" PRIx32 " (ok)\n",
              file.c_str(), with_commas(static_cast<long long>(bytes->size())).c_str(),
              nn::kModelFormatVersion, nn::stored_checksum(*bytes));
  print_model(*model, size_px);
  return 0;
}

}  // namespace

int run_model(Args args) {
  static constexpr cli::Subcommand kSubcommands[] = {{"convert", run_convert}, {"info", run_info}};
  return cli::dispatch_subcommand("mocap model", kUsage, kSubcommands, args);
}

}  // namespace mocap::tools
