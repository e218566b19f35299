// The shading pass's directional ambient (SH bands 0-2) against its C++ twin, per pixel of a virtual cube
// seen from above: top and side faces, every channel.
#include <gtest/gtest.h>

#include <algorithm>

#include "lighting/object_shadow.h"
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
  sh[2] = {0.5, 0.4, 0.3};     // y_10 ~ z
  sh[3] = {0.2, 0.25, 0.1};    // y_11 ~ x
  sh[6] = {0.05, -0.02, 0.0};  // y_20
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

TEST(AmbientSh, AnEnvironmentHoldingTheRealBounceIsNotAddedToAgain) {
  // A white cube beside a red wall under a point light: DLPV's bounce reddens the cube. When the ambient is
  // an environment seen at the object (the room's), that bounce is already in it: the cube is then shaded
  // by the direct light and the ambient alone, exactly as with no virtual-role technique, and a technique
  // serving only the virtual role is not run.
  auto ctx = test::makeContext();
  const test::TestScene s = test::makeScene(true, 0.3, {-0.25, 0.0, 0.15});
  const CameraView camera = test::topCamera(64, 64);
  const std::vector<SceneLight> lights = {test::pointAbove()};
  cv::Mat positions, normals, albedo;
  const auto virtualShade = [&](const std::string& technique, bool environment, std::vector<std::string>* skipped) {
    LightingPipeline pipe = test::makePipeline(test::testConfig(64, 64, 16, 64, technique), s);
    pipe.setEnvironment(environment);
    pipe.run(camera, lights, {0.1, 0.1, 0.1}, nullptr);
    if (skipped) *skipped = pipe.skippedStages();
    positions = pipe.downloadGBuffer(0), normals = pipe.downloadGBuffer(1), albedo = pipe.downloadGBuffer(2);
    return pipe.downloadShade();
  };
  Ambient sky;
  sky.uniform = {0.1f, 0.1f, 0.1f};
  const std::vector<OccluderSphere> spheres{occluderSphere(s.objects[0])};
  const cv::Mat bounce = virtualShade("dlpv", false, nullptr), held = virtualShade("dlpv", true, nullptr),
                none = virtualShade("dlpv+none", false, nullptr);
  int virtualPixels = 0, hiding = 0;
  double added = 0;
  for (int i = 0; i < static_cast<int>(bounce.total()); ++i) {
    const cv::Vec4f b = bounce.at<cv::Vec4f>(i), h = held.at<cv::Vec4f>(i), n = none.at<cv::Vec4f>(i);
    if (b[3] < 0.5f) {
      // Real pixels keep their delta, the ambient the cube hides (net of what it reflects) included: the
      // shading pass takes it from the ambient whether or not the ambient is an environment.
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(h[c], b[c], 1e-6) << "real pixels keep their delta";
      const cv::Vec4f p = positions.at<cv::Vec4f>(i), nn = normals.at<cv::Vec4f>(i);
      if (p[3] > 0.5f && ambientShadow(sky, {p[0], p[1], p[2]}, {nn[0], nn[1], nn[2]}, spheres)[0] > 1e-3f) ++hiding;
      continue;
    }
    ++virtualPixels;
    added += b[0] - h[0];
    for (int c = 0; c < 3; ++c) ASSERT_EQ(h[c], n[c]);
  }
  EXPECT_GT(virtualPixels, 50);
  EXPECT_GT(hiding, 50) << "real pixels near the cube lose some of the ambient";
  EXPECT_GT(added / virtualPixels, 1e-3) << "the wall's bounce reaches the cube when the ambient does not hold it";
  std::vector<std::string> skipped;
  virtualShade("none+kinect-val", true, &skipped);
  EXPECT_NE(std::find(skipped.begin(), skipped.end(), "kinect-val"), skipped.end());
  virtualShade("none+kinect-val", false, &skipped);
  EXPECT_EQ(std::find(skipped.begin(), skipped.end(), "kinect-val"), skipped.end());
}

}  // namespace
}  // namespace mrgi::lighting
