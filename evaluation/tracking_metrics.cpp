#include "evaluation/tracking_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "reconstruction/marker.h"
#include "reconstruction/point_index.h"

namespace mrgi::evaluation {

TrajectoryError trajectoryError(const std::vector<std::optional<capture::Pose>>& estimate,
                                const std::vector<capture::Pose>& truth) {
  TrajectoryError e;
  double ate2 = 0, rpe2 = 0, rpeDeg2 = 0;
  int pairs = 0;
  const size_t n = std::min(estimate.size(), truth.size());
  e.frames = static_cast<int>(n);
  for (size_t i = 0; i < n; ++i) {
    if (!estimate[i]) continue;
    ++e.tracked;
    const double d = reconstruction::translationError(*estimate[i], truth[i]);
    ate2 += d * d, e.ateMaxM = std::max(e.ateMaxM, d), e.lastM = d;
    if (i > 0 && estimate[i - 1]) {
      const capture::Pose a = capture::inversePose(*estimate[i - 1]) * *estimate[i];
      const capture::Pose b = capture::inversePose(truth[i - 1]) * truth[i];
      const double t = reconstruction::translationError(a, b), r = reconstruction::rotationErrorDeg(a, b);
      rpe2 += t * t, rpeDeg2 += r * r, ++pairs;
    }
  }
  if (e.tracked) e.ateRmseM = std::sqrt(ate2 / e.tracked);
  if (pairs) e.rpeRmseM = std::sqrt(rpe2 / pairs), e.rpeRmseDeg = std::sqrt(rpeDeg2 / pairs);
  return e;
}

SurfaceDistance surfaceDistance(const reconstruction::RoomMesh& from, const reconstruction::RoomMesh& to) {
  SurfaceDistance s;
  s.points = from.positions.size();
  if (from.positions.empty() || to.positions.empty()) {
    s.meanM = s.p90M = std::numeric_limits<double>::infinity();
    return s;
  }
  reconstruction::PointCloudAdaptor adaptor{to.positions};
  reconstruction::PointKdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  std::vector<double> d(from.positions.size());
  double sum = 0;
  size_t within = 0;
  for (size_t i = 0; i < from.positions.size(); ++i) {
    uint32_t nearest = 0;
    float d2 = 0;
    tree.knnSearch(&from.positions[i][0], 1, &nearest, &d2);
    const cv::Vec3d delta = cv::Vec3d(from.positions[i]) - cv::Vec3d(to.positions[nearest]);
    double dist = std::sqrt(static_cast<double>(d2));
    if (nearest < to.normals.size()) {
      const cv::Vec3d n(to.normals[nearest]);
      if (cv::norm(n) > 0.5) dist = std::min(dist, std::abs(delta.dot(n)));
    }
    d[i] = dist, sum += dist, within += dist <= 0.02;
  }
  s.meanM = sum / static_cast<double>(d.size());
  std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() * 9 / 10), d.end());
  s.p90M = d[d.size() * 9 / 10];
  s.within2cm = static_cast<double>(within) / static_cast<double>(d.size());
  return s;
}

}  // namespace mrgi::evaluation
