// PoseDetector (runtime/gpu/pose_detector.h) on real photos (tools/fetch_test_photos.sh) with
// models/posenet.mcnn, and with MoveNet MultiPose (models/movenet-multipose.json cut at its
// heads, runtime/nn/movenet.h): the people are found where they are (regions read off the
// photos by hand), mutual-best high-affinity limbs join candidates of one person, Vulkan and
// CPU backends agree, and a two-view batch gives each view's single-view result. Skips
// without the model, the photos or a Vulkan device, except under CI=true, where it fails.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "runtime/gpu/cnn_detector.h"
#include "runtime/gpu/crop_refiner.h"
#include "runtime/gpu/pose_detector.h"
#include "runtime/image/image.h"
#include "runtime/nn/model_file.h"
#include "runtime/nn/movenet.h"
#include "runtime/nn_import/blazepose_cut.h"
#include "runtime/nn_import/movenet_cuts.h"
#include "runtime/nn_import/tfjs_import.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/data.h"

namespace mocap::gpu {
namespace {

namespace fs = std::filesystem;
const fs::path kSource = MOCAP_SOURCE_DIR;

struct Box {
  float x0, y0, x1, y1;
  bool contains(const JointCandidate& c) const {
    return c.x_px >= x0 && c.x_px <= x1 && c.y_px >= y0 && c.y_px <= y1;
  }
};

// Persons in each photo (image pixels), read off the images by hand.
struct Photo {
  std::string file;
  std::vector<Box> people;  // whole body (arms included)
  int background = -1;      // the index of a blurred person in the background (-1: none)
  Box face;                 // the main person's face (nose)
  Box shoulders;            // the main person's shoulders
  Box hips;                 // the main person's hips
};

const std::vector<Photo>& photos() {
  static const std::vector<Photo> p = {
      // 548x342: Messi (centre, kicking, his right arm stretched out to x ~ 70), a blurred
      // player behind at the right.
      {"messi5.jpg",
       {{60, 50, 470, 342}, {370, 130, 445, 260}},
       1,
       {215, 85, 270, 135},
       {180, 100, 300, 160},
       {220, 200, 320, 280}},
      // 640x480: a man holding a ball (left), a man in a flowered shirt (right, side view).
      {"basketball1.png",
       {{20, 60, 185, 480}, {420, 10, 640, 480}},
       -1,
       {65, 85, 125, 145},
       {30, 120, 150, 200},
       {40, 240, 150, 320}},
  };
  return p;
}

class PoseDetectorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const fs::path model_file = kSource / "models/posenet.mcnn";
    if (!fs::exists(model_file)) {
      MOCAP_SKIP_OR_FAIL_IN_CI("models/posenet.mcnn missing (tools/fetch_models.sh)");
    }
    auto m = nn::read_model_file(model_file);
    ASSERT_TRUE(m.ok()) << m.error().message();
    model_ = std::move(*m);
    open_device();
  }
  // The photos and a Vulkan device (skips without them).
  void open_device() {
    for (const Photo& p : photos()) {
      if (!fs::exists(kSource / ".cache/photos" / p.file)) {
        MOCAP_SKIP_OR_FAIL_IN_CI(".cache/photos/" + p.file +
                                 " missing (tools/fetch_test_photos.sh)");
      }
    }
    GpuOptions go;
    go.validation = true;
    auto c = Context::create(go);
    if (!c.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + c.error().message());
    ctx_ = std::move(*c);
  }
  void TearDown() override {
    if (ctx_) {
      EXPECT_EQ(ctx_->validation_errors(), 0) << "Vulkan validation reported errors";
    }
  }
  // What a model must find, beyond the main person's face, shoulders and hips.
  struct Expected {
    int input_size_px = 0;   // height
    int input_width_px = 0;  // 0 = the height
    // Each person (but a background one unless background_people) has a shoulder candidate
    // scoring at least this.
    float person_shoulder_score = 0.5f;
    bool background_people = true;
    int min_strong_limbs = 8;  // mutual-best limbs >= 0.5 on the main person
  };
  // Runs the detector on each photo on both backends and checks what the header says.
  void expect_people_found(const Expected& e);
  // models/<json> (tools/fetch_models.sh) imported at `cut` as the model, then the device.
  void use_tfjs_model(const std::string& json, const nn::TfjsImportOptions& cut) {
    const fs::path path = kSource / "models" / json;
    if (!fs::exists(path)) {
      MOCAP_SKIP_OR_FAIL_IN_CI("models/" + json + " missing (tools/fetch_models.sh)");
    }
    auto m = nn::import_tfjs(path, cut);
    ASSERT_TRUE(m.ok()) << m.error().message();
    model_ = std::move(*m);
    open_device();
  }

  nn::Model model_;
  std::unique_ptr<Context> ctx_;
};

// MoveNet MultiPose, imported from the TF.js graph at its heads.
class MoveNetDetectorTest : public PoseDetectorTest {
 protected:
  void SetUp() override { use_tfjs_model("movenet-multipose.json", nn::movenet_multipose_cut()); }
};

// MoveNet SinglePose Thunder on crops (runtime/gpu/crop_refiner.h).
class CropRefinerTest : public PoseDetectorTest {
 protected:
  void SetUp() override { use_tfjs_model("movenet-thunder.json", nn::movenet_singlepose_cut()); }
};

// BlazePose full's landmark model on crops (runtime/gpu/crop_refiner.h): the feet too.
class BlazePoseCropTest : public PoseDetectorTest {
 protected:
  void SetUp() override { use_tfjs_model("blazepose-full.json", nn::blazepose_landmarks_cut()); }
};

// The photo's main person cropped as MediaPipe frames them (crops::CropFraming::kHipCentred):
// on the hips, 2.5 times the farthest side of the person's box from them.
CropRequest hip_centred_crop(const Photo& p, int frame) {
  const Box& b = p.people[0];
  const double hx = 0.5 * static_cast<double>(p.hips.x0 + p.hips.x1);
  const double hy = 0.5 * static_cast<double>(p.hips.y0 + p.hips.y1);
  const double reach = std::max({hx - static_cast<double>(b.x0), static_cast<double>(b.x1) - hx,
                                 hy - static_cast<double>(b.y0), static_cast<double>(b.y1) - hy});
  return {frame, hx, hy, 2.5 * reach};
}

int count_in(const std::vector<JointCandidate>& list, const Box& b, float min_score) {
  return static_cast<int>(std::count_if(list.begin(), list.end(), [&](const JointCandidate& c) {
    return c.score > min_score && b.contains(c);
  }));
}

TEST_F(PoseDetectorTest, FindsThePeopleAndLinksLimbsWithinAPerson) {
  expect_people_found({353, 0, 0.5f, true, 8});
}

// MoveNet at 256 does not find the blurred player behind Messi, and scores the side-view man
// in basketball1 lower than PoseNet (best shoulders 0.47 and 0.38, measured).
TEST_F(MoveNetDetectorTest, FindsThePeopleAndLinksLimbsWithinAPerson) {
  expect_people_found({256, 0, 0.3f, false, 8});
}

// Inputs fitted to the photos' landscape aspect (the border of the square cut off): the same
// people found, the Vulkan network and decoding matching the CPU reference on a non-square
// input.
TEST_F(PoseDetectorTest, FindsThePeopleOnAnInputFittedToTheFrame) {
  expect_people_found({273, 353, 0.5f, true, 8});
}

TEST_F(MoveNetDetectorTest, FindsThePeopleOnAnInputFittedToTheFrame) {
  expect_people_found({192, 256, 0.3f, false, 8});
}

// Opened the way the tools open it (the model file, the size from a config): a PoseNet size
// for MoveNet is an error naming the rule and the default, before any shape is computed.
TEST(CnnDetectorOpen, MoveNetSizeNotAMultipleOf32NamesTheRule) {
  const fs::path model = kSource / "models/movenet-multipose.mcnn";
  if (!fs::exists(model)) MOCAP_SKIP_OR_FAIL_IN_CI("models/movenet-multipose.mcnn missing");
  CnnOptions o;
  o.model = model;
  o.backend = BackendRequest::kCpu;
  o.input_size_px = 65;
  auto det = CnnDetector::open(o);
  ASSERT_FALSE(det.ok());
  EXPECT_NE(det.error().message().find("multiple of 32"), std::string::npos)
      << det.error().message();
  EXPECT_NE(det.error().message().find("448"), std::string::npos) << det.error().message();
  o.input_size_px = 64;
  o.frame_width_px = 320;  // the HIL guest's vivid cameras: 64x64 (36 rounds up to 64)
  o.frame_height_px = 180;
  auto small = CnnDetector::open(o);
  ASSERT_TRUE(small.ok()) << small.error().message();
  EXPECT_EQ((*small)->input_shape(), (InputShape{64, 64}));
  o.input_size_px = 0;
  o.frame_width_px = 1088;
  o.frame_height_px = 1920;
  auto def = CnnDetector::open(o);
  ASSERT_TRUE(def.ok()) << def.error().message();
  EXPECT_EQ((*def)->input_shape(), (InputShape{256, 448}));
  EXPECT_NE((*def)->description().find("256x448 px"), std::string::npos) << (*def)->description();
}

// A driver reporting less than the spec's minimum limits (injected: MOCAP_FAULT_DEVICE_LIMITS)
// is named with the limit and the fix when Vulkan is asked for; "auto" runs the CNN on the CPU
// and says why. A bad injection is an error naming the variable.
TEST(CnnDetectorOpen, ADriverBelowTheMinimumLimitsIsNamedAndAutoFallsBackToTheCpu) {
  const fs::path model = kSource / "models/posenet.mcnn";
  if (!fs::exists(model)) MOCAP_SKIP_OR_FAIL_IN_CI("models/posenet.mcnn missing");
  {
    auto probe = Context::create(GpuOptions{});
    if (!probe.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + probe.error().message());
  }
  struct Unset {
    ~Unset() { ::unsetenv("MOCAP_FAULT_DEVICE_LIMITS"); }
  } unset;
  ::setenv("MOCAP_FAULT_DEVICE_LIMITS", "maxPerStageDescriptorStorageBuffers=2", 1);
  CnnOptions o;
  o.model = model;
  o.backend = BackendRequest::kVulkan;
  auto vulkan = CnnDetector::open(o);
  ASSERT_FALSE(vulkan.ok());
  const std::string why = vulkan.error().message();
  EXPECT_NE(why.find("maxPerStageDescriptorStorageBuffers"), std::string::npos) << why;
  EXPECT_NE(why.find("update the GPU driver"), std::string::npos) << why;
  o.backend = BackendRequest::kAuto;
  auto fallback = CnnDetector::open(o);
  ASSERT_TRUE(fallback.ok()) << fallback.error().message();
  EXPECT_NE((*fallback)->fallback_reason().find("maxPerStageDescriptorStorageBuffers"),
            std::string::npos)
      << (*fallback)->fallback_reason();
  EXPECT_NE((*fallback)->description().find("CPU"), std::string::npos)
      << (*fallback)->description();
  for (const char* bad : {"maxNothing=1", "maxPushConstantsSize", "maxPushConstantsSize=-4"}) {
    ::setenv("MOCAP_FAULT_DEVICE_LIMITS", bad, 1);
    auto ctx = Context::create(GpuOptions{});
    ASSERT_FALSE(ctx.ok()) << bad;
    EXPECT_NE(ctx.error().message().find("MOCAP_FAULT_DEVICE_LIMITS"), std::string::npos)
        << ctx.error().message();
  }
}

// Crops need the cameras and a single-person model; opened, the description says so and the
// detector asks the pipeline for the tracks. Before any track, detections are the bottom-up
// ones alone.
TEST(CnnDetectorOpen, CropsNeedCamerasAndASinglePersonModel) {
  const fs::path model = kSource / "models/movenet-multipose.mcnn";
  const fs::path thunder = kSource / "models/movenet-thunder.mcnn";
  if (!fs::exists(model) || !fs::exists(thunder)) {
    MOCAP_SKIP_OR_FAIL_IN_CI("models/movenet-multipose.mcnn or movenet-thunder.mcnn missing");
  }
  CnnOptions o;
  o.model = model;
  o.backend = BackendRequest::kCpu;
  o.input_size_px = 64;
  o.crop_model = thunder;
  auto no_cameras = CnnDetector::open(o);
  ASSERT_FALSE(no_cameras.ok());
  EXPECT_NE(no_cameras.error().message().find("cameras"), std::string::npos);
  o.cameras = {Camera()};
  o.crop_model = model;
  auto same = CnnDetector::open(o);
  ASSERT_FALSE(same.ok());
  EXPECT_NE(same.error().message().find("single-person"), std::string::npos);
  o.crop_model = thunder;
  o.crop_input_size_px = 100;
  EXPECT_FALSE(CnnDetector::open(o).ok());
  o.crop_input_size_px = 64;
  auto det = CnnDetector::open(o);
  ASSERT_TRUE(det.ok()) << det.error().message();
  EXPECT_TRUE((*det)->wants_tracks());
  EXPECT_NE((*det)->description().find("movenet-thunder crops 64 px"), std::string::npos)
      << (*det)->description();
}

TEST_F(MoveNetDetectorTest, SizesMustBeMultiplesOf32) {
  PoseDetectorOptions o;
  o.input_size_px = 257;
  auto det = PoseDetector::create(model_, o, ctx_.get());
  ASSERT_FALSE(det.ok());
  EXPECT_NE(det.error().message().find("multiple of 32"), std::string::npos)
      << det.error().message();
}

void PoseDetectorTest::expect_people_found(const Expected& e) {
  const SkeletonTopology& topo = coco17_topology();
  for (const Photo& photo : photos()) {
    SCOPED_TRACE(photo.file);
    auto img = image::load_image(kSource / ".cache/photos" / photo.file);
    ASSERT_TRUE(img.ok()) << img.error().message();
    const nn::FrameView frame{img->rgb, img->width_px, img->height_px, 0, PixelFormat::kRGB24};
    const int id = 7;
    std::vector<ViewDetections> per_backend;
    std::vector<PoseBackend> backends = {PoseBackend::kVulkan, PoseBackend::kCpu};
    if (::mocap::testing::driver_run()) backends.pop_back();  // the CPU was checked once
    for (PoseBackend backend : backends) {
      PoseDetectorOptions o;
      o.backend = backend;
      o.input_size_px = e.input_size_px;
      o.input_width_px = e.input_width_px;
      auto det = PoseDetector::create(model_, o, ctx_.get());
      ASSERT_TRUE(det.ok()) << det.error().message();
      auto set = (*det)->detect({&frame, 1}, {&id, 1}, 42);
      ASSERT_TRUE(set.ok()) << set.error().message();
      EXPECT_TRUE(set->validate().ok());
      ASSERT_EQ(set->views.size(), 1u);
      EXPECT_EQ(set->views[0].view_id, id);
      EXPECT_EQ(set->frame_id, 42u);
      per_backend.push_back(set->views[0]);
    }
    const ViewDetections& v = per_backend[0];
    const auto& c = v.candidates;
    const int nose = topo.find_joint("nose");
    EXPECT_EQ(count_in(c[static_cast<std::size_t>(nose)], photo.face, 0.5f), 1);
    for (const char* j : {"l_shoulder", "r_shoulder"}) {
      EXPECT_EQ(count_in(c[static_cast<std::size_t>(topo.find_joint(j))], photo.shoulders, 0.5f), 1)
          << j;
    }
    for (const char* j : {"l_hip", "r_hip"}) {
      EXPECT_EQ(count_in(c[static_cast<std::size_t>(topo.find_joint(j))], photo.hips, 0.5f), 1)
          << j;
    }
    // Every person has shoulder candidates above the score.
    for (std::size_t p = 0; p < photo.people.size(); ++p) {
      if (static_cast<int>(p) == photo.background && !e.background_people) continue;
      const float score = e.person_shoulder_score;
      EXPECT_GE(count_in(c[static_cast<std::size_t>(topo.find_joint("l_shoulder"))],
                         photo.people[p], score) +
                    count_in(c[static_cast<std::size_t>(topo.find_joint("r_shoulder"))],
                             photo.people[p], score),
                1)
          << "person " << p;
    }
    // Mutual-best limbs with affinity >= 0.5 join two candidates of the same person (or two
    // candidates outside every person, e.g. the crowd).
    auto person_of = [&](const JointCandidate& jc) {
      for (std::size_t p = 0; p < photo.people.size(); ++p) {
        if (photo.people[p].contains(jc)) return static_cast<int>(p);
      }
      return -1;
    };
    int strong = 0;
    for (int l = 0; l < topo.limb_count(); ++l) {
      const AffinityMatrix& m = v.affinities[static_cast<std::size_t>(l)];
      const Limb& limb = topo.limb(l);
      for (int r = 0; r < m.rows; ++r) {
        for (int k = 0; k < m.cols; ++k) {
          const float a = m.at(r, k);
          bool best = a >= 0.5f;
          for (int i = 0; i < m.cols && best; ++i) best = m.at(r, i) <= a;
          for (int i = 0; i < m.rows && best; ++i) best = m.at(i, k) <= a;
          if (!best) continue;
          const auto& ca = c[static_cast<std::size_t>(limb.joint_a)][static_cast<std::size_t>(r)];
          const auto& cb = c[static_cast<std::size_t>(limb.joint_b)][static_cast<std::size_t>(k)];
          EXPECT_EQ(person_of(ca), person_of(cb))
              << topo.limb_name(l) << " joins (" << ca.x_px << ", " << ca.y_px << ") and ("
              << cb.x_px << ", " << cb.y_px << ") with affinity " << a;
          if (person_of(ca) == 0) ++strong;
        }
      }
    }
    EXPECT_GE(strong, e.min_strong_limbs) << "strong limbs on the main person";
    EXPECT_GE(nn::limb_chains(v, topo).size(), 1u);
    // The CPU backend finds the same candidates.
    if (per_backend.size() < 2) continue;
    const ViewDetections& cpu = per_backend[1];
    for (std::size_t j = 0; j < c.size(); ++j) {
      ASSERT_EQ(c[j].size(), cpu.candidates[j].size()) << topo.joint_name(static_cast<int>(j));
      for (std::size_t i = 0; i < c[j].size(); ++i) {
        EXPECT_NEAR(c[j][i].x_px, cpu.candidates[j][i].x_px, 0.05f);
        EXPECT_NEAR(c[j][i].y_px, cpu.candidates[j][i].y_px, 0.05f);
        EXPECT_NEAR(c[j][i].score, cpu.candidates[j][i].score, 1e-3f);
      }
    }
  }
}

TEST_F(PoseDetectorTest, TwoViewBatchMatchesSingleViews) {
  std::vector<image::ImageRgb8> imgs;
  std::vector<nn::FrameView> frames;
  for (const Photo& p : photos()) {
    auto img = image::load_image(kSource / ".cache/photos" / p.file);
    ASSERT_TRUE(img.ok());
    imgs.push_back(std::move(*img));
  }
  for (const auto& img : imgs) {
    frames.push_back({img.rgb, img.width_px, img.height_px, 0, PixelFormat::kRGB24});
  }
  PoseDetectorOptions o;
  o.max_views = 2;
  o.input_size_px = 257;
  auto det = PoseDetector::create(model_, o, ctx_.get());
  ASSERT_TRUE(det.ok()) << det.error().message();
  const int ids[2] = {3, 5};
  auto both = (*det)->detect(frames, ids);
  ASSERT_TRUE(both.ok()) << both.error().message();
  ASSERT_EQ(both->views.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    auto one = (*det)->detect({&frames[i], 1}, {&ids[i], 1});
    ASSERT_TRUE(one.ok());
    const ViewDetections& a = both->views[i];
    const ViewDetections& b = one->views[0];
    EXPECT_EQ(a.view_id, ids[i]);
    for (std::size_t j = 0; j < a.candidates.size(); ++j) {
      ASSERT_EQ(a.candidates[j].size(), b.candidates[j].size());
      for (std::size_t k = 0; k < a.candidates[j].size(); ++k) {
        EXPECT_NEAR(a.candidates[j][k].x_px, b.candidates[j][k].x_px, 1e-3f);
      }
    }
  }
  // Bad calls are errors, not crashes.
  const int dup[2] = {1, 1};
  EXPECT_FALSE((*det)->detect(frames, dup).ok());
  std::vector<std::uint8_t> odd(100, 0);
  const nn::FrameView bad{odd, 5, 4, 0, PixelFormat::kYUYV};
  const int id = 0;
  auto r = (*det)->detect({&bad, 1}, {&id, 1});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("even"), std::string::npos) << r.error().message();
}

// A frame of more views than the network runs at once (max_views_per_run, or what the device's
// maxStorageBufferRange allows) runs them in turns (here 2 + 1) and finds what one run finds.
TEST_F(PoseDetectorTest, ViewsRunInTurnsFindWhatOneRunFinds) {
  std::vector<image::ImageRgb8> imgs;
  for (const Photo& p : photos()) {
    auto img = image::load_image(kSource / ".cache/photos" / p.file);
    ASSERT_TRUE(img.ok());
    imgs.push_back(std::move(*img));
  }
  std::vector<nn::FrameView> frames;
  for (int i = 0; i < 3; ++i) {
    const image::ImageRgb8& img = imgs[static_cast<std::size_t>(i) % imgs.size()];
    frames.push_back({img.rgb, img.width_px, img.height_px, 0, PixelFormat::kRGB24});
  }
  const int ids[3] = {0, 1, 2};
  std::vector<DetectionSet> sets;
  for (int per_run : {0, 2}) {
    PoseDetectorOptions o;
    o.max_views = 3;
    o.max_views_per_run = per_run;
    o.input_size_px = 257;
    auto det = PoseDetector::create(model_, o, ctx_.get());
    ASSERT_TRUE(det.ok()) << det.error().message();
    EXPECT_EQ((*det)->kernel_plan().views_per_run, per_run == 0 ? 3 : per_run);
    auto set = (*det)->detect(frames, ids);
    ASSERT_TRUE(set.ok()) << set.error().message();
    sets.push_back(std::move(*set));
  }
  for (std::size_t s = 1; s < sets.size(); ++s) {
    ASSERT_EQ(sets[s].views.size(), 3u);
    for (std::size_t v = 0; v < 3; ++v) {
      const ViewDetections& a = sets[0].views[v];
      const ViewDetections& b = sets[s].views[v];
      EXPECT_EQ(b.view_id, ids[v]);
      for (std::size_t j = 0; j < a.candidates.size(); ++j) {
        ASSERT_EQ(a.candidates[j].size(), b.candidates[j].size()) << "set " << s << " view " << v;
        for (std::size_t k = 0; k < a.candidates[j].size(); ++k) {
          EXPECT_NEAR(a.candidates[j][k].x_px, b.candidates[j][k].x_px, 1e-3f);
          EXPECT_NEAR(a.candidates[j][k].score, b.candidates[j][k].score, 1e-5f);
        }
      }
      for (std::size_t l = 0; l < a.affinities.size(); ++l) {
        ASSERT_EQ(a.affinities[l].values.size(), b.affinities[l].values.size());
        for (std::size_t k = 0; k < a.affinities[l].values.size(); ++k) {
          EXPECT_NEAR(a.affinities[l].values[k], b.affinities[l].values[k], 1e-4f);
        }
      }
    }
  }
  PoseDetectorOptions bad;
  bad.max_views = 2;
  bad.max_views_per_run = 3;
  auto r = PoseDetector::create(model_, bad, ctx_.get());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("max_views_per_run 3"), std::string::npos)
      << r.error().message();
}

// MoveNet at 640 px needs 56 MiB a view in its largest buffer: eight views (450 MiB) are more
// than a device may bind (maxStorageBufferRange, 128 MiB at the spec's minimum and on lavapipe),
// so the network is planned for the most views that fit and a frame runs in turns.
TEST_F(MoveNetDetectorTest, EightViewsAt640RunInTurnsWithinMaxStorageBufferRange) {
  PoseDetectorOptions o;
  o.max_views = 8;
  o.input_size_px = 640;
  auto det = PoseDetector::create(model_, o, ctx_.get());
  ASSERT_TRUE(det.ok()) << det.error().message();
  const PoseDetector::KernelPlan plan = (*det)->kernel_plan();
  const std::uint64_t limit = ctx_->device_info().limits.max_storage_buffer_range;
  ASSERT_GE(plan.views_per_run, 1);
  const std::uint64_t per_view =
      plan.largest_buffer_bytes / static_cast<std::uint64_t>(plan.views_per_run);
  EXPECT_EQ(per_view, 56u * 1048576u + 262144u) << "MoveNet at 640: 320x320x144 floats a view";
  EXPECT_LE(plan.largest_buffer_bytes, limit);
  // As many views as fit (2 within lavapipe's and the spec's 128 MiB; SwiftShader binds 1 GiB).
  EXPECT_EQ(static_cast<std::uint64_t>(plan.views_per_run),
            std::min<std::uint64_t>(8, limit / per_view));
  std::printf("[ plan ] MoveNet 640, 8 views: %d views per run, largest buffer %.1f MiB of %u\n",
              plan.views_per_run, static_cast<double>(plan.largest_buffer_bytes) / 1048576.0,
              static_cast<unsigned>(limit >> 20));
}

// A crop around each photo's main person (from its hand-read box) finds that person's face,
// shoulders and hips, on both backends alike (one batch of both crops; the crops map back to
// image pixels); a crop off the frame or of a frame not given is an error, not a crash.
TEST_F(CropRefinerTest, FindsThePersonInItsCropOnBothBackends) {
  std::vector<image::ImageRgb8> images;
  std::vector<nn::FrameView> views;
  std::vector<CropRequest> crops;
  for (const Photo& p : photos())
    images.push_back(*image::load_image(kSource / ".cache/photos" / p.file));
  for (std::size_t i = 0; i < images.size(); ++i) {
    const image::ImageRgb8& img = images[i];
    views.push_back(nn::FrameView{img.rgb, img.width_px, img.height_px, 0, PixelFormat::kRGB24});
    const Box& b = photos()[i].people[0];
    crops.push_back({static_cast<int>(i), 0.5 * static_cast<double>(b.x0 + b.x1),
                     0.5 * static_cast<double>(b.y0 + b.y1),
                     1.1 * static_cast<double>(std::max(b.x1 - b.x0, b.y1 - b.y0))});
  }
  std::vector<std::vector<CropPose>> by_backend;
  for (PoseBackend backend : {PoseBackend::kVulkan, PoseBackend::kCpu}) {
    CropRefinerOptions o;
    o.backend = backend;
    auto r = CropRefiner::create(model_, o, ctx_.get());
    ASSERT_TRUE(r.ok()) << r.error().message();
    auto poses = (*r)->run(views, crops);
    ASSERT_TRUE(poses.ok()) << poses.error().message();
    ASSERT_EQ(poses->size(), crops.size());
    by_backend.push_back(std::move(*poses));
    const CropRequest bad_side[1] = {{0, 10, 10, 0}};
    EXPECT_FALSE((*r)->run(views, bad_side).ok());
    const CropRequest bad_frame[1] = {{5, 10, 10, 100}};
    EXPECT_FALSE((*r)->run(views, bad_frame).ok());
  }
  for (std::size_t i = 0; i < crops.size(); ++i) {
    const Photo& p = photos()[i];
    SCOPED_TRACE(p.file);
    const std::vector<JointCandidate>& j = by_backend[0][i].joints;
    ASSERT_EQ(j.size(), 17u);
    EXPECT_TRUE(p.face.contains(j[0])) << j[0].x_px << ", " << j[0].y_px;
    EXPECT_TRUE(p.shoulders.contains(j[5]) && p.shoulders.contains(j[6]));
    EXPECT_TRUE(p.hips.contains(j[11]) && p.hips.contains(j[12]));
    for (std::size_t k = 0; k < j.size(); ++k) {
      const JointCandidate& c = by_backend[1][i].joints[k];
      EXPECT_NEAR(j[k].x_px, c.x_px, 0.5f) << "joint " << k;
      EXPECT_NEAR(j[k].y_px, c.y_px, 0.5f) << "joint " << k;
      EXPECT_NEAR(j[k].score, c.score, 1e-3f) << "joint " << k;
    }
    EXPECT_TRUE(by_backend[0][i].feet.empty()) << "MoveNet has no feet";
  }
}

// The same photos' people, cropped as MediaPipe frames them (crops::CropFraming::kHipCentred:
// on the hips, 2.5x the farthest part of the person): the joints where the photos have them,
// the four foot points below the shoulders and in the person's box, Vulkan and CPU agreeing.
// BlazePose takes 256x256 crops only.
TEST_F(BlazePoseCropTest, FindsThePersonAndTheFeetInItsCropOnBothBackends) {
  std::vector<image::ImageRgb8> images;
  std::vector<nn::FrameView> views;
  std::vector<CropRequest> crops;
  for (const Photo& p : photos())
    images.push_back(*image::load_image(kSource / ".cache/photos" / p.file));
  for (std::size_t i = 0; i < images.size(); ++i) {
    const image::ImageRgb8& img = images[i];
    views.push_back(nn::FrameView{img.rgb, img.width_px, img.height_px, 0, PixelFormat::kRGB24});
    crops.push_back(hip_centred_crop(photos()[i], static_cast<int>(i)));
  }
  std::vector<std::vector<CropPose>> by_backend;
  for (PoseBackend backend : {PoseBackend::kVulkan, PoseBackend::kCpu}) {
    CropRefinerOptions o;
    o.backend = backend;
    auto r = CropRefiner::create(model_, o, ctx_.get());
    ASSERT_TRUE(r.ok()) << r.error().message();
    auto poses = (*r)->run(views, crops);
    ASSERT_TRUE(poses.ok()) << poses.error().message();
    by_backend.push_back(std::move(*poses));
    o.input_size_px = 192;
    EXPECT_FALSE(CropRefiner::create(model_, o, ctx_.get()).ok());
  }
  for (std::size_t i = 0; i < crops.size(); ++i) {
    const Photo& p = photos()[i];
    SCOPED_TRACE(p.file);
    const CropPose& pose = by_backend[0][i];
    EXPECT_GT(pose.center_score, 0.5f);
    ASSERT_EQ(pose.joints.size(), 17u);
    ASSERT_EQ(pose.feet.size(), 4u);
    EXPECT_TRUE(p.face.contains(pose.joints[0]))
        << pose.joints[0].x_px << ", " << pose.joints[0].y_px;
    EXPECT_TRUE(p.shoulders.contains(pose.joints[5]) && p.shoulders.contains(pose.joints[6]));
    EXPECT_TRUE(p.hips.contains(pose.joints[11]) && p.hips.contains(pose.joints[12]));
    // Within the person's box (hand-drawn, the image's edge for basketball1, whose toes the
    // model places just past it: 5 % of slack) and below the shoulders (Messi kicks: his
    // raised foot is level with his hips).
    const Box& b = p.people[0];
    const float slack = 0.05f * (b.y1 - b.y0);
    const Box near{b.x0 - slack, b.y0 - slack, b.x1 + slack, b.y1 + slack};
    for (const JointCandidate& f : pose.feet) {
      EXPECT_GT(f.y_px, p.shoulders.y1) << "a foot point above the shoulders";
      EXPECT_TRUE(near.contains(f)) << f.x_px << ", " << f.y_px;
      std::printf("[ blazepose ] %s foot point (%.0f, %.0f) px, score %.2f\n", p.file.c_str(),
                  static_cast<double>(f.x_px), static_cast<double>(f.y_px),
                  static_cast<double>(f.score));
    }
    const CropPose& cpu = by_backend[1][i];
    for (std::size_t k = 0; k < pose.feet.size(); ++k) {
      EXPECT_NEAR(pose.feet[k].x_px, cpu.feet[k].x_px, 0.5f) << "foot " << k;
      EXPECT_NEAR(pose.feet[k].y_px, cpu.feet[k].y_px, 0.5f) << "foot " << k;
      EXPECT_NEAR(pose.feet[k].score, cpu.feet[k].score, 1e-3f) << "foot " << k;
    }
    for (std::size_t k = 0; k < pose.joints.size(); ++k) {
      EXPECT_NEAR(pose.joints[k].x_px, cpu.joints[k].x_px, 0.5f) << "joint " << k;
      EXPECT_NEAR(pose.joints[k].y_px, cpu.joints[k].y_px, 0.5f) << "joint " << k;
    }
  }
}

// Feet the image does not show are reported not observed, never invented: the same photos cut
// below the hips (the frame ends there, so the hip-centred crop reaches past the image's edge
// into black border). The shoulders are still found; a foot point placed outside the frame or
// on its last rows scores 0 (BlazePose itself put Messi's cut-off right heel 2 px above the
// cut with visibility x presence 0.92), one inside it (Messi's raised foot, level with his
// hips) is kept.
TEST_F(BlazePoseCropTest, FeetOutsideTheImageAreNotObserved) {
  for (const Photo& p : photos()) {
    SCOPED_TRACE(p.file);
    const image::ImageRgb8 img = *image::load_image(kSource / ".cache/photos" / p.file);
    const int rows = static_cast<int>(p.hips.y1) + 10;  // a frame that ends below the hips
    const nn::FrameView cut{std::span(img.rgb).first(static_cast<std::size_t>(rows) *
                                                     static_cast<std::size_t>(img.width_px) * 3),
                            img.width_px, rows, 0, PixelFormat::kRGB24};
    const CropRequest crop[1] = {hip_centred_crop(p, 0)};
    CropRefinerOptions o;
    auto r = CropRefiner::create(model_, o, ctx_.get());
    ASSERT_TRUE(r.ok()) << r.error().message();
    const nn::FrameView views[1] = {cut};
    auto poses = (*r)->run(views, crop);
    ASSERT_TRUE(poses.ok()) << poses.error().message();
    const CropPose& pose = (*poses)[0];
    EXPECT_TRUE(p.shoulders.contains(pose.joints[5]) && p.shoulders.contains(pose.joints[6]));
    int outside = 0;
    for (const JointCandidate& f : pose.feet) {
      std::printf("[ blazepose ] %s cut below the hips: foot point (%.0f, %.0f) score %.2f\n",
                  p.file.c_str(), static_cast<double>(f.x_px), static_cast<double>(f.y_px),
                  static_cast<double>(f.score));
      if (f.y_px >= static_cast<float>(rows) - 5.f) {
        ++outside;
        EXPECT_EQ(f.score, 0.f) << "a foot invented outside the image";
      }
    }
    EXPECT_GE(outside, 2) << "the cut-off foot";
  }
}

}  // namespace
}  // namespace mocap::gpu
