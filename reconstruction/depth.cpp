#include "reconstruction/depth.h"

#include <cmath>
#include <opencv2/core/utility.hpp>

namespace mrgi::reconstruction {

cv::Mat backProject(const cv::Mat& depth, const capture::Intrinsics& k) {
  CV_Assert(depth.type() == CV_32FC1 && depth.cols == k.width && depth.rows == k.height && k.valid());
  cv::Mat out(depth.size(), CV_32FC3);
  for (int y = 0; y < depth.rows; ++y) {
    const float* d = depth.ptr<float>(y);
    auto* o = out.ptr<cv::Vec3f>(y);
    for (int x = 0; x < depth.cols; ++x) {
      const float z = d[x];
      o[x] = validDepth(z)
                 ? cv::Vec3f(static_cast<float>((x - k.cx) * z / k.fx), static_cast<float>((y - k.cy) * z / k.fy), z)
                 : cv::Vec3f(0, 0, 0);
    }
  }
  return out;
}

cv::Mat computeNormals(const cv::Mat& positions, float maxRelativeJump) {
  CV_Assert(positions.type() == CV_32FC3);
  cv::Mat out(positions.size(), CV_32FC3, cv::Scalar(0, 0, 0));
  const int w = positions.cols, h = positions.rows;
  auto at = [&](int x, int y) { return positions.at<cv::Vec3f>(y, x); };
  // Rows are independent (each writes its own): split over OpenCV's workers.
  cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      for (int x = 0; x < w; ++x) {
        const cv::Vec3f p = at(x, y);
        if (!(p[2] > 0.f)) continue;
        const float jump = maxRelativeJump * p[2];
        auto usable = [&](int xx, int yy) {
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) return false;
          const float z = at(xx, yy)[2];
          return z > 0.f && std::abs(z - p[2]) <= jump;
        };
        // Tangents: central difference when both neighbours are usable, else one-sided.
        auto tangent = [&](int dx, int dy, cv::Vec3f& t) {
          const bool fwd = usable(x + dx, y + dy), bwd = usable(x - dx, y - dy);
          if (fwd && bwd)
            t = at(x + dx, y + dy) - at(x - dx, y - dy);
          else if (fwd)
            t = at(x + dx, y + dy) - p;
          else if (bwd)
            t = p - at(x - dx, y - dy);
          else
            return false;
          return true;
        };
        cv::Vec3f tx, ty;
        if (!tangent(1, 0, tx) || !tangent(0, 1, ty)) continue;
        cv::Vec3f n = ty.cross(tx);  // x right, y down: ty x tx points towards the camera (-z)
        const float len = static_cast<float>(cv::norm(n));
        if (!(len > 0.f)) continue;
        n /= len;
        if (n.dot(p) > 0.f) n = -n;
        out.at<cv::Vec3f>(y, x) = n;
      }
    }
  });
  return out;
}

}  // namespace mrgi::reconstruction
