#include "runtime/geometry/calibration.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/support/data.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using Json = nlohmann::ordered_json;

// A valid three-view calibration document ("0", "1", "2") to break one field at a time.
Json valid_doc() {
  Json doc = Json::object();
  for (int v = 0; v < 3; ++v) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.4 * v + 0.1, Eigen::Vector3d(0.3, 1.0, -0.2).normalized())
            .toRotationMatrix();
    Json view;
    view["K"] = {1000.0 + v, 0.0, 516.0, 0.0, 1001.0, 388.0, 0.0, 0.0, 1.0};
    view["RT"] = {R(0, 0), R(0, 1), R(0, 2), 0.1 * v, R(1, 0), R(1, 1),
                  R(1, 2), 0.5,     R(2, 0), R(2, 1), R(2, 2), 3.0 + v};
    view["imgSize"] = {1032, 776};
    doc[std::to_string(v)] = view;
  }
  return doc;
}

Result<Calibration> parse(const Json& doc) {
  return parse_calibration_json(doc.dump(), "calibration.json");
}

// Parses `doc`, expects a parse error and returns its message.
std::string parse_error(const Json& doc) {
  Result<Calibration> r = parse(doc);
  EXPECT_FALSE(r.ok());
  if (r.ok()) return "";
  EXPECT_EQ(r.error().code(), ErrorCode::kParse);
  return r.error().message();
}

std::filesystem::path temp_file(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / "mocap_geometry_test";
  std::filesystem::create_directories(dir);
  return dir / name;
}

TEST(Calibration, ParsesValidDocument) {
  Result<Calibration> r = parse(valid_doc());
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_EQ(r->size(), 3u);
  EXPECT_THAT(r->view_ids, ::testing::ElementsAre("0", "1", "2"));
  const Camera& c = r->cameras[1];
  EXPECT_EQ(c.width_px(), 1032);
  EXPECT_EQ(c.height_px(), 776);
  EXPECT_DOUBLE_EQ(c.fx(), 1001.0);
  EXPECT_DOUBLE_EQ(c.fy(), 1001.0);
  EXPECT_DOUBLE_EQ(c.cx(), 516.0);
  EXPECT_DOUBLE_EQ(c.cy(), 388.0);
  EXPECT_FALSE(c.has_distortion());
  EXPECT_TRUE(c.name().empty());
  EXPECT_EQ(r->index_of("2"), 2u);
  EXPECT_FALSE(r->index_of("7").has_value());
}

TEST(Calibration, SortsIntegerKeysNumerically) {
  const Json base = valid_doc();
  Json doc = Json::object();
  doc["10"] = base["0"];
  doc["2"] = base["1"];
  doc["0"] = base["2"];
  Result<Calibration> r = parse(doc);
  ASSERT_TRUE(r.ok()) << r.error().message();
  EXPECT_THAT(r->view_ids, ::testing::ElementsAre("0", "2", "10"));
  EXPECT_DOUBLE_EQ(r->cameras[0].fx(), 1002.0);  // was base["2"]
}

TEST(Calibration, NonIntegerKeysKeepFileOrder) {
  const Json base = valid_doc();
  Json doc = Json::object();
  doc["left"] = base["0"];
  doc["right"] = base["1"];
  doc["centre"] = base["2"];
  Result<Calibration> r = parse(doc);
  ASSERT_TRUE(r.ok()) << r.error().message();
  EXPECT_THAT(r->view_ids, ::testing::ElementsAre("left", "right", "centre"));
}

TEST(Calibration, ReadsOptionalDistortionAndName) {
  Json doc = valid_doc();
  doc["0"]["dist"] = {-0.046, 0.14, 0.0006, 0.0007, 0.01};
  doc["0"]["name"] = "cam01";
  doc["1"]["dist"] = {-0.05, 0.13, 0.001, 0.002};
  Result<Calibration> r = parse(doc);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Distortion& d0 = r->cameras[0].distortion();
  EXPECT_DOUBLE_EQ(d0.k1, -0.046);
  EXPECT_DOUBLE_EQ(d0.k2, 0.14);
  EXPECT_DOUBLE_EQ(d0.p1, 0.0006);
  EXPECT_DOUBLE_EQ(d0.p2, 0.0007);
  EXPECT_DOUBLE_EQ(d0.k3, 0.01);
  EXPECT_EQ(r->cameras[0].name(), "cam01");
  const Distortion& d1 = r->cameras[1].distortion();
  EXPECT_DOUBLE_EQ(d1.p2, 0.002);
  EXPECT_DOUBLE_EQ(d1.k3, 0.0);
  EXPECT_FALSE(r->cameras[2].has_distortion());
}

TEST(Calibration, ReorthonormalisesSlightlyOffRotation) {
  Json doc = valid_doc();
  // Perturb R by ~1e-4, like the 8-digit rotations in the Shelf file.
  doc["1"]["RT"][0] = doc["1"]["RT"][0].get<double>() + 1e-4;
  Result<Calibration> r = parse(doc);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Eigen::Matrix3d& R = r->cameras[1].R();
  EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
}

TEST(CalibrationErrors, MissingField) {
  Json doc = valid_doc();
  doc["2"].erase("RT");
  EXPECT_EQ(parse_error(doc),
            "calibration.json: view \"2\": field \"RT\": missing; expected 12 numbers (3x4 "
            "world->camera [R|t], row-major, metres)");
  Json no_size = valid_doc();
  no_size["1"].erase("imgSize");
  EXPECT_THAT(parse_error(no_size),
              AllOf(HasSubstr("view \"1\""), HasSubstr("field \"imgSize\""), HasSubstr("missing")));
}

TEST(CalibrationErrors, WrongArrayLength) {
  Json doc = valid_doc();
  doc["2"]["K"].erase(8);
  EXPECT_EQ(parse_error(doc),
            "calibration.json: view \"2\": field \"K\": expected 9 numbers, got 8");
  Json dist = valid_doc();
  dist["0"]["dist"] = {0.1, 0.2, 0.3};
  EXPECT_EQ(parse_error(dist),
            "calibration.json: view \"0\": field \"dist\": expected 4 or 5 numbers, got 3");
  Json size = valid_doc();
  size["1"]["imgSize"] = {1032, 776, 3};
  EXPECT_THAT(parse_error(size), AllOf(HasSubstr("view \"1\""), HasSubstr("field \"imgSize\""),
                                       HasSubstr("expected 2 numbers, got 3")));
}

TEST(CalibrationErrors, NonNumericValue) {
  Json doc = valid_doc();
  doc["1"]["RT"][5] = "0.5";
  EXPECT_THAT(parse_error(doc),
              AllOf(HasSubstr("calibration.json: view \"1\": field \"RT\""),
                    HasSubstr("element 5 is not a number"), HasSubstr("string \"0.5\"")));
  Json null_value = valid_doc();
  null_value["0"]["K"][0] = nullptr;
  EXPECT_THAT(parse_error(null_value),
              AllOf(HasSubstr("view \"0\""), HasSubstr("field \"K\""), HasSubstr("null")));
}

TEST(CalibrationErrors, FieldOfWrongType) {
  Json doc = valid_doc();
  doc["0"]["K"] = "identity";
  EXPECT_THAT(parse_error(doc), AllOf(HasSubstr("view \"0\""), HasSubstr("field \"K\""),
                                      HasSubstr("expected an array of 9 numbers")));
  Json name = valid_doc();
  name["2"]["name"] = 7;
  EXPECT_THAT(parse_error(name), AllOf(HasSubstr("view \"2\""), HasSubstr("field \"name\""),
                                       HasSubstr("expected a string")));
}

TEST(CalibrationErrors, NonFiniteValue) {
  // JSON has no NaN/Inf literal; an overflowing literal is rejected by the JSON parser.
  std::string text = valid_doc().dump();
  text.replace(text.find("1000.0"), 6, "1e999");
  Result<Calibration> r = parse_calibration_json(text, "calibration.json");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kParse);
  EXPECT_THAT(r.error().message(),
              AllOf(HasSubstr("calibration.json: invalid JSON"), HasSubstr("1e999")));
}

TEST(CalibrationErrors, SingularK) {
  Json doc = valid_doc();
  doc["1"]["K"][0] = 0.0;
  EXPECT_THAT(parse_error(doc), AllOf(HasSubstr("calibration.json: view \"1\": field \"K\""),
                                      HasSubstr("singular"), HasSubstr("fx > 0")));
  Json negative = valid_doc();
  negative["0"]["K"][4] = -1000.0;
  EXPECT_THAT(parse_error(negative),
              AllOf(HasSubstr("view \"0\""), HasSubstr("field \"K\""), HasSubstr("singular")));
  Json tiny = valid_doc();
  tiny["0"]["K"][0] = 1e-9;
  tiny["0"]["K"][4] = 1e-9;
  EXPECT_THAT(parse_error(tiny), AllOf(HasSubstr("field \"K\""), HasSubstr("singular")));
  Json bottom = valid_doc();
  bottom["2"]["K"][8] = 2.0;
  EXPECT_THAT(parse_error(bottom), AllOf(HasSubstr("view \"2\""), HasSubstr("field \"K\""),
                                         HasSubstr("last row [0, 0, 1]")));
}

TEST(CalibrationErrors, NonOrthonormalR) {
  Json doc = valid_doc();
  for (int i = 0; i < 3; ++i) doc["2"]["RT"][i] = doc["2"]["RT"][i].get<double>() * 1.1;
  EXPECT_THAT(parse_error(doc), AllOf(HasSubstr("calibration.json: view \"2\": field \"RT\""),
                                      HasSubstr("not orthonormal")));
  // A reflection is orthogonal but not a rotation.
  Json mirror = valid_doc();
  for (int i : {0, 1, 2}) mirror["0"]["RT"][i] = -mirror["0"]["RT"][i].get<double>();
  EXPECT_THAT(parse_error(mirror),
              AllOf(HasSubstr("view \"0\""), HasSubstr("field \"RT\""), HasSubstr("reflection")));
}

TEST(CalibrationErrors, BadImageSize) {
  Json doc = valid_doc();
  doc["1"]["imgSize"] = {0, 776};
  EXPECT_THAT(parse_error(doc), AllOf(HasSubstr("view \"1\""), HasSubstr("field \"imgSize\""),
                                      HasSubstr("positive integers")));
  Json fraction = valid_doc();
  fraction["1"]["imgSize"] = {1032.5, 776};
  EXPECT_THAT(parse_error(fraction), HasSubstr("field \"imgSize\""));
}

TEST(CalibrationErrors, InvalidJson) {
  Result<Calibration> r = parse_calibration_json("{\"0\": {\"K\": [1, 2,", "calibration.json");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kParse);
  EXPECT_THAT(r.error().message(),
              AllOf(HasSubstr("calibration.json: invalid JSON"), HasSubstr("line 1")));
}

TEST(CalibrationErrors, EmptyNotObjectOrNoViews) {
  for (const char* text : {"", "  \n"}) {
    Result<Calibration> r = parse_calibration_json(text, "calibration.json");
    ASSERT_FALSE(r.ok());
    EXPECT_THAT(r.error().message(), HasSubstr("calibration.json: file is empty"));
  }
  Result<Calibration> arr = parse_calibration_json("[1, 2]", "calibration.json");
  ASSERT_FALSE(arr.ok());
  EXPECT_THAT(arr.error().message(),
              AllOf(HasSubstr("calibration.json"), HasSubstr("expected a JSON object"),
                    HasSubstr("got array")));
  Result<Calibration> none = parse_calibration_json("{}", "calibration.json");
  ASSERT_FALSE(none.ok());
  EXPECT_THAT(none.error().message(), HasSubstr("calibration.json: no views"));
  Json doc = valid_doc();
  doc["1"] = 42;
  EXPECT_THAT(parse_error(doc),
              AllOf(HasSubstr("calibration.json: view \"1\""), HasSubstr("expected an object")));
}

TEST(CalibrationErrors, MissingFile) {
  const std::filesystem::path path = temp_file("does_not_exist.json");
  std::filesystem::remove(path);
  Result<Calibration> r = load_calibration(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(r.error().message(), AllOf(HasSubstr(path.string()), HasSubstr("not found")));
}

TEST(CalibrationErrors, LoaderNamesTheFile) {
  const std::filesystem::path path = temp_file("bad_view.json");
  Json doc = valid_doc();
  doc["2"]["K"].erase(8);
  {
    std::ofstream out(path);
    out << doc.dump(2);
  }
  Result<Calibration> r = load_calibration(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message(),
            path.string() + ": view \"2\": field \"K\": expected 9 numbers, got 8");
}

void expect_same_calibration(const Calibration& a, const Calibration& b) {
  ASSERT_EQ(a.view_ids, b.view_ids);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Camera& x = a.cameras[i];
    const Camera& y = b.cameras[i];
    EXPECT_LT((x.K() - y.K()).norm(), 1e-12);
    EXPECT_LT((x.R() - y.R()).norm(), 1e-12);
    EXPECT_LT((x.t_m() - y.t_m()).norm(), 1e-12);
    EXPECT_EQ(x.width_px(), y.width_px());
    EXPECT_EQ(x.height_px(), y.height_px());
    EXPECT_EQ(x.has_distortion(), y.has_distortion());
    EXPECT_EQ(x.distortion().k1, y.distortion().k1);
    EXPECT_EQ(x.distortion().k2, y.distortion().k2);
    EXPECT_EQ(x.distortion().p1, y.distortion().p1);
    EXPECT_EQ(x.distortion().p2, y.distortion().p2);
    EXPECT_EQ(x.distortion().k3, y.distortion().k3);
    EXPECT_EQ(x.name(), y.name());
  }
}

TEST(Calibration, SaveLoadRoundTrip) {
  Json doc = valid_doc();
  doc["0"]["dist"] = {-0.046183, 0.139983, 0.000608, 0.00069, 0.0};
  doc["0"]["name"] = "cam01";
  doc["2"]["K"][1] = 0.75;  // skew
  Result<Calibration> original = parse(doc);
  ASSERT_TRUE(original.ok()) << original.error().message();

  const std::filesystem::path path = temp_file("round_trip.json");
  ASSERT_TRUE(save_calibration(*original, path).ok());
  EXPECT_TRUE(mocap::testing::temporary_files(path.parent_path()).empty());
  Result<Calibration> loaded = load_calibration(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message();
  expect_same_calibration(*original, *loaded);

  // "dist" only where there is distortion, "name" only where set.
  Result<std::string> text = calibration_to_json(*loaded);
  ASSERT_TRUE(text.ok());
  const Json written = Json::parse(*text);
  EXPECT_TRUE(written["0"].contains("dist"));
  EXPECT_TRUE(written["0"].contains("name"));
  EXPECT_FALSE(written["1"].contains("dist"));
  EXPECT_FALSE(written["1"].contains("name"));
}

TEST(Calibration, SaveRejectsInconsistentCalibration) {
  Calibration calib;
  calib.cameras.resize(2);
  calib.view_ids = {"0"};
  Status s = save_calibration(calib, temp_file("inconsistent.json"));
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code(), ErrorCode::kInvalidArgument);
  calib.view_ids = {"0", "0"};
  EXPECT_FALSE(calibration_to_json(calib).ok());
}

TEST(Calibration, SaveToMissingFolderFails) {
  Result<Calibration> calib = parse(valid_doc());
  ASSERT_TRUE(calib.ok());
  const std::filesystem::path path = temp_file("no_such_dir") / "sub" / "calibration.json";
  Status s = save_calibration(*calib, path);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code(), ErrorCode::kIo);
  EXPECT_THAT(s.error().message(), HasSubstr(path.string()));
}

// --- the shared data sets ---

TEST(CalibrationData, LoadsShelf) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  Result<Calibration> r = load_calibration(dir / "calibration.json");
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_EQ(r->size(), 5u);
  EXPECT_THAT(r->view_ids, ::testing::ElementsAre("0", "1", "2", "3", "4"));
  for (const Camera& cam : r->cameras) {
    EXPECT_EQ(cam.width_px(), 1032);
    EXPECT_EQ(cam.height_px(), 776);
    EXPECT_FALSE(cam.has_distortion());
    EXPECT_GT(cam.fx(), 900.0);
    EXPECT_LT(cam.fx(), 1300.0);
    EXPECT_LT((cam.R() * cam.R().transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    // Cameras stand a few metres from the scene.
    EXPECT_GT(cam.center_m().norm(), 1.0);
    EXPECT_LT(cam.center_m().norm(), 10.0);
  }
  EXPECT_NEAR(r->cameras[0].fx(), 1063.5121, 1e-9);
  EXPECT_NEAR(r->cameras[0].cy(), 350.08829, 1e-9);
  // Every camera looks at the scene around the world origin.
  for (const Camera& cam : r->cameras) EXPECT_GT(cam.to_camera(Eigen::Vector3d::Zero()).z(), 0.0);
}

TEST(CalibrationData, LoadsPose2Sim) {
  MOCAP_REQUIRE_DATA(dir, "pose2sim_multi");
  Result<Calibration> r = load_calibration(dir / "calibration.json");
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_EQ(r->size(), 4u);
  const char* names[] = {"cam01", "cam02", "cam03", "cam04"};
  for (std::size_t i = 0; i < 4; ++i) {
    const Camera& cam = r->cameras[i];
    EXPECT_EQ(r->view_ids[i], std::to_string(i));
    EXPECT_EQ(cam.name(), names[i]);
    EXPECT_EQ(cam.width_px(), 1088);
    EXPECT_EQ(cam.height_px(), 1920);
    EXPECT_TRUE(cam.has_distortion());
    EXPECT_LT(cam.distortion().k1, -0.04);
    EXPECT_GT(cam.distortion().k2, 0.13);
  }
  EXPECT_DOUBLE_EQ(r->cameras[0].distortion().k1, -0.046183);
  // Camera centres documented in the data set's README (metres).
  EXPECT_LT((r->cameras[0].center_m() - Eigen::Vector3d(1.46, -1.91, 1.90)).norm(), 0.01);
  EXPECT_LT((r->cameras[1].center_m() - Eigen::Vector3d(2.58, 0.71, 1.69)).norm(), 0.01);
  EXPECT_LT((r->cameras[2].center_m() - Eigen::Vector3d(-3.22, 2.23, 2.09)).norm(), 0.01);
}

TEST(CalibrationData, ShelfSaveLoadRoundTrip) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  Result<Calibration> original = load_calibration(dir / "calibration.json");
  ASSERT_TRUE(original.ok()) << original.error().message();
  const std::filesystem::path path = temp_file("shelf_round_trip.json");
  ASSERT_TRUE(save_calibration(*original, path).ok());
  Result<Calibration> loaded = load_calibration(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message();
  expect_same_calibration(*original, *loaded);
}

}  // namespace
}  // namespace mocap
