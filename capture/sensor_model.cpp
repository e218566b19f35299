#include "capture/sensor_model.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

namespace mrgi::capture {

cv::Mat applyDepthNoise(const cv::Mat& ideal, const cv::Mat& normals, double fx, double fy, double cx, double cy,
                        const DepthNoiseModel& m, uint64_t seed) {
  CV_Assert(ideal.type() == CV_32FC1 && normals.type() == CV_32FC3 && normals.size() == ideal.size());
  cv::RNG rng(seed);
  cv::Mat out = ideal.clone();
  const double cosMax = std::cos(m.maxIncidenceDeg * CV_PI / 180.0);
  for (int y = 0; y < ideal.rows; ++y) {
    for (int x = 0; x < ideal.cols; ++x) {
      const float z = ideal.at<float>(y, x);
      float& o = out.at<float>(y, x);
      if (!(z > 0) || z < m.minRange || z > m.maxRange) {
        o = 0;
        continue;
      }
      // Grazing angles: the return fades; drop with probability rising to 1 past the limit.
      const cv::Vec3f n = normals.at<cv::Vec3f>(y, x);
      cv::Vec3f ray(static_cast<float>((x - cx) / fx), static_cast<float>((y - cy) / fy), 1.f);
      ray = cv::normalize(ray);
      const double c = std::abs(n.dot(ray));
      if (c < cosMax || (c < 2 * cosMax && rng.uniform(0.0, 1.0) < (2 * cosMax - c) / cosMax)) {
        o = 0;
        continue;
      }
      // Edges: a farther surface beside a nearer one is shadowed from the projector.
      bool edge = false;
      for (int dy = -1; dy <= 1 && !edge; ++dy)
        for (int dx = -1; dx <= 1 && !edge; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= ideal.cols || yy >= ideal.rows) continue;
          const float zn = ideal.at<float>(yy, xx);
          edge = zn > 0 && z - zn > m.edgeJump;
        }
      if (edge && rng.uniform(0.0, 1.0) < m.edgeDropProbability) {
        o = 0;
        continue;
      }
      const double dz = z - m.sigmaZ0;
      o = static_cast<float>(z + rng.gaussian(m.sigmaA + m.sigmaB * dz * dz));
    }
  }
  for (int i = 0; i < m.holesPerFrame; ++i) {
    const cv::Point centre(rng.uniform(0, ideal.cols), rng.uniform(0, ideal.rows));
    const cv::Size axes(rng.uniform(2, static_cast<int>(m.maxHoleRadiusPx) + 3),
                        rng.uniform(2, static_cast<int>(m.maxHoleRadiusPx) + 3));
    cv::ellipse(out, centre, axes, rng.uniform(0.0, 180.0), 0, 360, cv::Scalar(0), cv::FILLED);
  }
  return out;
}

}  // namespace mrgi::capture
