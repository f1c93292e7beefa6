#include "runtime/box/problems.h"

#include <gtest/gtest.h>

namespace mocap::box {
namespace {

TEST(ProblemList, ReplaceKeepsThePlaceRemoveTakesEveryOneOfACode) {
  ProblemList list;
  list.add({ProblemCode::kNoCamera, {}, "no camera", "plug one in"});
  list.add({ProblemCode::kCalibrationMissing, "0,1", "cameras 0,1 have no calibration", {}});
  list.add({ProblemCode::kCnnOnCpu, {}, "the CNN runs on the CPU", {}});
  list.add({ProblemCode::kCameraMoved, "1", "camera 1 moved", {}});
  list.add({ProblemCode::kCameraMoved, "0", "camera 0 moved", {}});

  EXPECT_TRUE(list.replace(ProblemCode::kCalibrationMissing,
                           {ProblemCode::kCalibrationMissing, "0,1", "calibrating", "walk"}));
  EXPECT_FALSE(list.replace(ProblemCode::kAccessToken, {}));
  EXPECT_EQ(problem_texts(list.snapshot()),
            (std::vector<std::string>{"no camera", "calibrating", "the CNN runs on the CPU",
                                      "camera 1 moved", "camera 0 moved"}));

  list.remove({ProblemCode::kCameraMoved, ProblemCode::kNoCamera});
  EXPECT_EQ(problem_texts(list.snapshot()),
            (std::vector<std::string>{"calibrating", "the CNN runs on the CPU"}));
  EXPECT_TRUE(list.has(ProblemCode::kCnnOnCpu));
  EXPECT_FALSE(list.has(ProblemCode::kCameraMoved));
  EXPECT_EQ(list.snapshot()[0].fix, "walk");
  EXPECT_EQ(to_string(ProblemCode::kCalibrationMissing), "calibration_missing");
}

}  // namespace
}  // namespace mocap::box
