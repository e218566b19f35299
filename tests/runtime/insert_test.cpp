// Placing an object on a recorded frame (runtime/insert.h), without the command line: the base scene extended,
// the object put on the surface seen at a pixel, rested on the table's plane, and the scene file written so that
// it parses back to the same placement.
#include "runtime/insert.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "capture/error.h"
#include "lighting/scene_file.h"

namespace fs = std::filesystem;

namespace mrgi::runtime {
namespace {

const std::string kSource = MRGI_SOURCE_DIR;

gl::ContextConfig headless(int width, int height) {
  gl::ContextConfig cfg;
  cfg.width = width;
  cfg.height = height;
  return cfg;
}

TEST(Insert, APixelsSurfacePointThenTheTablePlanePlaceTheObjectAndTheSceneParsesBack) {
  const fs::path dir = fs::temp_directory_path() / ("mrgi_insert_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  InsertOptions o;
  o.session = kSource + "/recordings/tabletop-synth";
  o.model = kSource + "/recordings/models/sphere.ply";
  o.scale = 0.05;
  o.scene = kSource + "/recordings/scenes/tabletop.json";
  o.save = (dir / "placed.json").string();
  o.pose = PoseMode::GroundTruth;
  Insertion in(o, headless);
  const size_t base = lighting::loadScene(o.scene).objects.size();
  EXPECT_EQ(in.index(), base);  // appended after the base scene's objects
  // The table is the marker's plane (z = 0 in the marker frame): the surface point of a pixel on it lies there.
  // Two pixels 100 apart on the table: two points on it, apart by what the camera's 0.6-1 m away from it makes of
  // 100 pixels at f = 525 (11-19 cm).
  in.placeAtPixel(230, 300);
  const nlohmann::json left = in.document()["objects"][in.index()]["translate"];
  in.placeAtPixel(330, 300);
  const nlohmann::json placed = in.document()["objects"][in.index()]["translate"];
  EXPECT_NEAR(placed[2].get<double>(), 0.0, 0.01);
  EXPECT_NEAR(left[2].get<double>(), 0.0, 0.01);
  const double apart =
      std::hypot(placed[0].get<double>() - left[0].get<double>(), placed[1].get<double>() - left[1].get<double>());
  EXPECT_GT(apart, 0.11);
  EXPECT_LT(apart, 0.19);
  // Rested on the plane below: the sphere's centre one radius above the table.
  EXPECT_EQ(in.snap(SnapUp{}), std::nullopt);
  const nlohmann::json rested = in.document()["objects"][in.index()]["translate"];
  EXPECT_NEAR(rested[2].get<double>(), 0.05, 0.01);
  // Rested along the plane's normal, nearly the marker's z: x and y stay within a millimetre.
  EXPECT_NEAR(rested[0].get<double>(), placed[0].get<double>(), 1e-3);
  EXPECT_NEAR(rested[1].get<double>(), placed[1].get<double>(), 1e-3);
  EXPECT_TRUE(in.report().contains("plane"));
  in.save();
  const lighting::SceneDescription back = lighting::loadScene(o.save);
  ASSERT_EQ(back.objects.size(), base + 1);
  EXPECT_NEAR(back.objects.back().T_marker_object(2, 3), rested[2].get<double>(), 1e-9);
  // A pixel outside the image is an error; one in a small hole of the depth takes the nearest pixel with depth
  // and says so.
  EXPECT_THROW(in.placeAtPixel(-1, 0), std::invalid_argument);
  const cv::Mat& positions = in.measured().positions;
  int hu = -1, hv = -1;
  for (int y = 0; y < positions.rows && hu < 0; ++y)
    for (int x = 0; x < positions.cols && hu < 0; ++x)
      if (!(positions.at<cv::Vec3f>(y, x)[2] > 0)) hu = x, hv = y;
  ASSERT_GE(hu, 0) << "the sensor model leaves holes";
  const auto note = in.placeAtPixel(hu, hv);
  ASSERT_TRUE(note);
  const std::string pixel = std::to_string(hu) + "," + std::to_string(hv);
  EXPECT_NE(note->find("no depth at pixel " + pixel + "; placed at "), std::string::npos) << *note;
  int nu = -1, nv = -1;
  ASSERT_EQ(std::sscanf(note->c_str() + note->find("placed at ") + 10, "%d,%d", &nu, &nv), 2) << *note;
  EXPECT_GT(positions.at<cv::Vec3f>(nv, nu)[2], 0.f);
  EXPECT_LE(std::hypot(nu - hu, nv - hv), 3.0);  // holes are small
  const auto at = in.report()["translate"];
  EXPECT_FALSE(in.placeAtPixel(nu, nv));  // the same place, without a note
  EXPECT_EQ(in.report()["translate"], at);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mrgi::runtime
