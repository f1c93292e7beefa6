#include "runtime/box/box_status.h"

#include <gtest/gtest.h>

#include <string>

namespace mocap::box {
namespace {

bool has_line(const std::string& text, const std::string& line) {
  return text.find("\n" + line + "\n") != std::string::npos || text.rfind(line + "\n", 0) == 0;
}

BoxStatus calibrating_box() {
  BoxStatus s;
  s.version = "1.2.3";
  s.source = SourceKind::kCameras;
  s.board = "pi5";
  s.calibration.state = CalibrationState::kCalibrating;
  s.calibration.file = "";
  s.problems = {"cameras 0,1 have no calibration: calibrating"};
  s.gpu.backend = "vulkan";
  s.gpu.device = "llvmpipe";
  s.gpu.detector = "MoveNet MultiPose 448x256";
  s.take = nlohmann::json{{"recording", "a"}, {"current", {{"frames", 42}}}};
  s.stream = StreamStatus{9870, 9871, net::ServerStats{}};
  return s;
}

TEST(BoxStatus, HealthAndMetricsAreTwoRenderingsOfOneStatus) {
  BoxStatus s = calibrating_box();
  const nlohmann::json h = health_json(s);
  EXPECT_EQ(h["status"], "degraded");
  EXPECT_EQ(h["problems"].size(), 1u);
  EXPECT_EQ(h["source"]["kind"], "cameras");
  EXPECT_EQ(h["source"]["board"], "pi5");
  EXPECT_EQ(h["calibration"]["state"], "calibrating");
  EXPECT_EQ(h["output"], "detections");
  EXPECT_EQ(h["role"], "standalone");
  EXPECT_EQ(h["stream"]["port"], 9870);
  EXPECT_FALSE(h.contains("trigger"));

  const std::string m = prometheus_text(s);
  EXPECT_TRUE(has_line(m, R"(mocap_info{version="1.2.3",source="cameras",gpu="vulkan"} 1)")) << m;
  EXPECT_TRUE(has_line(m, "mocap_problems 1"));
  EXPECT_TRUE(has_line(m, R"(mocap_calibration_state{state="calibrating"} 1)"));
  EXPECT_TRUE(has_line(m, R"(mocap_calibration_state{state="ok"} 0)"));
  EXPECT_TRUE(has_line(m, "mocap_take_recording 1"));
  EXPECT_TRUE(has_line(m, "mocap_take_frames 42"));
  EXPECT_NE(m.find("mocap_stream_clients{kind=\"tcp\"} 0"), std::string::npos);
}

TEST(BoxStatus, AFailedPipelineAndALostGpuShowInBoth) {
  BoxStatus s = calibrating_box();
  s.problems.clear();
  s.calibration.state = CalibrationState::kOk;
  s.calibration.engine = true;
  s.pipeline.error = "cnn: device lost";
  s.gpu.recovery.devices_lost = 2;
  s.gpu.recovery.on_cpu = true;
  s.stream.reset();
  const nlohmann::json h = health_json(s);
  EXPECT_EQ(h["status"], "failed");
  EXPECT_EQ(h["output"], "skeletons");
  EXPECT_EQ(h["gpu"]["backend"], "cpu");
  EXPECT_EQ(h["gpu"]["devices_lost"], 2);
  EXPECT_FALSE(h.contains("stream"));
  const std::string m = prometheus_text(s);
  EXPECT_NE(m.find(R"(gpu="cpu")"), std::string::npos);
  EXPECT_EQ(m.find("mocap_stream_clients"), std::string::npos);  // no server, no series
}

TEST(BoxStatus, LabelValuesAreEscaped) {
  EXPECT_EQ(prometheus_label("a\"b\\c\nd"), "a\\\"b\\\\c\\nd");
  BoxStatus s;
  s.version = "v\"1";
  EXPECT_NE(prometheus_text(s).find(R"(version="v\"1")"), std::string::npos);
}

}  // namespace
}  // namespace mocap::box
