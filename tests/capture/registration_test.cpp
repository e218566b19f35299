// Depth -> colour registration against geometry known in closed form.
#include "capture/registration.h"

#include <gtest/gtest.h>

using namespace mrgi::capture;

TEST(Registration, PlaneSeenFromABaselineLandsWhereTheColourCameraSeesIt) {
  // Depth camera 2.5 cm to the right of the colour camera (a Kinect-like baseline), different intrinsics
  // and resolution; a fronto-parallel plane at z = 1.5 m plus a nearer box at z = 0.8 m.
  const Intrinsics dk{320, 240, 285.0, 285.0, 159.5, 119.5};
  const Intrinsics ck{640, 480, 525.0, 525.0, 319.5, 239.5};
  Pose T = Pose::eye();
  T(0, 3) = 0.025;  // depth-camera origin in the colour frame
  cv::Mat depth(240, 320, CV_32FC1, cv::Scalar(1.5f));
  depth(cv::Rect(140, 100, 40, 40)).setTo(0.8f);
  depth.at<float>(5, 5) = 0.f;
  const cv::Mat reg = registerDepthToColour(depth, dk, ck, T);
  ASSERT_EQ(reg.size(), cv::Size(640, 480));
  // A colour pixel on the plane: depth exact (the plane is parallel to both image planes).
  EXPECT_FLOAT_EQ(reg.at<float>(400, 100), 1.5f);
  // The box centre (depth pixel 159.5, 119.5 at 0.8 m) is at x = 0.025 m in the colour camera:
  // u = 525 * 0.025 / 0.8 + 319.5 = 335.9.
  EXPECT_FLOAT_EQ(reg.at<float>(240, 336), 0.8f);
  // Occlusion: where box and plane overlap after the shift, the nearer surface wins.
  // Columns 40..599 lie inside the depth camera's narrower field of view (it covers colour u in 33.5..623).
  int nearer = 0, holes = 0;
  for (int y = 120; y < 360; ++y)
    for (int x = 40; x < 600; ++x) {
      nearer += reg.at<float>(y, x) == 0.8f;
      holes += reg.at<float>(y, x) == 0.f;
    }
  // Box footprint: 40 depth px * (525/285) colour px per depth px = 73.7 px square.
  EXPECT_NEAR(nearer, 73.7 * 73.7, 0.06 * 73.7 * 73.7);  // within 6 %: pixel-grid rounding of the edges
  // No cracks: the only holes are the disocclusion band left of the box, (16.4 - 8.75) px x 73.7 px = 564.
  EXPECT_NEAR(holes, 564, 80);
}

TEST(Registration, RegisteredFramesAreLeftAlone) {
  RgbdFrame f;
  f.depth = cv::Mat(4, 4, CV_32FC1, cv::Scalar(1.f));
  f.depthRegistered = true;
  ensureRegistered(f);
  EXPECT_EQ(f.depth.cols, 4);
}
