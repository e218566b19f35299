#pragma once
/// Our poses (capture::Pose, a cv::Matx44d) as Open3D takes and gives them: Eigen matrices for its legacy
/// pipelines (TSDF integration, pose graphs) and Float64 tensors for its tensor pipelines (odometry,
/// registration). Internal to reconstruction/: only files that link Open3D include it.
#include <open3d/core/Tensor.h>

#include <Eigen/Core>

#include "capture/types.h"

namespace mrgi::reconstruction {

inline Eigen::Matrix4d toEigen(const capture::Pose& T) {
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = T(r, c);
  return m;
}

inline capture::Pose fromEigen(const Eigen::Matrix4d& m) {
  capture::Pose T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = m(r, c);
  return T;
}

inline open3d::core::Tensor poseTensor(const capture::Pose& T) {
  return open3d::core::Tensor(std::vector<double>(T.val, T.val + 16), {4, 4}, open3d::core::Float64);
}

inline capture::Pose poseOf(const open3d::core::Tensor& t) {
  const open3d::core::Tensor c = t.To(open3d::core::Float64).Contiguous();
  const double* p = c.GetDataPtr<double>();
  capture::Pose T;
  for (int i = 0; i < 16; ++i) T.val[i] = p[i];
  return T;
}

}  // namespace mrgi::reconstruction
