#include "tools/mocap/board_frames.h"

#include <glob.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "hal/replay/video_decoder.h"
#include "runtime/image/image.h"

namespace mocap::tools {
namespace {

// Luma (BT.601) of packed RGB rows into a tight grey buffer.
void to_gray(const std::uint8_t* rgb, int width, int height, int stride,
             std::vector<std::uint8_t>& gray) {
  gray.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row = rgb + static_cast<std::size_t>(y) * static_cast<std::size_t>(stride);
    std::uint8_t* out = gray.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    for (int x = 0; x < width; ++x) {
      const int v = 77 * row[3 * x] + 150 * row[3 * x + 1] + 29 * row[3 * x + 2];
      out[x] = static_cast<std::uint8_t>((v + 128) >> 8);
    }
  }
}

Result<std::vector<std::string>> expand_glob(const std::string& pattern) {
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
  std::vector<std::string> files;
  if (rc == 0) {
    for (std::size_t i = 0; i < g.gl_pathc; ++i) files.emplace_back(g.gl_pathv[i]);
  }
  globfree(&g);
  if (files.empty()) {
    return Error(ErrorCode::kNotFound, "--images: \"" + pattern + "\" matches no file");
  }
  std::sort(files.begin(), files.end());
  return files;
}

Result<boardcal::CameraFrames> camera_from_images(const std::string& view, const std::string& glob,
                                                  const boardcal::BoardDetector& detector,
                                                  int max_frames) {
  auto files = expand_glob(glob);
  if (!files.ok()) return files.error();
  boardcal::CameraFrames cam;
  cam.view_id = view;
  std::vector<std::uint8_t> gray;
  for (const auto& file : *files) {
    if (max_frames > 0 && static_cast<int>(cam.frames.size()) >= max_frames) break;
    auto img = image::load_image(file);
    if (!img.ok()) return img.error().with_context("camera " + view);
    if (cam.frames.empty()) {
      cam.width_px = img->width_px;
      cam.height_px = img->height_px;
    } else if (img->width_px != cam.width_px || img->height_px != cam.height_px) {
      return Error(
          ErrorCode::kInvalidArgument,
          file + ": " + std::to_string(img->width_px) + "x" + std::to_string(img->height_px) +
              " but camera " + view + "'s first image is " + std::to_string(cam.width_px) + "x" +
              std::to_string(cam.height_px) + ": one glob per camera, all its images of one size");
    }
    to_gray(img->rgb.data(), img->width_px, img->height_px, img->width_px * 3, gray);
    cam.frames.push_back(
        detector.detect({gray.data(), img->width_px, img->height_px, img->width_px}));
  }
  return cam;
}

Result<boardcal::CameraFrames> camera_from_video(const std::string& view,
                                                 const std::filesystem::path& path,
                                                 const boardcal::BoardDetector& detector,
                                                 int max_frames) {
  auto dec = hal::VideoDecoder::open(path);
  if (!dec.ok()) return dec.error();
  boardcal::CameraFrames cam;
  cam.view_id = view;
  hal::VideoFrame f;
  std::vector<std::uint8_t> gray;
  while (max_frames <= 0 || static_cast<int>(cam.frames.size()) < max_frames) {
    auto more = (*dec)->next(f);
    if (!more.ok()) return more.error();
    if (!*more) break;
    cam.width_px = f.width_px;
    cam.height_px = f.height_px;
    to_gray(f.rgb.data(), f.width_px, f.height_px, f.stride_bytes, gray);
    cam.frames.push_back(detector.detect({gray.data(), f.width_px, f.height_px, f.width_px}));
  }
  if (cam.frames.empty()) {
    return Error(ErrorCode::kParse, path.string() + ": no frames (an empty or damaged video)");
  }
  return cam;
}

std::vector<std::string> split_commas(const std::string& s) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= s.size()) {
    const std::size_t comma = std::min(s.find(',', start), s.size());
    if (comma > start) out.push_back(s.substr(start, comma - start));
    start = comma + 1;
  }
  return out;
}

}  // namespace

Result<std::vector<boardcal::CameraFrames>> collect_board_frames(
    const BoardFrameSource& src, const boardcal::BoardDetector& detector) {
  std::vector<boardcal::CameraFrames> cams;
  if (!src.images.empty()) {
    const auto globs = split_commas(src.images);
    for (std::size_t v = 0; v < globs.size(); ++v) {
      auto cam = camera_from_images(std::to_string(v), globs[v], detector, src.max_frames);
      if (!cam.ok()) return cam.error();
      cams.push_back(std::move(*cam));
    }
    return cams;
  }
  const std::filesystem::path videos = std::filesystem::path(src.recording) / "videos";
  std::vector<int> ids;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(videos, ec)) {
    const std::string stem = e.path().stem().string();
    if (e.path().extension() != ".mp4" || stem.empty() ||
        !std::all_of(stem.begin(), stem.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      continue;
    }
    ids.push_back(std::stoi(stem));
  }
  if (ec || ids.empty()) {
    return Error(ErrorCode::kNotFound, videos.string() +
                                           ": no videos N.mp4 (a recording folder holds "
                                           "videos/0.mp4, videos/1.mp4, ...)");
  }
  std::sort(ids.begin(), ids.end());
  for (int id : ids) {
    const auto path = videos / (std::to_string(id) + ".mp4");
    std::fprintf(stderr, "reading %s\n", path.c_str());
    auto cam = camera_from_video(std::to_string(id), path, detector, src.max_frames);
    if (!cam.ok()) return cam.error();
    cams.push_back(std::move(*cam));
  }
  return cams;
}

}  // namespace mocap::tools
