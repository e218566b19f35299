// The G-buffer's real albedo per camera pixel (FrameResources::setRealPixelAlbedo): a texture finer than the
// real mesh's vertices reaches the shading pass sharp.
#include <gtest/gtest.h>

#include "tests/lighting/test_scene.h"

namespace mrgi::test {
namespace {

TEST(PixelAlbedo, RealSurfacesTakeTheirPixelsAlbedoAndVirtualOnesKeepTheirMaterial) {
  auto ctx = makeContext();
  const int W = 64, H = 48;
  const TestScene s = makeScene(false, 0.2, {0.0, 0.0, 0.1});
  LightingPipeline pipe = makePipeline(testConfig(W, H, 16, 64, "none"), s);
  // A one-pixel checkerboard (the floor's vertices, far apart, could only interpolate it), with a hole
  // (negative: no albedo there) in one corner.
  cv::Mat albedo(H, W, CV_32FC3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      albedo.at<cv::Vec3f>(y, x) = (x + y) % 2 ? cv::Vec3f(0.9f, 0.2f, 0.1f) : cv::Vec3f(0.05f, 0.6f, 0.3f);
  albedo(cv::Rect(0, 0, 8, 8)).setTo(cv::Scalar::all(-1));
  pipe.setRealPixelAlbedo(albedo);
  pipe.run(topCamera(W, H), {sunDown()}, {0.1, 0.1, 0.1}, nullptr);
  const cv::Mat g = pipe.downloadGBuffer(2), pos = pipe.downloadGBuffer(0);
  int real = 0, virt = 0, hole = 0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const cv::Vec4f a = g.at<cv::Vec4f>(y, x);
      if (pos.at<cv::Vec4f>(y, x)[3] < 0.5f) continue;
      if (a[3] > 0.5f) {
        ++virt;
        for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(a[c], s.objects[0].material.albedo[c]);
      } else if (x < 8 && y < 8) {
        ++hole;
        for (int c = 0; c < 3; ++c)
          EXPECT_NEAR(a[c], kFloorAlbedo[c], 1e-6) << "the vertices' albedo where the image has none";
      } else {
        ++real;
        for (int c = 0; c < 3; ++c) {
          const float want = albedo.at<cv::Vec3f>(y, x)[c];
          ASSERT_NEAR(a[c], want, 4.9e-4f * want) << x << "," << y;  // held as half floats: 2^-11 relative
        }
      }
    }
  EXPECT_GT(real, 1000);
  EXPECT_GT(virt, 50);
  EXPECT_GT(hole, 30);
  // Cleared (or of another size): the vertices' albedo everywhere again.
  pipe.setRealPixelAlbedo(cv::Mat(H / 2, W, CV_32FC3, cv::Scalar::all(0.7)));
  pipe.run(topCamera(W, H), {sunDown()}, {0.1, 0.1, 0.1}, nullptr);
  const cv::Mat g2 = pipe.downloadGBuffer(2);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const cv::Vec4f a = g2.at<cv::Vec4f>(y, x);
      if (pos.at<cv::Vec4f>(y, x)[3] > 0.5f && a[3] < 0.5f) {
        ASSERT_NEAR(a[0], kFloorAlbedo[0], 1e-6);
      }
    }
}

}  // namespace
}  // namespace mrgi::test
