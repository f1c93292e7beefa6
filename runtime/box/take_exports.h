// The downloads of a take on the box's page (docs/web.md): when a take ends, a background
// thread writes its exports next to it — <take>/exports/<take>_person<id>.bvh (one per person,
// centimetres) with their sidecar <take>.bvh.json, and <take>/exports/<take>.glb (every person)
// with <take>.glb.json — with the same code as `mocap export` (runtime/out/take_export.h). Nothing
// runs on the HTTP or pipeline threads; an export that fails leaves its reason in
// <take>/exports/error.txt and the take itself untouched.
#pragma once

#include <condition_variable>
#include <deque>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::box {

class TakeExports {
 public:
  TakeExports();
  ~TakeExports();  // finishes the export in progress, drops the queued ones
  TakeExports(const TakeExports&) = delete;
  TakeExports& operator=(const TakeExports&) = delete;

  // Queues the take folder (again queued: once).
  void request(const std::filesystem::path& take_dir);
  bool pending(const std::filesystem::path& take_dir) const;

  // Writes the exports of one take now (the worker's job; tests).
  static Status export_take(const std::filesystem::path& take_dir);
  // The files a take offers for download: skeletons.ndjson, take.json, then its exports.
  static std::vector<std::string> files(const std::filesystem::path& take_dir);
  // The path of `file` of the take, when it is one of files(); empty otherwise.
  static std::filesystem::path file_path(const std::filesystem::path& take_dir,
                                         const std::string& file);

 private:
  void run();
  mutable std::mutex mu_;
  std::condition_variable wake_;
  std::deque<std::filesystem::path> queue_;
  std::filesystem::path busy_;
  bool stopping_ = false;
  std::thread worker_;
};

}  // namespace mocap::box
