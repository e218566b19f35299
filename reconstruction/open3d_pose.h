#pragma once
/// Our poses (capture::Pose, a cv::Matx44d) as Open3D takes and gives them: Eigen matrices for its legacy
/// pipelines (meshes, pose graphs) and Float64 tensors for its tensor pipelines (odometry, registration, the
/// room's voxel block grid); and our intrinsics and float images as its tensors. Internal to reconstruction/:
/// only files that link Open3D include it.
#include <open3d/core/Blob.h>
#include <open3d/core/ShapeUtil.h>
#include <open3d/core/Tensor.h>

#include <Eigen/Core>
#include <opencv2/core.hpp>

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

/// The 3 x 3 Float64 camera matrix Open3D's tensor pipelines take.
inline open3d::core::Tensor intrinsicsTensor(const capture::Intrinsics& k) {
  return open3d::core::Tensor(std::vector<double>{k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1}, {3, 3},
                              open3d::core::Float64);
}

/// A Float32 tensor (rows x cols x channels) over a continuous float image's own pixels, not a copy: the
/// tensor's memory holds a reference to the image until the last tensor sharing it goes. Neither may be written
/// while the other is read.
inline open3d::core::Tensor imageTensor(const cv::Mat& m) {
  CV_Assert(m.depth() == CV_32F && m.isContinuous());
  const open3d::core::SizeVector shape{m.rows, m.cols, static_cast<int64_t>(m.channels())};
  auto blob = std::make_shared<open3d::core::Blob>(open3d::core::Device("CPU:0"), m.data, [keep = m](void*) {});
  return open3d::core::Tensor(shape, open3d::core::shape_util::DefaultStrides(shape), m.data, open3d::core::Float32,
                              blob);
}

}  // namespace mrgi::reconstruction
