// The shading pass's directional ambient (SH bands 0-2) against its C++ twin, per pixel of a virtual cube
// seen from above: top and side faces, every channel.
#include <gtest/gtest.h>

#include "reconstruction/light_estimation.h"
#include "test_scene.h"

namespace mrgi::lighting {
namespace {

TEST(AmbientSh, ShadingPassMatchesTheCppIrradiancePerPixel) {
  auto ctx = test::makeContext();
  const test::TestScene s = test::makeScene(false, 0.3, {0.0, 0.0, 0.15});
  LightingPipeline pipe = test::makePipeline(test::testConfig(64, 64, 16, 64, "dlpv"), s);
  // A sky brighter overhead and towards +x, with some colour in band 2; no light and no uniform ambient.
  std::array<cv::Vec3d, 9> sh{};
  sh[0] = {0.8, 0.7, 0.6};
  sh[2] = {0.5, 0.4, 0.3};    // y_10 ~ z
  sh[3] = {0.2, 0.25, 0.1};   // y_11 ~ x
  sh[6] = {0.05, -0.02, 0.0}; // y_20
  pipe.setAmbientSh(sh);
  CameraView camera = test::topCamera(64, 64);
  camera.T_world_camera = capture::lookAtPose({0.9, -0.7, 0.8}, {0, 0, 0.15});  // top and two sides in view
  pipe.run(camera, {}, {0, 0, 0}, nullptr);
  const cv::Mat shade = pipe.downloadShade(), normals = pipe.downloadGBuffer(1);
  int virtualPixels = 0, sides = 0;
  double worst = 0;
  for (int y = 0; y < shade.rows; ++y)
    for (int x = 0; x < shade.cols; ++x) {
      const cv::Vec4f v = shade.at<cv::Vec4f>(y, x);
      if (v[3] < 0.5f) continue;
      ++virtualPixels;
      const cv::Vec4f n4 = normals.at<cv::Vec4f>(y, x);
      const cv::Vec3d n = cv::normalize(cv::Vec3d(n4[0], n4[1], n4[2]));
      if (std::abs(n[2]) < 0.5) ++sides;
      const cv::Vec3d expected = reconstruction::ambientShIrradiance(sh, n) * (0.9 / CV_PI);
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(v[c] - expected[c]) / std::max(expected[c], 1e-3));
    }
  EXPECT_GT(virtualPixels, 200);
  EXPECT_GT(sides, 20);
  EXPECT_LT(worst, 1e-3);
  // Zero SH adds nothing: the object is black without lights or ambient.
  pipe.setAmbientSh({});
  pipe.run(camera, {}, {0, 0, 0}, nullptr);
  const cv::Mat dark = pipe.downloadShade();
  for (int i = 0; i < static_cast<int>(dark.total()); ++i)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(dark.at<cv::Vec4f>(i)[c], 0.f);
}

}  // namespace
}  // namespace mrgi::lighting
