// CaptureRig: N cameras captured in parallel and grouped into synchronised frame sets.
//
//   auto rig = hal::CaptureRig::create(std::move(cameras), {.sync = {.cameras = n, ...}});
//   rig->start();
//   while (auto set = rig->next_set(100)) use(*set);   // nullopt: nothing within 100 ms
//
// One thread per camera dequeues frames (CameraSource::next) and pushes them into a
// FrameSynchronizer; next_set() hands out the sets as the synchroniser releases them. A camera
// that fails (an Error from next()) is reported in camera_states() and its thread ends: the
// other cameras keep running and the synchroniser stops waiting for it. Wrap cameras in
// ReconnectingCamera to have them retried instead. Camera i is view i.
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "hal/camera_source.h"
#include "hal/frame_sync.h"

namespace mocap::hal {

struct CaptureRigOptions {
  FrameSyncOptions sync;    // sync.cameras must equal the number of cameras
  int camera_poll_ms = 50;  // how long a camera thread waits in next() per call
  Status validate() const;
};

struct RigCameraState {
  std::string id;
  std::uint64_t frames = 0;
  std::uint64_t disconnected_polls = 0;  // next() calls that found the device gone
  bool failed = false;                   // next() returned an Error; the thread ended
  bool ended = false;                    // a finite source ran out
  std::string error;
};

class CaptureRig {
 public:
  static Result<std::unique_ptr<CaptureRig>> create(
      std::vector<std::unique_ptr<CameraSource>> cameras, const CaptureRigOptions& options);
  ~CaptureRig();
  CaptureRig(const CaptureRig&) = delete;
  CaptureRig& operator=(const CaptureRig&) = delete;

  // Starts every camera, then the threads. A camera that fails to start is an error naming it
  // (nothing is left running).
  Status start();
  void stop();
  // The next set, waiting at most timeout_ms; nullopt on timeout or when every camera ended or
  // failed and nothing is buffered (all_done()).
  std::optional<FrameSet> next_set(int timeout_ms);
  bool all_done() const;
  SyncStats sync_stats() const;
  std::vector<RigCameraState> camera_states() const;
  CameraSource& camera(int i) { return *cameras_[static_cast<std::size_t>(i)]; }
  int size() const { return static_cast<int>(cameras_.size()); }

 private:
  CaptureRig(std::vector<std::unique_ptr<CameraSource>> cameras, const CaptureRigOptions& options,
             FrameSynchronizer sync);
  void camera_loop(int i);
  std::vector<std::unique_ptr<CameraSource>> cameras_;
  CaptureRigOptions options_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  FrameSynchronizer sync_;
  std::deque<FrameSet> ready_;
  std::vector<RigCameraState> states_;
  std::vector<std::thread> threads_;
  std::atomic<bool> stop_{false};
  bool flushed_ = false;
};

}  // namespace mocap::hal
