#include "lighting/terms_history.h"

#include <cmath>

#include "lighting/upsample.h"

namespace mrgi::lighting {

HistoryCamera historyCamera(const CameraView& camera, int factor) {
  const capture::Intrinsics& k = camera.intrinsics;
  return {cv::Matx44f(capture::inversePose(camera.T_world_camera)),
          static_cast<float>(k.fx),
          static_cast<float>(k.fy),
          static_cast<float>(k.cx),
          static_cast<float>(k.cy),
          factor,
          cv::Size(reducedSize(k.width, factor), reducedSize(k.height, factor))};
}

std::optional<cv::Point> historyTexel(const HistoryCamera& previous, const cv::Vec3f& x) {
  const cv::Vec4f q = previous.cameraFromWorld * cv::Vec4f(x[0], x[1], x[2], 1.0f);
  if (!(q[2] > 1e-4f)) return std::nullopt;
  const float u = previous.fx * q[0] / q[2] + previous.cx, v = previous.fy * q[1] / q[2] + previous.cy;
  // The texel whose source pixel (i * factor + factor / 2) is nearest.
  const float f = static_cast<float>(previous.factor), half = static_cast<float>(previous.factor / 2);
  const float i = std::floor((u - half) / f + 0.5f), j = std::floor((v - half) / f + 0.5f);
  if (!(i >= 0.0f && j >= 0.0f && i < static_cast<float>(previous.grid.width) &&
        j < static_cast<float>(previous.grid.height)))
    return std::nullopt;
  return cv::Point(static_cast<int>(i), static_cast<int>(j));
}

bool historyAgrees(const cv::Vec3f& x, const cv::Vec3f& n, const cv::Vec3f& eye, const cv::Vec4f& previousPosition,
                   const cv::Vec4f& previousNormal) {
  if (!(previousPosition[3] > 0.5f)) return false;
  const cv::Vec3f d = cv::Vec3f(previousPosition[0], previousPosition[1], previousPosition[2]) - x;
  const float reach = kHistoryRelativeDistance * static_cast<float>(cv::norm(x - eye)) + kHistoryAbsoluteDistance;
  if (!(d.dot(d) <= reach * reach)) return false;
  return n.dot(cv::Vec3f(previousNormal[0], previousNormal[1], previousNormal[2])) >= kHistoryNormalCosine;
}

cv::Vec4f blendHistory(const cv::Vec4f& fresh, const cv::Vec4f& history, float weight, bool agrees) {
  if (!agrees || !(weight > 0.0f)) return fresh;
  for (int c = 0; c < 4; ++c)
    if (!std::isfinite(history[c])) return fresh;
  return (1.0f - weight) * fresh + weight * history;
}

}  // namespace mrgi::lighting
