// The GPU merge against its CPU reference (same math), plus the properties of Algorithm 1.
#include "compositor/compositor.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "capture/colour.h"
#include "gl/context.h"

using namespace mrgi;

namespace {
struct CompositorTest : ::testing::Test {
  void SetUp() override {
    gl::ContextConfig cfg;
    cfg.width = kW;
    cfg.height = kH;
    ctx = gl::createContext(cfg);
    background = cv::Mat(kH, kW, CV_8UC3);
    cv::randu(background, 0, 256);
  }
  static constexpr int kW = 96, kH = 64;
  std::unique_ptr<gl::Context> ctx;
  cv::Mat background;
};
}  // namespace

TEST(Colour, SrgbRoundTripIsExactFor8Bit) {
  for (int i = 0; i < 256; ++i)
    EXPECT_EQ(std::lround(capture::linearToSrgb(capture::srgbToLinear(i / 255.f)) * 255.f), i);
  EXPECT_EQ(capture::linearToSrgb(std::numeric_limits<float>::quiet_NaN()), 0.f);
  EXPECT_EQ(capture::linearToSrgb(1e30f), 1.f);
  EXPECT_EQ(capture::linearToSrgb(-5.f), 0.f);
  EXPECT_NEAR(capture::srgbToLinear(0.5f), 0.214041f, 1e-6f);  // IEC 61966-2-1
}

TEST_F(CompositorTest, NoDeltaGivesTheBackgroundUntouched) {
  compositor::Compositor comp(kW, kH);
  const cv::Mat out = comp.composite(background, cv::Mat(), cv::Mat(), nullptr);
  EXPECT_EQ(cv::norm(out, background, cv::NORM_INF), 0.0);  // decode + encode round-trips every 8-bit value
}

TEST_F(CompositorTest, GpuMatchesCpuReference) {
  cv::Mat delta(kH, kW, CV_32FC3);
  cv::randn(delta, 0.0, 0.2);  // negative deltas (shadows) and positive ones (bounce light)
  cv::Mat mask(kH, kW, CV_8UC1, cv::Scalar(0));
  cv::rectangle(mask, cv::Rect(10, 10, 30, 20), cv::Scalar(255), cv::FILLED);
  delta.at<cv::Vec3f>(0, 0) = {std::numeric_limits<float>::quiet_NaN(), 1e30f, -1e30f};
  compositor::Compositor comp(kW, kH);
  gl::Profiler prof;
  const cv::Mat gpu = comp.composite(background, delta, mask, &prof);
  const cv::Mat cpu = compositor::compositeReference(background, delta, mask);
  // GPU pow/exp differ from libm in the last bits: at most one 8-bit level after rounding.
  EXPECT_LE(cv::norm(gpu, cpu, cv::NORM_INF), 1.0);
  EXPECT_EQ(gpu.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 255, 0));  // NaN -> 0, huge -> 1, -huge -> 0
  EXPECT_EQ(prof.resolve().count("composite"), 1u);
  // A darkening delta on a real pixel lowers it; a virtual pixel ignores the background.
  cv::Mat dark(kH, kW, CV_32FC3, cv::Scalar(-0.05f, -0.05f, -0.05f));
  const cv::Mat shadowed = comp.composite(background, dark, cv::Mat(), nullptr);
  EXPECT_LT(cv::sum(shadowed)[0], cv::sum(background)[0]);
  cv::Mat all(kH, kW, CV_8UC1, cv::Scalar(255));
  const float level128 = capture::srgbToLinear(128.f / 255.f);
  cv::Mat half(kH, kW, CV_32FC3, cv::Scalar(level128, level128, level128));
  const cv::Mat virt = comp.composite(background, half, all, nullptr);
  EXPECT_EQ(virt.at<cv::Vec3b>(5, 5), cv::Vec3b(128, 128, 128));
}

TEST_F(CompositorTest, TheCameraExposureScalesDeltaAndVirtualRadianceOnGpuAndCpu) {
  // A camera at exposure 0.5 records half the scene radiance: a virtual pixel of radiance 2 x level128
  // reads 128, and a real pixel's delta counts half.
  const float level128 = capture::srgbToLinear(128.f / 255.f);
  cv::Mat radiance(kH, kW, CV_32FC3, cv::Scalar::all(2 * level128));
  cv::Mat mask(kH, kW, CV_8UC1, cv::Scalar(0));
  mask(cv::Rect(0, 0, kW / 2, kH)).setTo(255);
  compositor::Compositor comp(kW, kH);
  comp.setExposure(0.5);
  const cv::Mat gpu = comp.composite(background, radiance, mask, nullptr);
  const cv::Mat cpu = compositor::compositeReference(background, radiance, mask, 0.5);
  EXPECT_LE(cv::norm(gpu, cpu, cv::NORM_INF), 1.0);
  EXPECT_EQ(gpu.at<cv::Vec3b>(5, 5), cv::Vec3b(128, 128, 128));
  EXPECT_EQ(cpu.at<cv::Vec3b>(5, 5), cv::Vec3b(128, 128, 128));
  // Real half: background + 0.5 x delta.
  const int x = kW - 3, y = 5;
  const cv::Vec3b b = background.at<cv::Vec3b>(y, x);
  const float expected = capture::linearToSrgb(capture::srgbToLinear(b[0] / 255.f) + level128) * 255.f;
  EXPECT_NEAR(gpu.at<cv::Vec3b>(y, x)[0], expected, 1.0);
  comp.setExposure(1.0);
  EXPECT_EQ(comp.composite(background, radiance, mask, nullptr).at<cv::Vec3b>(5, 5)[0],
            std::lround(capture::linearToSrgb(2 * level128) * 255.f));
}
