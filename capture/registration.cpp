#include "capture/registration.h"

#include <algorithm>
#include <cmath>

namespace mrgi::capture {

cv::Mat registerDepthToColour(const cv::Mat& depth, const Intrinsics& dk, const Intrinsics& ck, const Pose& T,
                              int maxSplat) {
  CV_Assert(depth.type() == CV_32FC1 && depth.cols == dk.width && depth.rows == dk.height && dk.valid() && ck.valid());
  cv::Mat out(ck.height, ck.width, CV_32FC1, cv::Scalar(0));
  auto project = [&](double u, double v, double z, double& cu, double& cv_, double& cz) {
    const cv::Vec3d p = transformPoint(T, {(u - dk.cx) * z / dk.fx, (v - dk.cy) * z / dk.fy, z});
    cz = p[2];
    cu = ck.fx * p[0] / cz + ck.cx;
    cv_ = ck.fy * p[1] / cz + ck.cy;
  };
  for (int v = 0; v < depth.rows; ++v) {
    const float* row = depth.ptr<float>(v);
    for (int u = 0; u < depth.cols; ++u) {
      const float z = row[u];
      if (!(z > 0.f) || !std::isfinite(z)) continue;
      // Footprint: project the pixel's corners at this depth.
      double lo[2] = {1e30, 1e30}, hi[2] = {-1e30, -1e30}, cz = 0;
      bool ok = true;
      for (int c = 0; c < 4 && ok; ++c) {
        double cu, cvv, zz;
        project(u + (c % 2 ? 0.5 : -0.5), v + (c / 2 ? 0.5 : -0.5), z, cu, cvv, zz);
        if (!(zz > 0)) ok = false;
        lo[0] = std::min(lo[0], cu), hi[0] = std::max(hi[0], cu);
        lo[1] = std::min(lo[1], cvv), hi[1] = std::max(hi[1], cvv);
        cz += zz / 4;
      }
      if (!ok) continue;
      const int x0 = static_cast<int>(std::ceil(lo[0] - 0.5)),
                x1 = std::min(static_cast<int>(std::floor(hi[0] - 0.5)), x0 + maxSplat - 1);
      const int y0 = static_cast<int>(std::ceil(lo[1] - 0.5)),
                y1 = std::min(static_cast<int>(std::floor(hi[1] - 0.5)), y0 + maxSplat - 1);
      for (int y = std::max(y0, 0); y <= std::min(y1, ck.height - 1); ++y)
        for (int x = std::max(x0, 0); x <= std::min(x1, ck.width - 1); ++x) {
          float& o = out.at<float>(y, x);
          if (o == 0.f || cz < o) o = static_cast<float>(cz);
        }
    }
  }
  return out;
}

void ensureRegistered(RgbdFrame& f) {
  if (f.depthRegistered) return;
  f.depth = registerDepthToColour(f.depth, f.depthIntrinsics, f.colourIntrinsics, f.T_colour_depth);
  f.depthIntrinsics = f.colourIntrinsics;
  f.T_colour_depth = identityPose();
  f.depthRegistered = true;
}

}  // namespace mrgi::capture
