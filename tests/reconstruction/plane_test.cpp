#include "reconstruction/plane.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "reconstruction/depth.h"

using namespace mrgi;

namespace {

// A camera 1 m above a floor, looking down 40 degrees, with a wall across the far half of the view.
// Camera frame: OpenCV (y down). Floor: world z = 0 (up = world +z); wall: world y = 1.6.
struct Room {
  capture::Intrinsics k{160, 120, 120.0, 120.0, 79.5, 59.5};
  capture::Pose T_world_camera = capture::lookAtPose({0, -0.6, 1.0}, {0, 0.6, 0.0});
  cv::Mat depth;
  Room() {
    depth = cv::Mat(k.height, k.width, CV_32FC1, cv::Scalar(0));
    const cv::Matx33d R = capture::rotationOf(T_world_camera);
    const cv::Vec3d o = capture::translationOf(T_world_camera);
    for (int y = 0; y < k.height; ++y)
      for (int x = 0; x < k.width; ++x) {
        const cv::Vec3d ray((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0);  // z = 1 in the camera
        const cv::Vec3d dw = R * ray;
        double t = std::numeric_limits<double>::infinity();
        if (dw[2] < 0) t = std::min(t, -o[2] / dw[2]);                        // floor
        if (dw[1] > 0) t = std::min(t, (1.6 - o[1]) / dw[1]);                 // wall
        if (std::isfinite(t)) depth.at<float>(y, x) = static_cast<float>(t);  // depth = z in camera = t
      }
  }
};

}  // namespace

TEST(Plane, FindsFloorAndWallOfASyntheticRoom) {
  Room room;
  const cv::Mat p = reconstruction::backProject(room.depth, room.k);
  const cv::Mat n = reconstruction::computeNormals(p);
  cv::Mat labels;
  const auto planes = reconstruction::findPlanes(p, n, {}, &labels);
  ASSERT_GE(planes.size(), 2u);
  const capture::Pose& T = room.T_world_camera;
  bool floor = false, wall = false;
  for (const auto& plane : planes) {
    EXPECT_GT(plane.d, 0);  // camera on the positive side
    const auto w = reconstruction::transformPlane(plane, T);
    // World floor z = 0 facing the camera: n = +z, d = 0; wall y = 1.6 facing it: n = -y, d = 1.6.
    if (w.normal[2] > 0.999 && std::abs(w.d) < 0.005) floor = true;
    if (w.normal[1] < -0.999 && std::abs(w.d - 1.6) < 0.005) wall = true;
    EXPECT_GT(plane.inliers, 200);
  }
  EXPECT_TRUE(floor);
  EXPECT_TRUE(wall);
  EXPECT_GE(planes[0].inliers, planes[1].inliers);  // largest first
  EXPECT_EQ(labels.type(), CV_8UC1);
}

TEST(Plane, TransformKeepsPointsOnThePlane) {
  reconstruction::Plane p;
  p.normal = cv::normalize(cv::Vec3d(0.2, -0.9, -0.3));
  p.d = 1.3;
  const cv::Vec3d onPlane = -p.d * p.normal + cv::Vec3d(0.9, 0.2, 0).cross(p.normal) * 0.7;
  ASSERT_NEAR(p.signedDistance(onPlane), 0, 1e-12);
  const capture::Pose T = capture::lookAtPose({0.3, -0.2, 1.1}, {0, 0.5, 0});
  const auto q = reconstruction::transformPlane(p, T);
  EXPECT_NEAR(q.signedDistance(capture::transformPoint(T, onPlane)), 0, 1e-12);
  const cv::Vec3d off = onPlane + 0.25 * p.normal;
  EXPECT_NEAR(q.signedDistance(capture::transformPoint(T, off)), 0.25, 1e-12);
}

TEST(Plane, SupportPlaneIsTheFloorUnderThePointNotTheWall) {
  Room room;
  const cv::Mat p = reconstruction::backProject(room.depth, room.k);
  cv::Mat labels;
  const auto planes = reconstruction::findPlanes(p, reconstruction::computeNormals(p), {}, &labels);
  std::vector<reconstruction::Plane> world;
  for (const auto& pl : planes) world.push_back(reconstruction::transformPlane(pl, room.T_world_camera));
  const capture::Pose T_camera_world = capture::inversePose(room.T_world_camera);
  // A point 0.3 m above the floor and 0.2 m in front of the wall.
  const auto s = reconstruction::supportPlane(world, {0.1, 1.4, 0.3}, {0, 0, 1}, labels, T_camera_world, room.k);
  ASSERT_TRUE(s);
  EXPECT_GT(s->normal[2], 0.999);
  EXPECT_NEAR(s->signedDistance({0.1, 1.4, 0.3}), 0.3, 0.005);
  // With the up direction towards the room (the wall's normal) the wall is the support.
  const auto w = reconstruction::supportPlane(world, {0.1, 1.4, 0.3}, {0, -1, 0}, labels, T_camera_world, room.k);
  ASSERT_TRUE(w);
  EXPECT_LT(w->normal[1], -0.999);
  // Nothing within 45 degrees of a sideways up: no support.
  EXPECT_FALSE(reconstruction::supportPlane(world, {0.1, 1.4, 0.3}, {1, 0, 0}, labels, T_camera_world, room.k));
  // A point below the floor has none either.
  EXPECT_FALSE(reconstruction::supportPlane(world, {0.1, 1.0, -0.2}, {0, 0, 1}, labels, T_camera_world, room.k));
}

TEST(Plane, RestOnPlaneTouchesWithTheLowestPointAndAlignsUp) {
  reconstruction::Plane floor;
  floor.normal = cv::normalize(cv::Vec3d(0.1, 0.2, 1.0));
  floor.d = -0.05;
  // A unit-edge cube (object space, centred), tilted and floating.
  std::vector<cv::Vec3f> corners;
  for (int i = 0; i < 8; ++i) corners.emplace_back(i & 1 ? 0.5f : -0.5f, i & 2 ? 0.5f : -0.5f, i & 4 ? 0.5f : -0.5f);
  cv::Matx33d R;
  cv::Rodrigues(cv::Vec3d(0.4, -0.2, 0.9), R);
  const capture::Pose T = reconstruction::restOnPlane(capture::makePose(R, {0.3, -0.2, 2.0}), corners, floor);
  const cv::Vec3d up = capture::rotationOf(T) * cv::Vec3d(0, 0, 1);
  EXPECT_NEAR(up.dot(floor.normal), 1.0, 1e-12);
  double lowest = 1e9;
  for (const auto& c : corners)
    lowest = std::min(lowest, floor.signedDistance(capture::transformPoint(T, cv::Vec3d(c))));
  EXPECT_NEAR(lowest, 0.0, 1e-12);
  // The cube's face rests flat: four corners touch.
  int touching = 0;
  for (const auto& c : corners)
    touching += std::abs(floor.signedDistance(capture::transformPoint(T, cv::Vec3d(c)))) < 1e-9;
  EXPECT_EQ(touching, 4);
  // Upside-down input: the half turn still lands on the plane.
  cv::Matx33d flip;
  cv::Rodrigues(cv::Vec3d(CV_PI, 0, 0), flip);
  const capture::Pose U = reconstruction::restOnPlane(capture::makePose(flip, {0, 0, 1}), corners, floor);
  EXPECT_NEAR((capture::rotationOf(U) * cv::Vec3d(0, 0, 1)).dot(floor.normal), 1.0, 1e-9);
}
