#include "hal/libcamera/libcamera_camera.h"

#include <sys/mman.h>

#include <cstdlib>

#include <libcamera/libcamera.h>
#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>

#include "runtime/core/log.h"

namespace mocap::hal {
namespace {

MOCAP_LOG_CATEGORY(Libcamera)

namespace lc = libcamera;

// libcamera allows one CameraManager per process: shared by every listing and camera, started
// on first use, stopped when the last user lets go.
Result<std::shared_ptr<lc::CameraManager>> camera_manager() {
  static std::mutex mu;
  static std::weak_ptr<lc::CameraManager> current;
  std::lock_guard lock(mu);
  if (auto cm = current.lock()) return cm;
  // libcamera logs INFO lines to stderr by default; keep its warnings and errors only, unless
  // the user set LIBCAMERA_LOG_LEVELS.
  ::setenv("LIBCAMERA_LOG_LEVELS", "*:WARN", 0);
  auto cm = std::make_shared<lc::CameraManager>();
  if (const int r = cm->start(); r < 0) {
    return Error(ErrorCode::kDevice,
                 std::string("libcamera: camera manager failed to start: ") + std::strerror(-r));
  }
  current = cm;
  return cm;
}

std::optional<PixelFormat> to_pixel_format(const lc::PixelFormat& f) {
  // libcamera names formats after DRM: BGR888 is R, G, B in memory (V4L2's RGB24).
  if (f == lc::formats::YUYV) return PixelFormat::kYUYV;
  if (f == lc::formats::NV12) return PixelFormat::kNV12;
  if (f == lc::formats::BGR888) return PixelFormat::kRGB24;
  if (f == lc::formats::R8) return PixelFormat::kGREY;
  if (f == lc::formats::MJPEG) return PixelFormat::kMJPEG;
  return std::nullopt;
}

lc::PixelFormat to_libcamera(PixelFormat f) {
  switch (f) {
    case PixelFormat::kYUYV:
      return lc::formats::YUYV;
    case PixelFormat::kNV12:
      return lc::formats::NV12;
    case PixelFormat::kRGB24:
      return lc::formats::BGR888;
    case PixelFormat::kGREY:
      return lc::formats::R8;
    case PixelFormat::kMJPEG:
      return lc::formats::MJPEG;
  }
  return lc::formats::YUYV;
}

// Highest frame rate from the camera's FrameDurationLimits (minimum duration, us); 0 = unstated.
double max_rate_hz(const lc::Camera& cam) {
  const auto it = cam.controls().find(&lc::controls::FrameDurationLimits);
  if (it == cam.controls().end()) return 0;
  const std::int64_t min_us = it->second.min().get<std::int64_t>();
  return min_us > 0 ? 1e6 / static_cast<double>(min_us) : 0;
}

std::vector<CameraMode> modes_of(lc::Camera& cam) {
  std::vector<CameraMode> modes;
  std::unique_ptr<lc::CameraConfiguration> config =
      cam.generateConfiguration({lc::StreamRole::VideoRecording});
  if (!config || config->empty()) return modes;
  const lc::StreamFormats& formats = config->at(0).formats();
  const double rate = max_rate_hz(cam);
  for (const lc::PixelFormat& pf : formats.pixelformats()) {
    const std::optional<PixelFormat> f = to_pixel_format(pf);
    if (!f) continue;
    for (const lc::Size& s : formats.sizes(pf)) {
      modes.push_back(CameraMode{*f, static_cast<int>(s.width), static_cast<int>(s.height), rate});
    }
  }
  return modes;
}

std::string camera_name(const lc::Camera& cam) {
  const auto model = cam.properties().get(lc::properties::Model);
  return model ? *model : cam.id();
}

}  // namespace

struct LibcameraCamera::State {
  struct Mapping {
    void* addr = MAP_FAILED;
    std::size_t length = 0;
  };
  struct Slot {
    std::unique_ptr<lc::Request> request;
    std::vector<Mapping> maps;  // one per plane
    std::vector<const std::uint8_t*> plane_data;
    bool held = false;  // a Frame owns it
    bool queued = false;
  };

  std::shared_ptr<lc::CameraManager> manager;
  std::shared_ptr<lc::Camera> camera;
  std::unique_ptr<lc::FrameBufferAllocator> allocator;
  lc::Stream* stream = nullptr;
  CameraDescription description;
  CameraMode mode;
  int stride_bytes = 0;
  int view_id = 0;
  std::optional<lc::ControlList> start_controls;

  std::mutex mu;
  std::condition_variable cv;
  bool running = false;
  bool disconnected = false;
  std::vector<Slot> slots;
  std::deque<std::size_t> completed;  // slot indices, in completion order
  std::uint64_t frames = 0;
  std::uint64_t failed = 0;

  ~State() {
    if (camera) {
      if (running) camera->stop();
      camera->requestCompleted.disconnect(this);
      camera->disconnected.disconnect(this);
    }
    for (Slot& s : slots) {
      for (Mapping& m : s.maps) {
        if (m.addr != MAP_FAILED) ::munmap(m.addr, m.length);
      }
    }
    slots.clear();  // requests before the allocator and the camera
    if (allocator && stream != nullptr) allocator->free(stream);
    allocator.reset();
    if (camera) camera->release();
    camera.reset();  // before the manager
  }

  std::size_t slot_of(const lc::Request* r) const { return static_cast<std::size_t>(r->cookie()); }

  // libcamera's thread: a request finished.
  void on_request_completed(lc::Request* request) {
    std::lock_guard lock(mu);
    Slot& s = slots[slot_of(request)];
    s.queued = false;
    if (request->status() != lc::Request::RequestComplete) {
      if (running) ++failed;
      return;  // cancelled at stop(), or failed: re-queued by start()/next()
    }
    completed.push_back(slot_of(request));
    cv.notify_one();
  }

  void on_disconnected() {
    std::lock_guard lock(mu);
    disconnected = true;
    cv.notify_all();
  }

  // Caller holds mu.
  bool queue_locked(std::size_t i) {
    Slot& s = slots[i];
    s.request->reuse(lc::Request::ReuseBuffers);
    if (camera->queueRequest(s.request.get()) < 0) return false;
    s.queued = true;
    return true;
  }

  void release(std::size_t i) {
    std::lock_guard lock(mu);
    slots[i].held = false;
    if (running && !disconnected && !queue_locked(i)) {
      MOCAP_LOG(Libcamera, Warn) << description.id << ": re-queueing request " << i << " failed";
    }
  }
};

// A request's buffer handed out as a Frame: the request is queued again on destruction.
using RequestBuffer = LentFrameBuffer<LibcameraCamera::State>;

Status LibcameraCameraOptions::validate() const {
  if (view_id < 0) return Error(ErrorCode::kInvalidArgument, "LibcameraCameraOptions.view_id < 0");
  if (buffer_count < 2 || buffer_count > 32) {
    return Error(ErrorCode::kInvalidArgument,
                 "LibcameraCameraOptions.buffer_count must be in 2..32");
  }
  return request.validate();
}

Result<LibcameraListing> list_libcamera_cameras() {
  Result<std::shared_ptr<lc::CameraManager>> cm = camera_manager();
  if (!cm) return cm.error();
  LibcameraListing out;
  for (const std::shared_ptr<lc::Camera>& cam : (*cm)->cameras()) {
    CameraDescription d;
    d.id = cam->id();
    d.name = camera_name(*cam);
    d.backend = "libcamera";
    d.modes = modes_of(*cam);
    out.cameras.push_back(std::move(d));
  }
  return out;
}

Result<std::unique_ptr<LibcameraCamera>> LibcameraCamera::open(
    const LibcameraCameraOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  Result<std::shared_ptr<lc::CameraManager>> cm = camera_manager();
  if (!cm) return cm.error();
  auto st = std::make_shared<State>();
  st->manager = *cm;
  st->view_id = options.view_id;
  if (options.camera_id.empty()) {
    if (st->manager->cameras().empty()) {
      return Error(ErrorCode::kNotFound,
                   "libcamera: no camera found (is one connected, and is udev running? libcamera "
                   "ignores devices udev has not initialised)");
    }
    st->camera = st->manager->cameras().front();
  } else {
    st->camera = st->manager->get(options.camera_id);
    if (!st->camera) {
      return Error(ErrorCode::kNotFound, "libcamera camera '" + options.camera_id +
                                             "' not found (`mocap cameras` lists the ids)");
    }
  }
  lc::Camera& cam = *st->camera;
  const std::string id = cam.id();
  if (cam.acquire() < 0) {
    st->camera.reset();
    return Error(ErrorCode::kDevice, "libcamera camera '" + id +
                                         "' is busy: another program or camera object holds it");
  }
  st->description.id = id;
  st->description.name = camera_name(cam);
  st->description.backend = "libcamera";
  st->description.modes = modes_of(cam);
  Result<CameraMode> mode = negotiate_mode(st->description.modes, options.request, id);
  if (!mode) return mode.error();

  std::unique_ptr<lc::CameraConfiguration> config =
      cam.generateConfiguration({lc::StreamRole::VideoRecording});
  if (!config || config->empty()) {
    return Error(ErrorCode::kUnsupported, "libcamera camera '" + id + "': no video stream");
  }
  lc::StreamConfiguration& sc = config->at(0);
  sc.pixelFormat = to_libcamera(mode->format);
  sc.size = lc::Size(static_cast<unsigned>(mode->width_px), static_cast<unsigned>(mode->height_px));
  sc.bufferCount = static_cast<unsigned>(options.buffer_count);
  const lc::CameraConfiguration::Status v = config->validate();
  if (v == lc::CameraConfiguration::Invalid || to_pixel_format(sc.pixelFormat) != mode->format ||
      static_cast<int>(sc.size.width) != mode->width_px ||
      static_cast<int>(sc.size.height) != mode->height_px) {
    return Error(ErrorCode::kUnsupported, "libcamera camera '" + id + "': asked for " +
                                              to_string(*mode) + ", it would give " +
                                              sc.toString());
  }
  if (const int r = cam.configure(config.get()); r < 0) {
    return Error(ErrorCode::kDevice,
                 "libcamera camera '" + id + "': configure failed: " + std::strerror(-r));
  }
  st->stream = sc.stream();
  st->stride_bytes = static_cast<int>(sc.stride);
  st->mode = *mode;

  // Frame rate: fixed frame duration when the camera has the control.
  const double want_hz =
      options.request.frame_rate_hz > 0 ? options.request.frame_rate_hz : mode->frame_rate_hz;
  if (want_hz > 0 && cam.controls().count(&lc::controls::FrameDurationLimits) != 0) {
    const auto d_us = static_cast<std::int64_t>(std::llround(1e6 / want_hz));
    st->start_controls.emplace(lc::controls::controls);
    st->start_controls->set(lc::controls::FrameDurationLimits,
                            lc::Span<const std::int64_t, 2>({d_us, d_us}));
    st->mode.frame_rate_hz = want_hz;
  }

  st->allocator = std::make_unique<lc::FrameBufferAllocator>(st->camera);
  if (st->allocator->allocate(st->stream) < 0) {
    return Error(ErrorCode::kDevice, "libcamera camera '" + id + "': buffer allocation failed");
  }
  const auto& buffers = st->allocator->buffers(st->stream);
  st->slots.resize(buffers.size());
  for (std::size_t i = 0; i < buffers.size(); ++i) {
    State::Slot& slot = st->slots[i];
    slot.request = cam.createRequest(i);
    if (!slot.request || slot.request->addBuffer(st->stream, buffers[i].get()) < 0) {
      return Error(ErrorCode::kDevice, "libcamera camera '" + id + "': cannot create requests");
    }
    for (const lc::FrameBuffer::Plane& p : buffers[i]->planes()) {
      State::Mapping m;
      m.length = p.offset + p.length;
      m.addr = ::mmap(nullptr, m.length, PROT_READ, MAP_SHARED, p.fd.get(), 0);
      if (m.addr == MAP_FAILED) {
        return Error(ErrorCode::kDevice,
                     "libcamera camera '" + id + "': mmap failed: " + std::strerror(errno));
      }
      slot.maps.push_back(m);
      slot.plane_data.push_back(static_cast<const std::uint8_t*>(m.addr) + p.offset);
    }
  }
  State* raw = st.get();
  cam.requestCompleted.connect(raw, &State::on_request_completed);
  cam.disconnected.connect(raw, &State::on_disconnected);

  std::unique_ptr<LibcameraCamera> out(new LibcameraCamera());
  out->state_ = std::move(st);
  MOCAP_LOG(Libcamera, Info) << id << ": " << to_string(out->state_->mode) << ", " << buffers.size()
                             << " buffers";
  return out;
}

LibcameraCamera::~LibcameraCamera() { stop(); }

const CameraDescription& LibcameraCamera::description() const { return state_->description; }
const CameraMode& LibcameraCamera::mode() const { return state_->mode; }

std::uint64_t LibcameraCamera::frames() const {
  std::lock_guard lock(state_->mu);
  return state_->frames;
}
std::uint64_t LibcameraCamera::failed_requests() const {
  std::lock_guard lock(state_->mu);
  return state_->failed;
}

Status LibcameraCamera::start() {
  State& s = *state_;
  {
    std::lock_guard lock(s.mu);
    if (s.running) return Status::Ok();
  }
  const int r = s.camera->start(s.start_controls ? &*s.start_controls : nullptr);
  if (r < 0) {
    return Error(ErrorCode::kDevice,
                 "libcamera camera '" + s.description.id + "': start failed: " + std::strerror(-r));
  }
  std::lock_guard lock(s.mu);
  s.running = true;
  s.completed.clear();
  for (std::size_t i = 0; i < s.slots.size(); ++i) {
    if (!s.slots[i].held && !s.queue_locked(i)) {
      return Error(ErrorCode::kDevice,
                   "libcamera camera '" + s.description.id + "': queueRequest failed");
    }
  }
  return Status::Ok();
}

void LibcameraCamera::stop() {
  if (!state_) return;
  State& s = *state_;
  {
    std::lock_guard lock(s.mu);
    if (!s.running) return;
    s.running = false;
  }
  s.camera->stop();  // completes every queued request as cancelled
  std::lock_guard lock(s.mu);
  s.completed.clear();
}

Result<Capture> LibcameraCamera::next(int timeout_ms) {
  State& s = *state_;
  std::size_t slot = 0;
  {
    std::unique_lock lock(s.mu);
    if (!s.running) {
      return Error(ErrorCode::kInvalidArgument,
                   "libcamera camera '" + s.description.id + "': next() before start()");
    }
    s.cv.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                  [&] { return !s.completed.empty() || s.disconnected; });
    if (s.disconnected) {
      return Error(ErrorCode::kDevice, "libcamera camera '" + s.description.id + "': disconnected");
    }
    // Requests that failed go back to the driver here (not from libcamera's thread).
    for (std::size_t i = 0; i < s.slots.size(); ++i) {
      const bool in_completed =
          std::find(s.completed.begin(), s.completed.end(), i) != s.completed.end();
      if (!s.slots[i].held && !s.slots[i].queued && !in_completed) s.queue_locked(i);
    }
    if (s.completed.empty()) return Capture{CaptureStatus::kTimeout, {}};
    slot = s.completed.front();
    s.completed.pop_front();
    s.slots[slot].held = true;
    ++s.frames;
  }
  State::Slot& sl = s.slots[slot];
  const lc::FrameBuffer* fb = sl.request->buffers().begin()->second;
  const lc::FrameMetadata& md = fb->metadata();
  Frame f;
  f.view_id = s.view_id;
  f.sequence = md.sequence;
  f.timestamp_ns = static_cast<std::int64_t>(md.timestamp);
  f.width_px = s.mode.width_px;
  f.height_px = s.mode.height_px;
  const auto planes = md.planes();
  const auto& fb_planes = fb->planes();
  std::size_t used0 = planes.empty() ? 0 : planes[0].bytesused;
  used0 = std::min<std::size_t>(used0, fb_planes[0].length);
  // NV12 in two planes of one dmabuf, back to back, is handed out as one span (zero-copy).
  const bool nv12_split = s.mode.format == PixelFormat::kNV12 && fb_planes.size() > 1;
  const bool nv12_contiguous = nv12_split && fb_planes[1].fd.get() == fb_planes[0].fd.get() &&
                               fb_planes[1].offset == fb_planes[0].offset + fb_planes[0].length;
  if (nv12_contiguous) used0 = fb_planes[0].length + fb_planes[1].length;
  auto raw = std::make_shared<RequestBuffer>(
      state_, slot, std::span<const std::uint8_t>(sl.plane_data[0], used0));
  switch (s.mode.format) {
    case PixelFormat::kMJPEG:
    case PixelFormat::kGREY: {
      Result<std::shared_ptr<const FrameBuffer>> rgb = convert_to_rgb24(
          s.mode.format, raw->bytes(), s.stride_bytes, f.width_px, f.height_px, s.description.id);
      if (!rgb) return Capture{CaptureStatus::kTimeout, {}};  // corrupt frame: dropped
      f.format = PixelFormat::kRGB24;
      f.stride_bytes = f.width_px * 3;
      f.buffer = std::move(*rgb);
      break;
    }
    case PixelFormat::kNV12:
      f.format = PixelFormat::kNV12;
      f.stride_bytes = s.stride_bytes;
      // Two planes: the UV plane starts after plane 0's whole length, which may be padded past
      // stride x height (alignment of the ISP's buffers), in one dmabuf or in the copy below.
      if (nv12_split) f.uv_offset_bytes = fb_planes[0].length;
      if (nv12_split && !nv12_contiguous) {
        // Planes in separate buffers: copied together (the request goes back at once).
        std::vector<std::uint8_t> both(fb_planes[0].length + fb_planes[1].length);
        std::memcpy(both.data(), sl.plane_data[0], fb_planes[0].length);
        std::memcpy(both.data() + fb_planes[0].length, sl.plane_data[1], fb_planes[1].length);
        f.buffer = std::make_shared<OwnedFrameBuffer>(std::move(both));
      } else {
        f.buffer = std::move(raw);
      }
      break;
    default:
      f.format = s.mode.format;
      f.stride_bytes = s.stride_bytes;
      f.buffer = std::move(raw);
      break;
  }
  return Capture{CaptureStatus::kFrame, std::move(f)};
}

}  // namespace mocap::hal
