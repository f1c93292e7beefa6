#include "runtime/nn/blazepose.h"

#include <cmath>
#include <string>

namespace mocap::nn {

namespace {

float sigmoid(float v) { return 1.f / (1.f + std::exp(-v)); }

}  // namespace

bool is_blazepose(const Model& model) {
  auto has = [&](const char* name) {
    for (const ModelOutput& o : model.outputs) {
      if (o.name == name) return true;
    }
    return false;
  };
  return has(kBlazePoseLandmarksOutput) && has(kBlazePoseFlagOutput);
}

Result<BlazePosePose> blazepose_decode_cpu(const Tensor& landmarks, const Tensor& flag, int n) {
  const Shape& ls = landmarks.shape;
  const Shape& fs = flag.shape;
  const long per_item = static_cast<long>(kBlazePoseRows) * kBlazePoseValues;
  if (ls.h * ls.w * ls.c != per_item || fs.h * fs.w * fs.c != 1 || n < 0 || n >= ls.n ||
      n >= fs.n || static_cast<long>(landmarks.data.size()) != ls.elements() ||
      static_cast<long>(flag.data.size()) != fs.elements()) {
    return invalid_argument("blazepose decoding", "landmarks " + ls.text() + " and flag " +
                                                      fs.text() + ", item " + std::to_string(n) +
                                                      ": needs [N,1,1,195] and [N,1,1,1], n < N");
  }
  BlazePosePose p;
  p.person_score = flag.data[static_cast<std::size_t>(n)];
  const float* v = landmarks.data.data() + static_cast<long>(n) * per_item;
  for (int i = 0; i < kBlazePoseLandmarks; ++i) {
    const float* r = v + i * kBlazePoseValues;
    p.landmarks[static_cast<std::size_t>(i)] = {r[0], r[1], r[2], sigmoid(r[3]), sigmoid(r[4])};
  }
  return p;
}

}  // namespace mocap::nn
