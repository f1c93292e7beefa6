#include "runtime/geometry/calibration.h"

#include "runtime/core/atomic_file.h"

#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <fstream>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <system_error>
#include <utility>

namespace mocap {
namespace {

using Json = nlohmann::ordered_json;

constexpr std::uintmax_t kMaxFileBytes = 64u << 20;  // calibration files are a few KiB
constexpr int kMaxImageSide_px = 1 << 16;
constexpr double kMinDetK = 1e-6;

std::string fmt_num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

// A short rendering of a JSON value for error messages.
std::string describe(const Json& j) {
  std::string text = j.dump(-1, ' ', false, Json::error_handler_t::replace);
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  return std::string(j.type_name()) + " " + text;
}

// Errors while parsing one view: "<source>: view "<id>": field "<field>": <what>".
class ViewContext {
 public:
  ViewContext(std::string_view source, std::string_view view) : source_(source), view_(view) {}

  Error view_error(std::string_view what) const {
    std::string m(source_);
    m += ": view \"";
    m += view_;
    m += "\": ";
    m += what;
    return Error(ErrorCode::kParse, std::move(m));
  }
  Error field_error(std::string_view field, std::string_view what) const {
    std::string m("field \"");
    m += field;
    m += "\": ";
    m += what;
    return view_error(m);
  }

 private:
  std::string_view source_;
  std::string_view view_;
};

// Reads `field` as an array of finite numbers whose length is one of `allowed` into `out`
// (room for max(allowed) entries). `count_text` says how many ("9 numbers"), `meaning` what
// they are ("3x3 intrinsic matrix, row-major").
Status read_numbers(const Json& view, const ViewContext& ctx, const char* field,
                    std::initializer_list<std::size_t> allowed, std::string_view count_text,
                    std::string_view meaning, double* out, std::size_t* count) {
  const std::string counted(count_text);
  const std::string explained = counted + " (" + std::string(meaning) + ")";
  auto it = view.find(field);
  if (it == view.end()) return ctx.field_error(field, "missing; expected " + explained);
  const Json& arr = *it;
  if (!arr.is_array()) {
    return ctx.field_error(field, "expected an array of " + explained + ", got " + describe(arr));
  }
  if (std::find(allowed.begin(), allowed.end(), arr.size()) == allowed.end()) {
    return ctx.field_error(field, "expected " + counted + ", got " + std::to_string(arr.size()));
  }
  for (std::size_t i = 0; i < arr.size(); ++i) {
    const Json& v = arr[i];
    if (!v.is_number()) {
      return ctx.field_error(field, "element " + std::to_string(i) + " is not a number (got " +
                                        describe(v) + "); expected " + counted);
    }
    const double x = v.get<double>();
    if (!std::isfinite(x)) {
      return ctx.field_error(
          field, "element " + std::to_string(i) + " is not a finite number; expected " + counted);
    }
    out[i] = x;
  }
  *count = arr.size();
  return Status::Ok();
}

Status parse_intrinsics(const Json& view, const ViewContext& ctx, Eigen::Matrix3d* K) {
  std::array<double, 9> k{};
  std::size_t n = 0;
  if (Status s = read_numbers(view, ctx, "K", {9}, "9 numbers", "3x3 intrinsic matrix, row-major",
                              k.data(), &n);
      !s.ok()) {
    return s;
  }
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) (*K)(r, c) = k[static_cast<std::size_t>(3 * r + c)];
  }
  const double fx = k[0];
  const double fy = k[4];
  if (std::abs(k[6]) > 1e-9 || std::abs(k[7]) > 1e-9 || std::abs(k[8] - 1.0) > 1e-9) {
    return ctx.field_error("K", "expected last row [0, 0, 1], got [" + fmt_num(k[6]) + ", " +
                                    fmt_num(k[7]) + ", " + fmt_num(k[8]) + "]");
  }
  if (std::abs(k[3]) > 1e-9) {
    return ctx.field_error(
        "K", "expected K[1][0] = 0 (upper-triangular intrinsics), got " + fmt_num(k[3]));
  }
  const double det = K->determinant();
  if (!(fx > 0.0) || !(fy > 0.0) || !(std::abs(det) >= kMinDetK)) {
    return ctx.field_error("K", "singular or invalid intrinsic matrix (fx = " + fmt_num(fx) +
                                    ", fy = " + fmt_num(fy) + ", det = " + fmt_num(det) +
                                    "); expected fx > 0 and fy > 0 (pixels)");
  }
  return Status::Ok();
}

Status parse_extrinsics(const Json& view, const ViewContext& ctx, Eigen::Matrix3d* R,
                        Eigen::Vector3d* t_m) {
  std::array<double, 12> rt{};
  std::size_t n = 0;
  if (Status s = read_numbers(view, ctx, "RT", {12}, "12 numbers",
                              "3x4 world->camera [R|t], row-major, metres", rt.data(), &n);
      !s.ok()) {
    return s;
  }
  Eigen::Matrix3d raw;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) raw(r, c) = rt[static_cast<std::size_t>(4 * r + c)];
    (*t_m)(r) = rt[static_cast<std::size_t>(4 * r + 3)];
  }
  const double orth_err = (raw * raw.transpose() - Eigen::Matrix3d::Identity()).norm();
  const double det = raw.determinant();
  if (!(orth_err <= kRotationTolerance) || !(std::abs(det - 1.0) <= kRotationTolerance)) {
    std::string what = "rotation part R is not orthonormal (|R R^T - I| = " + fmt_num(orth_err) +
                       ", det(R) = " + fmt_num(det) + ")";
    if (det < 0.0) what += ", a reflection";
    what += "; expected a rotation matrix to within " + fmt_num(kRotationTolerance);
    return ctx.field_error("RT", what);
  }
  // Nearest rotation (Frobenius): R = U V^T.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(raw, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d& V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0.0) U.col(2) = -U.col(2);
  *R = U * V.transpose();
  return Status::Ok();
}

Status parse_image_size(const Json& view, const ViewContext& ctx, int* width_px, int* height_px) {
  std::array<double, 2> wh{};
  std::size_t n = 0;
  if (Status s = read_numbers(view, ctx, "imgSize", {2}, "2 numbers", "[width, height] in pixels",
                              wh.data(), &n);
      !s.ok()) {
    return s;
  }
  for (double v : wh) {
    if (!(v >= 1.0) || v > kMaxImageSide_px || std::floor(v) != v) {
      return ctx.field_error("imgSize", "expected [width, height] as positive integers up to " +
                                            std::to_string(kMaxImageSide_px) + ", got [" +
                                            fmt_num(wh[0]) + ", " + fmt_num(wh[1]) + "]");
    }
  }
  *width_px = static_cast<int>(wh[0]);
  *height_px = static_cast<int>(wh[1]);
  return Status::Ok();
}

Status parse_distortion(const Json& view, const ViewContext& ctx, Distortion* dist) {
  *dist = Distortion{};
  if (!view.contains("dist")) return Status::Ok();
  std::array<double, 5> d{};
  std::size_t n = 0;
  if (Status s = read_numbers(view, ctx, "dist", {4, 5}, "4 or 5 numbers",
                              "[k1, k2, p1, p2, k3], k3 optional", d.data(), &n);
      !s.ok()) {
    return s;
  }
  dist->k1 = d[0];
  dist->k2 = d[1];
  dist->p1 = d[2];
  dist->p2 = d[3];
  dist->k3 = n == 5 ? d[4] : 0.0;
  return Status::Ok();
}

Result<Camera> parse_view(const Json& view, const ViewContext& ctx) {
  if (!view.is_object()) {
    return ctx.view_error("expected an object with fields \"K\", \"RT\", \"imgSize\", got " +
                          describe(view));
  }
  Eigen::Matrix3d K;
  Eigen::Matrix3d R;
  Eigen::Vector3d t_m;
  Distortion dist;
  int width_px = 0;
  int height_px = 0;
  if (Status s = parse_intrinsics(view, ctx, &K); !s.ok()) return s.error();
  if (Status s = parse_extrinsics(view, ctx, &R, &t_m); !s.ok()) return s.error();
  if (Status s = parse_image_size(view, ctx, &width_px, &height_px); !s.ok()) return s.error();
  if (Status s = parse_distortion(view, ctx, &dist); !s.ok()) return s.error();
  std::string name;
  if (auto it = view.find("name"); it != view.end()) {
    if (!it->is_string()) {
      return ctx.field_error("name", "expected a string, got " + describe(*it));
    }
    name = it->get<std::string>();
  }
  return Camera(K, dist, width_px, height_px, R, t_m, std::move(name));
}

bool is_integer_key(const std::string& key) {
  return !key.empty() &&
         std::all_of(key.begin(), key.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// Numeric order of decimal strings of any length ("2" < "10"), ties broken by the text.
bool numeric_less(const std::string& a, const std::string& b) {
  const std::size_t za = std::min(a.find_first_not_of('0'), a.size());
  const std::size_t zb = std::min(b.find_first_not_of('0'), b.size());
  const std::string_view da = std::string_view(a).substr(za);
  const std::string_view db = std::string_view(b).substr(zb);
  if (da.size() != db.size()) return da.size() < db.size();
  if (da != db) return da < db;
  return a < b;
}

Result<Calibration> parse_document(std::string_view text, std::string_view source) {
  const std::string src(source);
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    return Error(ErrorCode::kParse,
                 src + ": file is empty; expected a JSON object keyed by view id");
  }
  Json root;
  try {
    root = Json::parse(text.begin(), text.end());
  } catch (const Json::exception& e) {  // parse_error, or out_of_range on number overflow
    std::string what = e.what();
    // Drop nlohmann's "[json.exception.parse_error.101] " tag.
    if (auto close = what.find("] ");
        what.starts_with("[json.exception") && close != std::string::npos) {
      what = what.substr(close + 2);
    }
    return Error(ErrorCode::kParse, src + ": invalid JSON: " + what);
  }
  if (!root.is_object()) {
    return Error(ErrorCode::kParse, src +
                                        ": expected a JSON object keyed by view id "
                                        "({\"0\": {\"K\": ..., \"RT\": ..., \"imgSize\": ...}}), "
                                        "got " +
                                        std::string(root.type_name()));
  }
  if (root.empty()) {
    return Error(ErrorCode::kParse,
                 src + ": no views; expected at least one view object keyed by view id");
  }

  std::vector<std::pair<std::string, const Json*>> views;
  views.reserve(root.size());
  bool all_integer = true;
  for (auto it = root.begin(); it != root.end(); ++it) {
    views.emplace_back(it.key(), &it.value());
    all_integer = all_integer && is_integer_key(it.key());
  }
  if (all_integer) {
    std::stable_sort(views.begin(), views.end(),
                     [](const auto& a, const auto& b) { return numeric_less(a.first, b.first); });
  }

  Calibration calib;
  calib.cameras.reserve(views.size());
  calib.view_ids.reserve(views.size());
  for (const auto& [id, view] : views) {
    Result<Camera> cam = parse_view(*view, ViewContext(source, id));
    if (!cam.ok()) return cam.error();
    calib.cameras.push_back(std::move(cam).value());
    calib.view_ids.push_back(id);
  }
  return calib;
}

Json numbers(std::initializer_list<double> values) {
  Json arr = Json::array();
  for (double v : values) arr.push_back(v);
  return arr;
}

}  // namespace

std::optional<std::size_t> Calibration::index_of(std::string_view view_id) const {
  for (std::size_t i = 0; i < view_ids.size(); ++i) {
    if (view_ids[i] == view_id) return i;
  }
  return std::nullopt;
}

Result<Calibration> parse_calibration_json(std::string_view text, std::string_view source_name) {
  try {
    return parse_document(text, source_name);
  } catch (const std::exception& e) {
    return Error(ErrorCode::kInternal,
                 std::string(source_name) + ": unexpected failure while parsing: " + e.what());
  }
}

Result<Calibration> load_calibration(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  try {
    const std::string name = path.string();
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    if (!fs::exists(st)) {
      return Error(ErrorCode::kNotFound, name + ": calibration file not found (check the path)");
    }
    if (fs::is_directory(st)) {
      return Error(ErrorCode::kIo, name + ": is a directory, expected a calibration JSON file");
    }
    const std::uintmax_t size = fs::file_size(path, ec);
    if (!ec && size > kMaxFileBytes) {
      return Error(ErrorCode::kParse, name + ": file is " + std::to_string(size) +
                                          " bytes, too large for a calibration file");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      return Error(ErrorCode::kIo, name + ": cannot open for reading: " + errno_text(errno));
    }
    std::string text;
    std::array<char, 8192> chunk;
    while (in.read(chunk.data(), chunk.size()) || in.gcount() > 0) {
      text.append(chunk.data(), static_cast<std::size_t>(in.gcount()));
      if (text.size() > kMaxFileBytes) {
        return Error(ErrorCode::kParse, name + ": too large for a calibration file");
      }
    }
    if (in.bad()) return Error(ErrorCode::kIo, name + ": read failed: " + errno_text(errno));
    return parse_calibration_json(text, name);
  } catch (const std::exception& e) {
    return Error(ErrorCode::kIo, path.string() + ": cannot read calibration: " + e.what());
  }
}

Result<std::string> calibration_to_json(const Calibration& calib) {
  if (calib.view_ids.size() != calib.cameras.size()) {
    return Error(ErrorCode::kInvalidArgument,
                 "calibration has " + std::to_string(calib.cameras.size()) + " cameras but " +
                     std::to_string(calib.view_ids.size()) + " view ids");
  }
  try {
    std::set<std::string_view> seen;
    Json root = Json::object();
    for (std::size_t i = 0; i < calib.cameras.size(); ++i) {
      const std::string& id = calib.view_ids[i];
      if (!seen.insert(id).second) {
        return Error(ErrorCode::kInvalidArgument, "view id \"" + id + "\" appears twice");
      }
      const Camera& cam = calib.cameras[i];
      const Eigen::Matrix3d& K = cam.K();
      const Eigen::Matrix3d& R = cam.R();
      const Eigen::Vector3d& t = cam.t_m();
      Json view = Json::object();
      view["K"] = numbers(
          {K(0, 0), K(0, 1), K(0, 2), K(1, 0), K(1, 1), K(1, 2), K(2, 0), K(2, 1), K(2, 2)});
      view["RT"] = numbers({R(0, 0), R(0, 1), R(0, 2), t(0), R(1, 0), R(1, 1), R(1, 2), t(1),
                            R(2, 0), R(2, 1), R(2, 2), t(2)});
      view["imgSize"] = Json::array({cam.width_px(), cam.height_px()});
      if (cam.has_distortion()) {
        const Distortion& d = cam.distortion();
        view["dist"] = numbers({d.k1, d.k2, d.p1, d.p2, d.k3});
      }
      if (!cam.name().empty()) view["name"] = cam.name();
      root[id] = std::move(view);
    }
    std::string text = root.dump(2, ' ', false, Json::error_handler_t::replace);
    text += '\n';
    return text;
  } catch (const std::exception& e) {
    return Error(ErrorCode::kInternal, std::string("cannot serialise calibration: ") + e.what());
  }
}

Status save_calibration(const Calibration& calib, const std::filesystem::path& path) {
  Result<std::string> text = calibration_to_json(calib);
  if (!text.ok()) return text.error().with_context(path.string());
  return write_file_atomically(path, *text, Durability::kDurable);
}

}  // namespace mocap
