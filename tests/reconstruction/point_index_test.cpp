// The nearest point through the k-d tree (reconstruction/point_index.h): parity with nanoflann's own search and with
// a brute-force scan, whatever point the search is seeded with, ties included.
#include "reconstruction/point_index.h"

#include <gtest/gtest.h>

#include <random>

namespace mrgi::reconstruction {
namespace {

// The nearest point by a scan: the smallest squared distance (summed as nanoflann sums it), ties to the lowest index.
uint32_t nearestByScan(const std::vector<cv::Vec3f>& points, const cv::Vec3f& q) {
  uint32_t best = 0;
  float bestD2 = std::numeric_limits<float>::infinity();
  for (size_t i = 0; i < points.size(); ++i) {
    float d = 0;
    for (int k = 0; k < 3; ++k) {
      const float diff = q[k] - points[i][k];
      d += diff * diff;
    }
    if (d < bestD2) bestD2 = d, best = static_cast<uint32_t>(i);
  }
  return best;
}

TEST(NearestPoint, AnySeedGivesTheScansAnswerAndNanoflannsWhereNothingTies) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<cv::Vec3f> points(5000);
  for (auto& p : points) p = {u(rng), u(rng), 0.3f * u(rng)};  // a slab, as a room's surface is
  const PointCloudAdaptor cloud{points};
  const PointKdTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  std::uniform_int_distribution<int> pick(0, static_cast<int>(points.size()) - 1);
  for (int n = 0; n < 2000; ++n) {
    const cv::Vec3f q(1.2f * u(rng), 1.2f * u(rng), 0.5f * u(rng));
    const uint32_t expected = nearestByScan(points, q);
    uint32_t flann = 0;
    float flannD2 = 0;
    ASSERT_EQ(tree.knnSearch(&q[0], 1, &flann, &flannD2), 1u);
    EXPECT_EQ(flann, expected);
    // No seed, a far seed, a near one (the answer itself), and a neighbour's answer.
    for (const int64_t seed : {int64_t{-1}, int64_t{pick(rng)}, int64_t{expected}, int64_t{(expected + 1) % 5000}}) {
      uint32_t index = 0;
      float d2 = 0;
      ASSERT_TRUE(nearestPoint(tree, points, q, seed, index, d2));
      EXPECT_EQ(index, expected) << "seed " << seed;
      EXPECT_EQ(d2, flannD2);
    }
  }
}

TEST(NearestPoint, TiesGoToTheLowestIndexWhateverTheSeed) {
  // A grid with every point twice (indices i and i + n): each query ties between the two copies, and a query midway
  // between grid points ties between neighbours as well.
  std::vector<cv::Vec3f> points;
  for (int x = 0; x < 10; ++x)
    for (int y = 0; y < 10; ++y) points.push_back({x * 0.25f, y * 0.25f, 0.f});
  const size_t n = points.size();
  for (size_t i = 0; i < n; ++i) points.push_back(points[i]);
  const PointCloudAdaptor cloud{points};
  const PointKdTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(4));
  for (const cv::Vec3f q :
       {cv::Vec3f(0.5f, 0.75f, 0.1f), cv::Vec3f(0.625f, 0.75f, 0.f), cv::Vec3f(1.125f, 1.125f, 0.f)})
    for (int64_t seed = -1; seed < static_cast<int64_t>(points.size()); ++seed) {
      uint32_t index = 0;
      float d2 = 0;
      ASSERT_TRUE(nearestPoint(tree, points, q, seed, index, d2));
      EXPECT_EQ(index, nearestByScan(points, q)) << "seed " << seed;
      EXPECT_LT(index, n);
    }
}

TEST(NearestPoint, AnEmptySetHasNone) {
  const std::vector<cv::Vec3f> points;
  const PointCloudAdaptor cloud{points};
  const PointKdTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  uint32_t index = 7;
  float d2 = 0;
  EXPECT_FALSE(nearestPoint(tree, points, cv::Vec3f(0, 0, 0), -1, index, d2));
  EXPECT_EQ(index, 7u);
}

}  // namespace
}  // namespace mrgi::reconstruction
