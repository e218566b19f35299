// Real pixels whose camera channels are clipped (lighting/clipped_real.glsl and its C++ twin lighting/clipped_real.h):
// the objects' shadow there is taken from the radiance the lights predict, not from the sensor's white.
#include "lighting/clipped_real.h"

#include <gtest/gtest.h>

#include <random>

#include "compositor/compositor.h"
#include "gl/error.h"
#include "tests/lighting/test_scene.h"

namespace mrgi::test {
namespace {

TEST(ClippedReal, AShadowOnAClippedPixelReadsTheShadowedSurfacesRadiance) {
  // A sunlit table the camera clips: its radiance is 2 W (W the camera's white), the sensor shows W. An object
  // blocks three quarters of its light (shaded = -1.5 W): the table there reads 0.5 W, not W - 1.5 W < 0.
  const float W = 0.5f;
  const cv::Vec3f predicted(2 * W, 2 * W, 0.6f * W), shaded(-1.5f * W, -1.5f * W, -0.45f * W);
  const cv::Vec3f out = lighting::clippedRealShade(shaded, predicted, W, 0b011);  // red and green clipped
  EXPECT_FLOAT_EQ(W + out[0], 0.5f * W);
  EXPECT_FLOAT_EQ(W + out[1], 0.5f * W);
  EXPECT_FLOAT_EQ(out[2], shaded[2]) << "an unclipped channel keeps its measured background and its delta";
  // Through the compositor (exposure 1 / W: the white is 1 in the camera's linear values), as 8-bit sRGB.
  cv::Mat background(1, 1, CV_8UC3, cv::Scalar(255, 255, 200)), delta(1, 1, CV_32FC3, cv::Scalar::all(0));
  delta.at<cv::Vec3f>(0, 0) = out;
  const cv::Mat composite = compositor::compositeReference(background, delta, cv::Mat(), 1.0 / W);
  EXPECT_NEAR(composite.at<cv::Vec3b>(0, 0)[0], 188, 1);  // sRGB of 0.5
  // A shallow shadow on it stays white, as the sensor would show it: the surface is still brighter than W.
  const cv::Vec3f shallow = lighting::clippedRealShade({-0.5f * W, 0, 0}, predicted, W, 0b001);
  EXPECT_FLOAT_EQ(shallow[0], 0.0f);
  // A surface the lights predict no brighter than the white (their estimate low): the delta as measured.
  EXPECT_EQ(lighting::clippedRealShade(shaded, {0.5f * W, W, W}, W, 0b111), shaded);
  // Light the objects add (their bounce) is never changed; nor is anything without a white or a clipped channel.
  EXPECT_EQ(lighting::clippedRealShade({0.2f, 0.2f, 0.2f}, predicted, W, 0b111), cv::Vec3f(0.2f, 0.2f, 0.2f));
  EXPECT_EQ(lighting::clippedRealShade(shaded, predicted, 0, 0b111), shaded);
  EXPECT_EQ(lighting::clippedRealShade(shaded, predicted, W, 0), shaded);
  // Huge predictions stay bounded: never brighter than the white.
  const cv::Vec3f huge = lighting::clippedRealShade(shaded, {1e30f, 1e30f, 1e30f}, W, 0b111);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(huge[k], 0.0f);
}

TEST(ClippedReal, ChannelBitsFollowTheSensorsWhite) {
  EXPECT_EQ(lighting::clippedChannelBits({250, 249, 255}), 0b101);
  EXPECT_EQ(lighting::clippedChannelBits({0, 0, 0}), 0);
  cv::Mat image(2, 2, CV_8UC3, cv::Scalar(255, 255, 255));
  image.at<cv::Vec3b>(1, 1) = {10, 251, 10};
  const cv::Mat bits = lighting::clippedChannels(image);
  EXPECT_EQ(bits.at<uint8_t>(0, 0), 7);
  EXPECT_EQ(bits.at<uint8_t>(1, 1), 2);
}

TEST(GL, ClippedRealGlslMatchesCpuReference) {
  auto ctx = makeContext();
  const int n = 2048;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-3, 3);
  std::vector<cv::Vec4f> shaded(n), predicted(n);
  for (int i = 0; i < n; ++i) {
    shaded[i] = {u(rng), u(rng), u(rng), i % 5 == 0 ? 0.f : std::abs(u(rng))};
    predicted[i] = {std::abs(u(rng)), std::abs(u(rng)), std::abs(u(rng)), -static_cast<float>(i % 8)};
  }
  gl::Buffer a(n * sizeof(cv::Vec4f), shaded.data()), b(n * sizeof(cv::Vec4f), predicted.data());
  gl::Buffer out(n * sizeof(cv::Vec4f), nullptr);
  gl::Program prog = gl::Program::compute("lighting/shaders/clipped_real_eval.comp");
  prog.use();
  prog.set("uCount", n);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, a.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, b.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, out.id());
  glDispatchCompute((n + 63) / 64, 1, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<cv::Vec4f> gpu(n);
  out.download(0, n * sizeof(cv::Vec4f), gpu.data());
  gl::checkGlError("clipped_real_eval");
  int changed = 0;
  for (int i = 0; i < n; ++i) {
    const cv::Vec3f s(shaded[i][0], shaded[i][1], shaded[i][2]), p(predicted[i][0], predicted[i][1], predicted[i][2]);
    const cv::Vec3f want = lighting::clippedRealShade(s, p, shaded[i][3], static_cast<int>(-predicted[i][3]));
    changed += want != s;
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(gpu[i][k], want[k], 1e-6f) << i;
  }
  EXPECT_GT(changed, n / 8);
}

TEST(ClippedReal, TheShadingPassTakesAClippedFloorsShadowFromTheLightsPrediction) {
  // A floor of albedo 0.5 under a sun of 10 W/m^2 at 37 degrees from the zenith (8 on the floor) and an ambient of
  // 0.1: its radiance is 0.5 (8 + 0.1 pi) / pi = 1.32. The camera's white at 1: the floor clipped. A cube's
  // shadow beside it blocks the sun.
  auto ctx = makeContext();
  const int W = 64, H = 48;
  const TestScene s = makeScene(false, 0.2, {0.0, 0.0, 0.1});
  LightingPipeline pipe = makePipeline(testConfig(W, H, 16, 64, "none"), s);
  const cv::Mat albedo(H, W, CV_32FC3, cv::Scalar::all(kFloorAlbedo[0]));
  const auto shade = [&](const cv::Mat& clipped, double white) {
    pipe.setRealPixelAlbedo(albedo, clipped);
    pipe.setCameraWhite(white);
    SceneLight sun = sunDown();
    sun.direction = {0.6, 0, -0.8};
    pipe.run(topCamera(W, H), {sun}, {0.1, 0.1, 0.1}, nullptr);
    return pipe.downloadShade();
  };
  const cv::Mat measured = shade(cv::Mat(), 0), clipped = shade(cv::Mat(H, W, CV_8UC1, cv::Scalar(7)), 1.0),
                unclippedWhite = shade(cv::Mat(H, W, CV_8UC1, cv::Scalar(0)), 1.0);
  const double predicted = 0.5 * (8 + 0.1 * CV_PI) / CV_PI;
  int deep = 0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const cv::Vec4f m = measured.at<cv::Vec4f>(y, x), c = clipped.at<cv::Vec4f>(y, x);
      ASSERT_EQ(unclippedWhite.at<cv::Vec4f>(y, x), m) << "no clipped channel: unchanged";
      if (m[3] > 0.5f) continue;  // the cube's own pixels
      const cv::Vec3f want = lighting::clippedRealShade({m[0], m[1], m[2]}, cv::Vec3f::all(float(predicted)), 1.0f, 7);
      for (int k = 0; k < 3; ++k) ASSERT_NEAR(c[k], want[k], 2e-3 * predicted) << x << "," << y;
      deep += m[0] < -1.0f;  // the sun's shadow: 1 + shaded is the shadowed floor's 0.05, not 1.32 - 1.27
    }
  EXPECT_GT(deep, 20);
}

}  // namespace
}  // namespace mrgi::test
