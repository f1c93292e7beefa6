#include "runtime/box/take_exports.h"

#include <algorithm>
#include <fstream>

#include "runtime/core/log.h"
#include "runtime/out/animation.h"
#include "runtime/out/take_export.h"

MOCAP_LOG_CATEGORY(Exports)

namespace mocap::box {

namespace fs = std::filesystem;

TakeExports::TakeExports() : worker_([this] { run(); }) {}

TakeExports::~TakeExports() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
    queue_.clear();
  }
  wake_.notify_all();
  worker_.join();
}

void TakeExports::request(const fs::path& take_dir) {
  {
    std::lock_guard lock(mu_);
    if (busy_ == take_dir || std::find(queue_.begin(), queue_.end(), take_dir) != queue_.end()) {
      return;
    }
    queue_.push_back(take_dir);
  }
  wake_.notify_one();
}

bool TakeExports::pending(const fs::path& take_dir) const {
  std::lock_guard lock(mu_);
  return busy_ == take_dir || std::find(queue_.begin(), queue_.end(), take_dir) != queue_.end();
}

void TakeExports::run() {
  std::unique_lock lock(mu_);
  while (true) {
    wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
    if (stopping_) return;
    busy_ = queue_.front();
    queue_.pop_front();
    const fs::path dir = busy_;
    lock.unlock();
    const Status s = export_take(dir);
    if (!s.ok()) {
      MOCAP_LOG(Exports, Error) << "take " << dir.string() << ": " << s.error().message();
    }
    lock.lock();
    busy_.clear();
  }
}

Status TakeExports::export_take(const fs::path& take_dir) {
  const fs::path out_dir = take_dir / "exports";
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) return Error(ErrorCode::kIo, out_dir.string() + ": " + ec.message());
  const std::string name = take_dir.filename().string();
  auto fail = [&](const Error& e) {
    std::ofstream(out_dir / "error.txt") << e.message() << "\n";
    return e;
  };
  Result<out::ExportSource> src = out::load_take_folder(take_dir);
  if (!src.ok()) return fail(src.error());
  Result<out::Animation> anim = out::build_animation(src->data, {});
  if (!anim.ok()) return fail(anim.error());
  if (auto bvh = out::export_bvh(*src, *anim, {}, out_dir); !bvh.ok()) return fail(bvh.error());
  if (auto glb = out::export_gltf(*src, *anim, {.binary = true}, out_dir / (name + ".glb"));
      !glb.ok()) {
    return fail(glb.error());
  }
  fs::remove(out_dir / "error.txt", ec);
  MOCAP_LOG(Exports, Info) << "take " << name << ": exports written (" << anim->persons.size()
                           << " persons)";
  return Status::Ok();
}

std::vector<std::string> TakeExports::files(const fs::path& take_dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const char* f : {"skeletons.ndjson", "take.json"}) {
    if (fs::symlink_status(take_dir / f, ec).type() == fs::file_type::regular) out.emplace_back(f);
  }
  std::vector<std::string> exports;
  for (fs::directory_iterator it(take_dir / "exports", ec), end; !ec && it != end;
       it.increment(ec)) {
    const std::string f = it->path().filename().string();
    const std::string ext = it->path().extension().string();
    const bool top_name = f == "skeletons.ndjson" || f == "take.json";  // a take named "take"
    if ((ext == ".bvh" || ext == ".glb" || ext == ".json") && !top_name &&
        it->symlink_status(ec).type() == fs::file_type::regular) {
      exports.push_back(f);  // a link could point anywhere: not served
    }
  }
  std::sort(exports.begin(), exports.end());
  out.insert(out.end(), exports.begin(), exports.end());
  return out;
}

fs::path TakeExports::file_path(const fs::path& take_dir, const std::string& file) {
  // Only a listed name: never a path given by the client.
  const std::vector<std::string> all = files(take_dir);
  if (std::find(all.begin(), all.end(), file) == all.end()) return {};
  const bool top = file == "skeletons.ndjson" || file == "take.json";
  return top ? take_dir / file : take_dir / "exports" / file;
}

}  // namespace mocap::box
