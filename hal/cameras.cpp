#include "hal/cameras.h"

#include <fnmatch.h>

#include <algorithm>

#include "hal/libcamera/libcamera_camera.h"
#include "hal/v4l2/v4l2_camera.h"

namespace mocap::hal {
namespace {

namespace fs = std::filesystem;

bool glob_match(const std::string& pattern, const std::string& text) {
  return pattern.empty() || fnmatch(pattern.c_str(), text.c_str(), 0) == 0;
}

// Lists each backend at most once per discovery.
class Lister {
 public:
  Lister(std::string dev_dir, std::vector<std::string>& notes)
      : dev_dir_(std::move(dev_dir)), notes_(notes) {}

  const std::vector<CameraDescription>& cameras(CameraBackend b) {
    if (b == CameraBackend::kV4l2 && !v4l2_listed_) {
      v4l2_listed_ = true;
      V4l2Listing l = list_v4l2_cameras(dev_dir_);
      for (const auto& s : l.skipped) notes_.push_back("v4l2: skipped " + s);
      v4l2_ = std::move(l.cameras);
    } else if (b == CameraBackend::kLibcamera && !libcamera_listed_) {
      libcamera_listed_ = true;
      Result<LibcameraListing> l = list_libcamera_cameras();
      if (l.ok()) {
        libcamera_ = std::move(l->cameras);
      } else {
        notes_.push_back("libcamera unavailable: " + l.error().message());
      }
    }
    static const std::vector<CameraDescription> kNone;
    if (b == CameraBackend::kV4l2) return v4l2_;
    if (b == CameraBackend::kLibcamera) return libcamera_;
    return kNone;
  }

 private:
  std::string dev_dir_;
  std::vector<std::string>& notes_;
  bool v4l2_listed_ = false, libcamera_listed_ = false;
  std::vector<CameraDescription> v4l2_, libcamera_;
};

// The cameras of one board on this machine: one entry per device, in id order, at most
// max_cameras.
std::vector<FoundCamera> find_board_cameras(const Board& board, const std::string& dev_dir,
                                            int max_cameras, std::vector<std::string>& notes) {
  std::vector<FoundCamera> found;
  Lister lister(dev_dir, notes);
  for (const BoardCamera& bc : board.cameras) {
    for (const CameraDescription& d : lister.cameras(bc.backend)) {
      if (glob_match(bc.match, d.id)) found.push_back({bc.backend, d});
    }
  }
  const auto by_id = [](const FoundCamera& a, const FoundCamera& b) {
    return a.description.id < b.description.id;
  };
  const auto same_id = [](const FoundCamera& a, const FoundCamera& b) {
    return a.description.id == b.description.id;
  };
  std::sort(found.begin(), found.end(), by_id);
  found.erase(std::unique(found.begin(), found.end(), same_id), found.end());
  const int limit = std::min(max_cameras, board.max_cameras);
  if (static_cast<int>(found.size()) > limit) {
    notes.push_back("found " + std::to_string(found.size()) + " cameras; using the first " +
                    std::to_string(limit) + " (max_cameras)");
    found.resize(static_cast<std::size_t>(limit));
  }
  return found;
}

}  // namespace

std::string_view to_string(CameraBackend backend) {
  switch (backend) {
    case CameraBackend::kV4l2:
      return "v4l2";
    case CameraBackend::kLibcamera:
      return "libcamera";
    case CameraBackend::kReplay:
      return "replay";
    case CameraBackend::kSimulator:
      return "simulator";
  }
  return "?";
}

Result<CameraBackend> parse_camera_backend(std::string_view name) {
  if (name == "v4l2") return CameraBackend::kV4l2;
  if (name == "libcamera") return CameraBackend::kLibcamera;
  return Error(ErrorCode::kInvalidArgument,
               "camera backend '" + std::string(name) + "': expected v4l2 or libcamera");
}

Status CameraSpec::validate() const {
  if (backend != CameraBackend::kV4l2 && backend != CameraBackend::kLibcamera) {
    return Error(ErrorCode::kInvalidArgument, "camera backend " + std::string(to_string(backend)) +
                                                  " does not open cameras (v4l2 or libcamera do)");
  }
  if (backend == CameraBackend::kV4l2 && id.empty()) {
    return Error(ErrorCode::kInvalidArgument, "a V4L2 camera needs a device node (/dev/videoN)");
  }
  if (buffer_count < 2 || buffer_count > 32) {
    return Error(ErrorCode::kInvalidArgument,
                 "camera buffer_count must be in [2, 32], got " + std::to_string(buffer_count));
  }
  return request.validate();
}

Result<CameraFactory> camera_factory(const CameraSpec& spec) {
  if (Status s = spec.validate(); !s.ok()) return s.error();
  if (spec.backend == CameraBackend::kV4l2) {
    V4l2CameraOptions o;
    o.device = spec.id;
    o.view_id = spec.view_id;
    o.request = spec.request;
    o.buffer_count = spec.buffer_count;
    o.external_trigger = spec.external_trigger;
    return CameraFactory([o]() -> Result<std::unique_ptr<CameraSource>> {
      auto c = V4l2Camera::open(o);
      if (!c) return c.error();
      return std::unique_ptr<CameraSource>(std::move(*c));
    });
  }
  LibcameraCameraOptions o;
  o.camera_id = spec.id;
  o.view_id = spec.view_id;
  o.request = spec.request;
  o.buffer_count = spec.buffer_count;
  return CameraFactory([o]() -> Result<std::unique_ptr<CameraSource>> {
    auto c = LibcameraCamera::open(o);
    if (!c) return c.error();
    return std::unique_ptr<CameraSource>(std::move(*c));
  });
}

Result<Discovery> discover_cameras(const fs::path& board_dir, const std::string& board,
                                   const std::string& dev_dir, int max_cameras) {
  Discovery d;
  if (!board.empty()) {
    Result<Board> b = load_board(board_dir / board / "board.json");
    if (!b.ok()) return b.error();
    d.board_name = board;
    d.board = *b;
    d.cameras = find_board_cameras(d.board, dev_dir, max_cameras, d.notes);
    return d;
  }
  std::error_code ec;
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(board_dir, ec)) {
    if (fs::exists(e.path() / "board.json")) names.push_back(e.path().filename().string());
  }
  if (ec) {
    return Error(ErrorCode::kNotFound,
                 board_dir.string() + ": cannot list boards (" + ec.message() + "); set board_dir");
  }
  std::sort(names.begin(), names.end());
  for (const std::string& name : names) {
    if (name == "sim") continue;
    Result<Board> b = load_board(board_dir / name / "board.json");
    if (!b.ok()) {
      d.notes.push_back("board " + name + " skipped: " + b.error().message());
      continue;
    }
    std::vector<FoundCamera> cams = find_board_cameras(*b, dev_dir, max_cameras, d.notes);
    if (!cams.empty()) {
      d.board_name = name;
      d.board = *b;
      d.cameras = std::move(cams);
      return d;
    }
  }
  Result<Board> sim = load_board(board_dir / "sim" / "board.json");
  if (!sim.ok()) return sim.error();
  d.board_name = "sim";
  d.board = *sim;
  return d;
}

}  // namespace mocap::hal
