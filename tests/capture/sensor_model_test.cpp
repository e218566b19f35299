// Depth sensor model: noise level follows sigma(z), holes and grazing dropouts appear, determinism.
#include "capture/sensor_model.h"

#include <gtest/gtest.h>

using namespace mrgi::capture;

namespace {
cv::Mat facingNormals(int w, int h) { return cv::Mat(h, w, CV_32FC3, cv::Scalar(0, 0, -1)); }
}  // namespace

TEST(SensorModel, AxialNoiseMatchesSigmaOfDepth) {
  DepthNoiseModel m;
  m.holesPerFrame = 0;
  for (double z : {0.8, 2.0, 3.5}) {
    const cv::Mat ideal(200, 200, CV_32FC1, cv::Scalar(z));
    // A wide field of view would trigger grazing dropouts at the borders: use a long focal length.
    const cv::Mat noisy = applyDepthNoise(ideal, facingNormals(200, 200), 5000, 5000, 100, 100, m, 7);
    cv::Scalar mean, sd;
    cv::meanStdDev(noisy - ideal, mean, sd, noisy > 0);
    const double expected = m.sigmaA + m.sigmaB * (z - m.sigmaZ0) * (z - m.sigmaZ0);
    EXPECT_NEAR(sd[0], expected, 0.05 * expected) << "z = " << z;  // 40k samples: sd within 5 %
    EXPECT_NEAR(mean[0], 0.0, 0.05 * expected);
  }
}

TEST(SensorModel, DropoutsAtGrazingAnglesRangeAndHoles) {
  DepthNoiseModel m;
  m.holesPerFrame = 0;
  const cv::Mat ideal(50, 50, CV_32FC1, cv::Scalar(1.0));
  cv::Mat grazing(50, 50, CV_32FC3, cv::Scalar(0, -0.995, -0.0998));  // ~84 degrees from the view ray
  EXPECT_EQ(cv::countNonZero(applyDepthNoise(ideal, grazing, 5000, 5000, 25, 25, m, 1)), 0);
  const cv::Mat tooFar(50, 50, CV_32FC1, cv::Scalar(9.0));
  EXPECT_EQ(cv::countNonZero(applyDepthNoise(tooFar, facingNormals(50, 50), 5000, 5000, 25, 25, m, 1)), 0);
  m.holesPerFrame = 5;
  const cv::Mat holes = applyDepthNoise(ideal, facingNormals(50, 50), 5000, 5000, 25, 25, m, 3);
  EXPECT_LT(cv::countNonZero(holes), 2500);
  EXPECT_EQ(cv::norm(holes, applyDepthNoise(ideal, facingNormals(50, 50), 5000, 5000, 25, 25, m, 3), cv::NORM_INF),
            0.0);
}
