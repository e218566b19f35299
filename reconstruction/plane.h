#pragma once
/// Planes in a depth frame (OpenCV's rgbd plane segmentation) and the support plane an inserted object
/// rests on ("snap to the table").
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "capture/types.h"

namespace mrgi::reconstruction {

/// Plane n·x + d = 0 with unit n; in the camera frame n faces the camera (d > 0 for a plane in front of it).
struct Plane {
  cv::Vec3d normal{0, 0, 1};
  double d = 0;
  int inliers = 0;  ///< pixels labelled with this plane
  cv::Vec3d centroid{0, 0, 0};
  double signedDistance(const cv::Vec3d& p) const { return normal.dot(p) + d; }
};

/// The plane expressed in another frame: T_new_old maps points of the plane's frame into the new one.
Plane transformPlane(const Plane& plane, const capture::Pose& T_new_old);

struct PlaneOptions {
  double thresholdMetres = 0.01;  ///< largest point-to-plane distance of a member (at 1 m; grows as z²)
  double minFraction = 0.02;      ///< smallest plane, as a fraction of the frame's valid pixels
};

/// Planar regions of a frame (camera-frame positions and normals as from backProject/computeNormals,
/// (0, 0, 0) = invalid), largest first; `labels` (optional) gets CV_8UC1 plane indices, 255 = none.
std::vector<Plane> findPlanes(const cv::Mat& positions, const cv::Mat& normals, const PlaneOptions& options = {},
                              cv::Mat* labels = nullptr);

/// The plane an object at `point` rests on, all in one frame: among planes within maxTiltDeg of `up`
/// that lie below the point, the one directly under it (its foot point lands on the plane's own pixels,
/// seen through `T_camera_frame` and `k`), else the nearest below it. Planes are in the same frame as
/// the point; `labels` from findPlanes (camera image).
std::optional<Plane> supportPlane(const std::vector<Plane>& planes, const cv::Vec3d& point, const cv::Vec3d& up,
                                  const cv::Mat& labels, const capture::Pose& T_camera_frame,
                                  const capture::Intrinsics& k, double maxTiltDeg = 45.0);

/// A world founded on a frame without a marker: z up along the dominant plane under the view's centre (the
/// plane whose pixels hold the image centre, else the largest one facing the camera from below it: the floor
/// or the table), its origin where the centre's viewing ray meets that plane (its seen centroid when the ray
/// meets it beyond twice the centroid's distance: a view along the floor), x along the camera's x axis
/// laid on the plane. Returns T_camera_world; nullopt when the frame holds no such plane.
std::optional<capture::Pose> worldOnDominantPlane(const cv::Mat& positions, const cv::Mat& normals,
                                                  const capture::Intrinsics& k);

/// Rests an object on a plane: its pose's up axis (the pose's +z) turns onto the plane normal (smallest
/// rotation), its origin moves onto the plane along the normal, then up until the lowest of `points`
/// (object space) touches the plane. Poses map object to the plane's frame.
capture::Pose restOnPlane(const capture::Pose& T_frame_object, const std::vector<cv::Vec3f>& points,
                          const Plane& plane);

}  // namespace mrgi::reconstruction
