#pragma once
/// nanoflann's k-d tree over a vector of 3D points held by reference (the points must outlive the tree):
/// nearest sparse points of a mesh vertex (Kinect-VAL), nearest room vertex of a depth-mesh vertex or of a
/// point a room bounce ray leaves through. Constructing the tree builds its index (nanoflann's default flags).
#include <cmath>
#include <cstdint>
#include <limits>
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

/// nanoflann's result set for the one nearest point, ties to the lowest index: the same answer whatever point the
/// search starts from (nanoflann's own keeps the first of equals it meets).
struct NearestPointResult {
  uint32_t index = 0;
  float d2 = std::numeric_limits<float>::infinity();
  bool found = false;
  size_t size() const { return found ? 1 : 0; }
  bool full() const { return found; }
  bool addPoint(float dist, uint32_t i) {
    if (dist < d2 || (dist == d2 && i < index)) d2 = dist, index = i, found = true;
    return true;
  }
  /// Just above the best so far: a point at the same distance is still offered (the tie rule decides).
  float worstDist() const { return found ? std::nextafter(d2, std::numeric_limits<float>::infinity()) : d2; }
};

/// The point of `points` (which `tree` indexes) nearest `q`, ties to the lowest index; `seed` (an index into
/// `points`, or < 0 for none) is a point thought to lie near: the search starts with it as the best so far, which
/// prunes most of the tree when it is close (a neighbouring pixel's answer). The answer does not depend on the seed.
/// False only for an empty set.
inline bool nearestPoint(const PointKdTree& tree, const std::vector<cv::Vec3f>& points, const cv::Vec3f& q,
                         int64_t seed, uint32_t& index, float& d2) {
  NearestPointResult r;
  if (seed >= 0 && static_cast<size_t>(seed) < points.size()) {
    const cv::Vec3f& s = points[static_cast<size_t>(seed)];
    float d = 0;  // as nanoflann's L2_Simple_Adaptor sums it
    for (int k = 0; k < 3; ++k) {
      const float diff = q[k] - s[k];
      d += diff * diff;
    }
    r.addPoint(d, static_cast<uint32_t>(seed));
  }
  tree.findNeighbors(r, &q[0], nanoflann::SearchParams());
  if (!r.found) return false;
  index = r.index, d2 = r.d2;
  return true;
}

}  // namespace mrgi::reconstruction
