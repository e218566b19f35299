// The radiance map the shading pass reads what the objects hide through (lighting/radiance_map.h): its levels
// keep the map's light, a sample follows GL's filtering, and a cap's cosine-weighted mean is the integral.
#include "lighting/radiance_map.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace mrgi::lighting {
namespace {

/// A lat-long map of radiance f(direction), each texel the mean over its solid angle (8 x 8 points).
template <class F>
cv::Mat latLong(int width, F f) {
  cv::Mat m(width / 2, width, CV_32FC3);
  for (int v = 0; v < m.rows; ++v)
    for (int u = 0; u < m.cols; ++u) {
      const double z0 = std::cos(CV_PI * v / m.rows), z1 = std::cos(CV_PI * (v + 1) / m.rows);
      double sum = 0;
      for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j) {
          const double z = z0 + (z1 - z0) * (i + 0.5) / 8, s = std::sqrt(1 - z * z),
                       p = 2 * CV_PI * (u + (j + 0.5) / 8) / m.cols;
          sum += f(cv::Vec3d(s * std::cos(p), s * std::sin(p), z));
        }
      m.at<cv::Vec3f>(v, u) = cv::Vec3f::all(static_cast<float>(sum / 64));
    }
  return m;
}

/// The cosine-weighted integral over the cap of half-angle alpha about w of radiance f, by a fine midpoint rule.
template <class F>
double capIntegral(const cv::Vec3d& w, double alpha, const cv::Vec3d& n, F f) {
  const cv::Vec3d t = cv::normalize(w.cross(std::abs(w[2]) < 0.9 ? cv::Vec3d(0, 0, 1) : cv::Vec3d(1, 0, 0)));
  const cv::Vec3d b = w.cross(t);
  const int N = 400;
  double sum = 0;
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) {
      const double c = 1 - (1 - std::cos(alpha)) * (i + 0.5) / N, s = std::sqrt(1 - c * c),
                   p = 2 * CV_PI * (j + 0.5) / N;
      const cv::Vec3d d = s * std::cos(p) * t + s * std::sin(p) * b + c * w;
      sum += std::max(0.0, d.dot(n)) * f(d);
    }
  return sum * 2 * CV_PI * (1 - std::cos(alpha)) / (double(N) * N);
}

TEST(RadianceMap, LevelsKeepTheLightAndAUniformMapReadsUniformEverywhere) {
  const RadianceMap uniform(cv::Mat(32, 64, CV_32FC3, cv::Scalar(0.5, 1.0, 2.0)));
  ASSERT_EQ(uniform.levels().size(), 7u);  // 64 x 32 down to 1 x 1
  EXPECT_EQ(uniform.levels().back().size(), cv::Size(1, 1));
  for (const cv::Vec3f& w : {cv::Vec3f(0, 0, 1), cv::Vec3f(0, 0, -1), cv::Vec3f(1, 0, 0), cv::Vec3f(-0.6f, -0.8f, 0)})
    for (const float lod : {0.0f, 0.5f, 2.3f, 6.0f, 40.0f, -3.0f, NAN}) {
      const cv::Vec3f L = uniform.sample(w, lod);
      EXPECT_FLOAT_EQ(L[0], 0.5f);
      EXPECT_FLOAT_EQ(L[2], 2.0f);
    }
  // Each level is the mean of the one before: the last one is the map's mean texel.
  cv::RNG rng(3);
  cv::Mat noisy(32, 64, CV_32FC3);
  rng.fill(noisy, cv::RNG::UNIFORM, 0.0, 4.0);
  const RadianceMap m(noisy);
  const cv::Scalar mean = cv::mean(noisy);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(m.levels().back().at<cv::Vec3f>(0, 0)[c], mean[c], 1e-5);
  // The azimuth repeats: either side of the seam at +x reads the same.
  const cv::Vec3f a = m.sample(cv::normalize(cv::Vec3f(1, 1e-4f, 0.2f)), 0),
                  b = m.sample(cv::normalize(cv::Vec3f(1, -1e-4f, 0.2f)), 0);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 0.02);  // texels differ by up to 4
}

TEST(RadianceMap, ACapsCosineWeightedMeanIsTheIntegralOverTheCap) {
  // The mean over a cap, weighted by the cosine about a normal, times the cap's cosine-weighted solid angle is the
  // integral: within 1.5 % for a smooth sky (brighter towards +z; measured 1.1 % at most, a 3 degree cap near the
  // horizon read from one texel); with a bright band beside it, sharp-edged, within 3 % for caps of 30 degrees and
  // more, 7 % at 11 degrees (measured 2.0 and 6.1 %: the 64 x 32 map's texels are 5.6 degrees; a smaller cap beside
  // an edge is only as sharp as the map).
  const auto smooth = [](const cv::Vec3d& d) { return 0.2 + 0.8 * std::max(0.0, d[2]) + 0.3 * d[0] * d[0]; };
  const auto banded = [&](const cv::Vec3d& d) {
    return smooth(d) + (d[0] < -0.5 && d[2] > 0 && d[2] < 0.6 ? 2.0 : 0.0);
  };
  const RadianceMap smoothMap(latLong(64, smooth)), bandedMap(latLong(64, banded));
  int caps = 0;
  for (const double alpha : {0.05, 0.2, 0.5, 0.9, 1.3})
    for (const cv::Vec3d& w0 :
         {cv::Vec3d(0, 0, 1), cv::Vec3d(-1, 0, 0.3), cv::Vec3d(-1, 0.5, 1), cv::Vec3d(0.3, 0.2, 0.1)}) {
      const cv::Vec3d w = cv::normalize(w0), n(0, 0, 1);
      const double weights = capIntegral(w, alpha, n, [](const cv::Vec3d&) { return 1.0; });
      if (!(weights > 1e-4)) continue;
      const float omc = static_cast<float>(1 - std::cos(alpha));
      const double exactSmooth = capIntegral(w, alpha, n, smooth), exactBanded = capIntegral(w, alpha, n, banded);
      const double smoothMean = smoothMap.capMean(cv::Vec3f(w), omc, cv::Vec3f(n))[0];
      const double bandedMean = bandedMap.capMean(cv::Vec3f(w), omc, cv::Vec3f(n))[0];
      EXPECT_NEAR(smoothMean * weights, exactSmooth, 0.015 * exactSmooth) << "alpha " << alpha << " towards " << w;
      if (alpha >= 0.2) {
        EXPECT_NEAR(bandedMean * weights, exactBanded, (alpha >= 0.5 ? 0.03 : 0.07) * exactBanded)
            << "alpha " << alpha << " towards " << w;
      }
      ++caps;
    }
  EXPECT_GE(caps, 18);
  const RadianceMap& map = bandedMap;
  // Tiny caps and grazing normals stay finite.
  for (const float omc : {0.0f, 1e-12f, 1e-6f, 1.0f, 2.0f}) {
    const cv::Vec3f L = map.capMean({0, 0, 1}, omc, {1, 0, 0});
    EXPECT_TRUE(std::isfinite(L[0]) && L[0] >= 0) << omc;
  }
}

TEST(RadianceMap, NegativeNonFiniteOrMisshapenMapsAreRefused) {
  EXPECT_THROW(RadianceMap{cv::Mat()}, std::invalid_argument);
  EXPECT_THROW(RadianceMap{cv::Mat(32, 60, CV_32FC3, cv::Scalar::all(1))}, std::invalid_argument);
  EXPECT_THROW(RadianceMap{cv::Mat(2, 4, CV_32FC3, cv::Scalar::all(1))}, std::invalid_argument);
  EXPECT_THROW(RadianceMap{cv::Mat(32, 64, CV_32FC1, cv::Scalar::all(1))}, std::invalid_argument);
  cv::Mat bad(32, 64, CV_32FC3, cv::Scalar::all(1));
  bad.at<cv::Vec3f>(3, 4)[1] = -1;
  EXPECT_THROW(RadianceMap{bad}, std::invalid_argument);
  bad.at<cv::Vec3f>(3, 4)[1] = NAN;
  EXPECT_THROW(RadianceMap{bad}, std::invalid_argument);
}

}  // namespace
}  // namespace mrgi::lighting
