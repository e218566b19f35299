#include "reconstruction/depth.h"

#include <gtest/gtest.h>

using namespace mrgi;

TEST(Depth, BackProjectionInvertsThePinholeModel) {
  const capture::Intrinsics k{64, 48, 50.0, 60.0, 31.5, 23.5};
  cv::Mat d(48, 64, CV_32FC1, cv::Scalar(2.0f));
  d.at<float>(10, 20) = 0.f;
  const cv::Mat p = reconstruction::backProject(d, k);
  const cv::Vec3f q = p.at<cv::Vec3f>(40, 60);
  EXPECT_FLOAT_EQ(q[0], static_cast<float>((60 - 31.5) * 2.0 / 50.0));
  EXPECT_FLOAT_EQ(q[1], static_cast<float>((40 - 23.5) * 2.0 / 60.0));
  EXPECT_FLOAT_EQ(q[2], 2.0f);
  EXPECT_EQ(p.at<cv::Vec3f>(10, 20), cv::Vec3f(0, 0, 0));
}

TEST(Depth, NormalsOfATiltedPlaneAndInvalidNeighbours) {
  // Plane z = 2 + 0.5 x (camera space): normal ∝ (0.5, 0, -1), facing the camera.
  const capture::Intrinsics k{64, 48, 50.0, 50.0, 31.5, 23.5};
  cv::Mat d(48, 64, CV_32FC1);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      const double u = (x - k.cx) / k.fx;
      d.at<float>(y, x) = static_cast<float>(2.0 / (1.0 - 0.5 * u));  // ray (u, v, 1) meets the plane
    }
  d.at<float>(20, 31) = 0.f;  // a hole: its neighbours fall back to one-sided differences
  const cv::Mat n = reconstruction::computeNormals(reconstruction::backProject(d, k));
  const cv::Vec3f expected = cv::normalize(cv::Vec3f(0.5f, 0.f, -1.f));
  for (cv::Point p : {cv::Point(10, 10), cv::Point(32, 20), cv::Point(30, 20), cv::Point(63, 47)}) {
    const cv::Vec3f got = n.at<cv::Vec3f>(p);
    EXPECT_GT(got.dot(expected), 0.9999f) << p;  // float positions: within ~0.8 degrees
  }
  EXPECT_EQ(n.at<cv::Vec3f>(20, 31), cv::Vec3f(0, 0, 0));
}
