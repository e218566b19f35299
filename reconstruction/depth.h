#pragma once
/// Depth-image geometry: back-projection and normals. Depth in metres, 0 = invalid; camera frame OpenCV
/// (x right, y down, z forward).
#include <opencv2/core.hpp>

#include "capture/types.h"

namespace mrgi::reconstruction {

/// True for a usable depth sample (finite, > 0).
inline bool validDepth(float z) { return z > 0.f && z < 1e30f; }

/// Camera-space positions (CV_32FC3, metres); invalid pixels get (0, 0, 0).
cv::Mat backProject(const cv::Mat& depth, const capture::Intrinsics& k);

/// Unit normals facing the camera (CV_32FC3) by central differences of back-projected positions, falling
/// back to one-sided differences beside invalid pixels; (0, 0, 0) where no two valid neighbours exist or
/// where a neighbour lies across a depth jump larger than maxRelativeJump * z.
cv::Mat computeNormals(const cv::Mat& positions, float maxRelativeJump = 0.05f);

}  // namespace mrgi::reconstruction
