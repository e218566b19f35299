#pragma once
/// nanoflann's k-d tree over a vector of 3D points held by reference (the points must outlive the tree):
/// nearest sparse points of a mesh vertex (Kinect-VAL), nearest room vertex of a depth-mesh vertex or of a
/// point a room bounce ray leaves through. Constructing the tree builds its index (nanoflann's default flags).
#include <cstdint>
#include <nanoflann.hpp>
#include <opencv2/core.hpp>
#include <vector>

namespace mrgi::reconstruction {

struct PointCloudAdaptor {
  const std::vector<cv::Vec3f>& p;
  size_t kdtree_get_point_count() const { return p.size(); }
  float kdtree_get_pt(size_t i, size_t d) const { return p[i][static_cast<int>(d)]; }
  template <class B>
  bool kdtree_get_bbox(B&) const {
    return false;
  }
};
using PointKdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointCloudAdaptor>,
                                                        PointCloudAdaptor, 3, uint32_t>;

}  // namespace mrgi::reconstruction
