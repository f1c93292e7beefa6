#include "hal/v4l2/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <utility>

#include "runtime/core/atomic_file.h"
#include "runtime/core/log.h"

namespace mocap::hal {
namespace {

MOCAP_LOG_CATEGORY(V4l2)

// ioctl, retried when a signal interrupts it.
int xioctl(int fd, unsigned long request, void* arg) {
  int r = 0;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

std::optional<PixelFormat> to_pixel_format(std::uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_YUYV:
      return PixelFormat::kYUYV;
    case V4L2_PIX_FMT_NV12:
      return PixelFormat::kNV12;
    case V4L2_PIX_FMT_RGB24:
      return PixelFormat::kRGB24;
    case V4L2_PIX_FMT_GREY:
      return PixelFormat::kGREY;
    case V4L2_PIX_FMT_MJPEG:
    case V4L2_PIX_FMT_JPEG:
      return PixelFormat::kMJPEG;
    default:
      return std::nullopt;
  }
}

// The format the frames have once they leave the backend (MJPEG and GREY are converted).
PixelFormat delivered_format(PixelFormat captured) {
  return captured == PixelFormat::kMJPEG || captured == PixelFormat::kGREY ? PixelFormat::kRGB24
                                                                           : captured;
}

std::string fourcc_text(std::uint32_t f) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i)
    s[static_cast<std::size_t>(i)] = static_cast<char>((f >> (8 * i)) & 0xff);
  return s;
}

// The explanation for a failed open(), naming the node and the fix.
Error open_error(const std::string& device, int err) {
  switch (err) {
    case ENOENT:
    case ENODEV:
    case ENXIO:
      return Error(
          ErrorCode::kNotFound,
          "camera " + device +
              ": no such device (is it plugged in? `mocap cameras` lists the ones present)");
    case EACCES:
    case EPERM:
      return Error(ErrorCode::kDevice,
                   "camera " + device +
                       ": permission denied (add the user to the 'video' group: `usermod -aG video "
                       "$USER`, then log in again)");
    case EBUSY:
      return Error(ErrorCode::kDevice,
                   "camera " + device + ": busy, another program holds it (find it with `fuser " +
                       device + "`)");
    default:
      return Error(ErrorCode::kDevice, "camera " + device + ": cannot open: " + errno_text(err));
  }
}

Error ioctl_error(const std::string& device, const char* what, int err) {
  if (err == EBUSY) {
    return Error(ErrorCode::kDevice, "camera " + device + ": busy during " + what +
                                         ": another program is streaming from it (find it with "
                                         "`fuser " +
                                         device + "`)");
  }
  if (err == ENODEV || err == EIO || err == ENXIO) {
    return Error(ErrorCode::kDevice, "camera " + device + ": disconnected during " + what + " (" +
                                         errno_text(err) + ")");
  }
  return Error(ErrorCode::kDevice,
               "camera " + device + ": " + what + " failed: " + errno_text(err));
}

// An fd closed on scope exit unless released.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

Result<int> open_node(const std::string& device) {
  const int fd = ::open(device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return open_error(device, errno);
  return fd;
}

double interval_rate_hz(const v4l2_fract& f) {
  return f.numerator == 0 ? 0.0 : static_cast<double>(f.denominator) / f.numerator;
}

// Highest frame rate at one format and size; 0 when the driver does not enumerate intervals.
double max_rate_hz(int fd, std::uint32_t fourcc, std::uint32_t w, std::uint32_t h) {
  double best = 0;
  for (std::uint32_t i = 0;; ++i) {
    v4l2_frmivalenum iv{};
    iv.index = i;
    iv.pixel_format = fourcc;
    iv.width = w;
    iv.height = h;
    if (xioctl(fd, VIDIOC_ENUM_FRAMEINTERVALS, &iv) < 0) break;
    if (iv.type == V4L2_FRMIVAL_TYPE_DISCRETE) {
      best = std::max(best, interval_rate_hz(iv.discrete));
    } else {
      best = std::max(best, interval_rate_hz(iv.stepwise.min));  // shortest interval
      break;
    }
  }
  return best;
}

// Sizes offered at one format: discrete sizes as they are; for stepwise or continuous ranges
// the largest size and the common sizes that fit the range.
std::vector<std::pair<std::uint32_t, std::uint32_t>> frame_sizes(int fd, std::uint32_t fourcc) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> sizes;
  for (std::uint32_t i = 0;; ++i) {
    v4l2_frmsizeenum fs{};
    fs.index = i;
    fs.pixel_format = fourcc;
    if (xioctl(fd, VIDIOC_ENUM_FRAMESIZES, &fs) < 0) break;
    if (fs.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
      sizes.emplace_back(fs.discrete.width, fs.discrete.height);
      continue;
    }
    const v4l2_frmsize_stepwise& s = fs.stepwise;
    constexpr std::pair<std::uint32_t, std::uint32_t> kCommon[] = {
        {640, 480}, {1280, 720}, {1280, 960}, {1920, 1080}};
    for (const auto& [w, h] : kCommon) {
      const bool fits = w >= s.min_width && w <= s.max_width && h >= s.min_height &&
                        h <= s.max_height &&
                        (s.step_width == 0 || (w - s.min_width) % s.step_width == 0) &&
                        (s.step_height == 0 || (h - s.min_height) % s.step_height == 0);
      if (fits) sizes.emplace_back(w, h);
    }
    sizes.emplace_back(s.max_width, s.max_height);
    break;
  }
  return sizes;
}

struct Probe {
  CameraDescription description;
  std::vector<std::uint32_t> fourccs;  // parallel to description.modes
  std::uint32_t caps = 0;
};

Result<Probe> probe_fd(int fd, const std::string& device) {
  v4l2_capability cap{};
  if (xioctl(fd, VIDIOC_QUERYCAP, &cap) < 0) {
    return Error(ErrorCode::kDevice, "camera " + device + ": not a V4L2 device (VIDIOC_QUERYCAP: " +
                                         errno_text(errno) + ")");
  }
  Probe p;
  p.caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  p.description.id = device;
  p.description.name = reinterpret_cast<const char*>(cap.card);
  p.description.backend = "v4l2";
  if ((p.caps & V4L2_CAP_VIDEO_CAPTURE) == 0) {
    const char* what = (p.caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) != 0
                           ? "a multi-planar capture node (use the libcamera backend for it)"
                           : "not a video capture node (metadata or output)";
    return Error(ErrorCode::kUnsupported,
                 "camera " + device + " (" + p.description.name + "): " + what);
  }
  if ((p.caps & V4L2_CAP_STREAMING) == 0) {
    return Error(ErrorCode::kUnsupported, "camera " + device + " (" + p.description.name +
                                              "): no streaming I/O (read() only)");
  }
  for (std::uint32_t i = 0;; ++i) {
    v4l2_fmtdesc fd_desc{};
    fd_desc.index = i;
    fd_desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd, VIDIOC_ENUM_FMT, &fd_desc) < 0) break;
    const std::optional<PixelFormat> pf = to_pixel_format(fd_desc.pixelformat);
    if (!pf) continue;
    for (const auto& [w, h] : frame_sizes(fd, fd_desc.pixelformat)) {
      CameraMode m;
      m.format = *pf;
      m.width_px = static_cast<int>(w);
      m.height_px = static_cast<int>(h);
      m.frame_rate_hz = max_rate_hz(fd, fd_desc.pixelformat, w, h);
      p.description.modes.push_back(m);
      p.fourccs.push_back(fd_desc.pixelformat);
    }
  }
  return p;
}

// Node number of "videoN" (for sorting), -1 for other names.
int video_node_number(const std::string& name) {
  if (name.rfind("video", 0) != 0 || name.size() == 5) return -1;
  int n = 0;
  for (std::size_t i = 5; i < name.size(); ++i) {
    if (name[i] < '0' || name[i] > '9') return -1;
    n = n * 10 + (name[i] - '0');
  }
  return n;
}

}  // namespace

// ------------------------------------------------------------------------------- Device

struct V4l2Camera::Device {
  enum class BufferState { kFree, kQueued, kHeld };
  struct Mapping {
    void* addr = MAP_FAILED;
    std::size_t length = 0;
    BufferState state = BufferState::kFree;
  };

  std::string path;
  int fd = -1;
  mutable std::mutex mu;
  bool streaming = false;
  std::vector<Mapping> maps;

  ~Device() {
    if (fd >= 0 && streaming) {
      v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      xioctl(fd, VIDIOC_STREAMOFF, &type);
    }
    for (Mapping& m : maps) {
      if (m.addr != MAP_FAILED) ::munmap(m.addr, m.length);
    }
    if (fd >= 0) ::close(fd);
  }

  // Queues buffer `index` to the driver (caller holds mu).
  bool queue_locked(std::uint32_t index) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = index;
    if (xioctl(fd, VIDIOC_QBUF, &b) < 0) return false;
    maps[index].state = BufferState::kQueued;
    return true;
  }

  // A frame let go of its buffer: back to the driver while streaming, else free.
  void release(std::size_t index) {
    std::lock_guard lock(mu);
    maps[index].state = BufferState::kFree;
    if (streaming && !queue_locked(index)) {
      MOCAP_LOG(V4l2, Warn) << path << ": re-queueing buffer " << index
                            << " failed: " << errno_text(errno);
    }
  }
};

// A driver buffer handed out as a Frame: the mmap'ed bytes, re-queued on destruction.
using MappedBuffer = LentFrameBuffer<V4l2Camera::Device>;

// ---------------------------------------------------------------------------- public API

Status V4l2CameraOptions::validate() const {
  if (device.empty())
    return Error(ErrorCode::kInvalidArgument, "V4l2CameraOptions.device is empty");
  if (view_id < 0) return Error(ErrorCode::kInvalidArgument, "V4l2CameraOptions.view_id < 0");
  if (buffer_count < 2 || buffer_count > 32) {
    return Error(ErrorCode::kInvalidArgument, "V4l2CameraOptions.buffer_count must be in 2..32");
  }
  return request.validate();
}

Result<CameraDescription> probe_v4l2_camera(const std::string& device) {
  Result<int> fd = open_node(device);
  if (!fd) return fd.error();
  const Fd guard(*fd);
  Result<Probe> p = probe_fd(guard.get(), device);
  if (!p) return p.error();
  return std::move(p->description);
}

V4l2Listing list_v4l2_cameras(const std::string& dev_dir) {
  V4l2Listing out;
  std::vector<std::pair<int, std::string>> nodes;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dev_dir, ec)) {
    const std::string name = entry.path().filename().string();
    const int n = video_node_number(name);
    if (n >= 0) nodes.emplace_back(n, entry.path().string());
  }
  std::sort(nodes.begin(), nodes.end());
  for (const auto& [n, path] : nodes) {
    Result<CameraDescription> d = probe_v4l2_camera(path);
    if (d) {
      out.cameras.push_back(std::move(*d));
    } else {
      out.skipped.push_back(d.error().message());
    }
  }
  return out;
}

Result<std::unique_ptr<V4l2Camera>> V4l2Camera::open(const V4l2CameraOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  Result<int> fd_or = open_node(options.device);
  if (!fd_or) return fd_or.error();
  Fd fd(*fd_or);
  Result<Probe> probe = probe_fd(fd.get(), options.device);
  if (!probe) return probe.error();

  std::unique_ptr<V4l2Camera> cam(new V4l2Camera());
  cam->options_ = options;
  cam->description_ = probe->description;
  Result<CameraMode> mode =
      negotiate_mode(probe->description.modes, options.request, options.device);
  if (!mode) return mode.error();
  const auto it = std::find_if(probe->description.modes.begin(), probe->description.modes.end(),
                               [&](const CameraMode& m) {
                                 return m.format == mode->format && m.width_px == mode->width_px &&
                                        m.height_px == mode->height_px;
                               });
  cam->fourcc_ = probe->fourccs[static_cast<std::size_t>(it - probe->description.modes.begin())];

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<std::uint32_t>(mode->width_px);
  fmt.fmt.pix.height = static_cast<std::uint32_t>(mode->height_px);
  fmt.fmt.pix.pixelformat = cam->fourcc_;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(fd.get(), VIDIOC_S_FMT, &fmt) < 0)
    return ioctl_error(options.device, "VIDIOC_S_FMT", errno);
  if (fmt.fmt.pix.pixelformat != cam->fourcc_ ||
      static_cast<int>(fmt.fmt.pix.width) != mode->width_px ||
      static_cast<int>(fmt.fmt.pix.height) != mode->height_px) {
    return Error(ErrorCode::kUnsupported,
                 "camera " + options.device + ": asked for " + to_string(*mode) +
                     ", the driver set " + fourcc_text(fmt.fmt.pix.pixelformat) + " " +
                     std::to_string(fmt.fmt.pix.width) + "x" + std::to_string(fmt.fmt.pix.height));
  }
  cam->stride_bytes_ = static_cast<int>(fmt.fmt.pix.bytesperline);
  cam->mode_ = *mode;

  // Frame interval: the requested rate, else the mode's highest. Not with an external
  // trigger, where the pulses set the rate.
  const double want_hz =
      options.request.frame_rate_hz > 0 ? options.request.frame_rate_hz : mode->frame_rate_hz;
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (!options.external_trigger && want_hz > 0 && xioctl(fd.get(), VIDIOC_G_PARM, &parm) == 0 &&
      (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) != 0) {
    const double rounded = std::round(want_hz);
    if (std::abs(rounded - want_hz) < 1e-6) {
      parm.parm.capture.timeperframe = {1, static_cast<std::uint32_t>(rounded)};
    } else {
      parm.parm.capture.timeperframe = {1000,
                                        static_cast<std::uint32_t>(std::lround(want_hz * 1000))};
    }
    if (xioctl(fd.get(), VIDIOC_S_PARM, &parm) < 0) {
      return ioctl_error(options.device, "VIDIOC_S_PARM (frame interval)", errno);
    }
  }
  v4l2_streamparm got{};
  got.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd.get(), VIDIOC_G_PARM, &got) == 0) {
    cam->actual_rate_hz_ = interval_rate_hz(got.parm.capture.timeperframe);
  }
  if (!options.external_trigger && options.request.frame_rate_hz > 0 && cam->actual_rate_hz_ > 0 &&
      cam->actual_rate_hz_ + 0.01 < options.request.frame_rate_hz) {
    return Error(ErrorCode::kUnsupported, "camera " + options.device + ": asked for " +
                                              std::to_string(options.request.frame_rate_hz) +
                                              " fps, the driver set " +
                                              std::to_string(cam->actual_rate_hz_));
  }
  cam->mode_.frame_rate_hz = cam->actual_rate_hz_ > 0 ? cam->actual_rate_hz_ : mode->frame_rate_hz;

  // External trigger: switch on a "Trigger Mode" control when the driver has one.
  cam->trigger_.requested = options.external_trigger;
  if (options.external_trigger) {
    v4l2_queryctrl q{};
    q.id = V4L2_CTRL_FLAG_NEXT_CTRL;
    while (xioctl(fd.get(), VIDIOC_QUERYCTRL, &q) == 0) {
      std::string name = reinterpret_cast<const char*>(q.name);
      std::transform(name.begin(), name.end(), name.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (name.find("trigger") != std::string::npos && (q.flags & V4L2_CTRL_FLAG_DISABLED) == 0) {
        v4l2_control c{};
        c.id = q.id;
        c.value = 1;
        cam->trigger_.control_found = xioctl(fd.get(), VIDIOC_S_CTRL, &c) == 0;
        break;
      }
      q.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
    }
  }

  // Buffers: ask, then map each one.
  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(options.buffer_count);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd.get(), VIDIOC_REQBUFS, &req) < 0)
    return ioctl_error(options.device, "VIDIOC_REQBUFS", errno);
  if (req.count < 2) {
    return Error(ErrorCode::kDevice, "camera " + options.device + ": the driver gave " +
                                         std::to_string(req.count) + " buffer(s), 2 are needed");
  }
  auto dev = std::make_shared<Device>();
  dev->path = options.device;
  dev->fd = fd.release();
  dev->maps.resize(req.count);
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (xioctl(dev->fd, VIDIOC_QUERYBUF, &b) < 0)
      return ioctl_error(options.device, "VIDIOC_QUERYBUF", errno);
    void* addr = ::mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, dev->fd, b.m.offset);
    if (addr == MAP_FAILED) return ioctl_error(options.device, "mmap", errno);
    dev->maps[i].addr = addr;
    dev->maps[i].length = b.length;
  }
  cam->device_ = std::move(dev);
  MOCAP_LOG(V4l2, Info) << options.device << " (" << cam->description_.name
                        << "): " << to_string(cam->mode_) << ", " << cam->device_->maps.size()
                        << " buffers";
  return cam;
}

V4l2Camera::~V4l2Camera() { stop(); }

int V4l2Camera::buffer_count() const { return static_cast<int>(device_->maps.size()); }

int V4l2Camera::buffers_held() const {
  std::lock_guard lock(device_->mu);
  return static_cast<int>(
      std::count_if(device_->maps.begin(), device_->maps.end(),
                    [](const auto& m) { return m.state == Device::BufferState::kHeld; }));
}

Status V4l2Camera::start() {
  Device& d = *device_;
  std::lock_guard lock(d.mu);
  if (d.streaming) return Status::Ok();
  for (std::uint32_t i = 0; i < d.maps.size(); ++i) {
    if (d.maps[i].state == Device::BufferState::kFree && !d.queue_locked(i)) {
      return ioctl_error(d.path, "VIDIOC_QBUF", errno);
    }
  }
  v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(d.fd, VIDIOC_STREAMON, &type) < 0)
    return ioctl_error(d.path, "VIDIOC_STREAMON", errno);
  d.streaming = true;
  trigger_.streaming = true;
  return Status::Ok();
}

void V4l2Camera::stop() {
  if (!device_) return;
  Device& d = *device_;
  std::lock_guard lock(d.mu);
  if (!d.streaming) return;
  v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  xioctl(d.fd, VIDIOC_STREAMOFF, &type);  // dequeues every queued buffer
  for (Device::Mapping& m : d.maps) {
    if (m.state == Device::BufferState::kQueued) m.state = Device::BufferState::kFree;
  }
  d.streaming = false;
  trigger_.streaming = false;
}

Result<Capture> V4l2Camera::next(int timeout_ms) {
  Device& d = *device_;
  {
    std::lock_guard lock(d.mu);
    if (!d.streaming) {
      return Error(ErrorCode::kInvalidArgument, "camera " + d.path + ": next() before start()");
    }
  }
  const std::int64_t deadline_ns =
      monotonic_ns() + static_cast<std::int64_t>(timeout_ms) * 1'000'000;
  for (;;) {
    const std::int64_t left_ns = deadline_ns - monotonic_ns();
    pollfd p{d.fd, POLLIN, 0};
    const int wait_ms = left_ns > 0 ? static_cast<int>((left_ns + 999'999) / 1'000'000) : 0;
    const int r = ::poll(&p, 1, wait_ms);
    if (r < 0) {
      if (errno == EINTR) continue;
      return ioctl_error(d.path, "poll", errno);
    }
    if (r == 0) return Capture{CaptureStatus::kTimeout, {}};
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    {
      std::lock_guard lock(d.mu);
      if (xioctl(d.fd, VIDIOC_DQBUF, &b) < 0) {
        const int err = errno;
        if (err == EAGAIN && (p.revents & POLLERR) == 0) continue;
        // POLLERR with nothing to dequeue, EIO, ENODEV: the device went away or failed.
        return ioctl_error(d.path, "capture", err == EAGAIN ? ENODEV : err);
      }
      d.maps[b.index].state = Device::BufferState::kHeld;
    }
    auto raw = std::make_shared<MappedBuffer>(
        device_, b.index,
        std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(d.maps[b.index].addr),
                                      std::min<std::size_t>(b.bytesused, d.maps[b.index].length)));
    if ((b.flags & V4L2_BUF_FLAG_ERROR) != 0 || b.bytesused == 0) {
      ++corrupt_frames_;
      MOCAP_LOG(V4l2, Debug) << d.path << ": frame " << b.sequence
                             << " flagged corrupt by the driver";
      continue;  // `raw` goes back to the driver here
    }
    Frame f;
    f.view_id = options_.view_id;
    f.sequence = b.sequence;
    const bool monotonic =
        (b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    f.timestamp_ns = monotonic ? static_cast<std::int64_t>(b.timestamp.tv_sec) * 1'000'000'000 +
                                     static_cast<std::int64_t>(b.timestamp.tv_usec) * 1'000
                               : monotonic_ns();
    f.width_px = mode_.width_px;
    f.height_px = mode_.height_px;
    f.format = delivered_format(mode_.format);
    if (mode_.format == PixelFormat::kMJPEG || mode_.format == PixelFormat::kGREY) {
      // Converted on the CPU; the driver buffer goes back when `raw` goes out of scope.
      Result<std::shared_ptr<const FrameBuffer>> rgb = convert_to_rgb24(
          mode_.format, raw->bytes(), stride_bytes_, f.width_px, f.height_px, d.path);
      if (!rgb) {
        ++corrupt_frames_;
        MOCAP_LOG(V4l2, Warn) << "frame " << b.sequence << " dropped: " << rgb.error().message();
        continue;
      }
      f.stride_bytes = f.width_px * 3;
      f.buffer = std::move(*rgb);
    } else {
      f.stride_bytes = stride_bytes_;
      f.buffer = std::move(raw);  // zero-copy: re-queued when the pipeline lets go
    }
    ++frames_;
    return Capture{CaptureStatus::kFrame, std::move(f)};
  }
}

}  // namespace mocap::hal
