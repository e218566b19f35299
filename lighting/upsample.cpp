#include "lighting/upsample.h"

#include <algorithm>
#include <cmath>

namespace mrgi::lighting {

namespace {

constexpr float kPlaneSine = 0.3f;  // upsample.h: the sine at which a texel's weight falls to 1/e
constexpr float kNoWeight = 1e-4f;  // below it the four texels around a pixel do not hold its surface

}  // namespace

int renderFactor(double renderScale) {
  if (!(renderScale > 0.0)) return 1;
  return static_cast<int>(std::clamp(std::lround(1.0 / renderScale), 1L, 4L));
}

float upsampleWeight(const cv::Vec4f& positionP, const cv::Vec4f& normalP, const cv::Vec4f& positionQ,
                     const cv::Vec4f& normalQ) {
  if (positionP[3] < 0.5f || positionQ[3] < 0.5f) return 0.f;
  if (std::abs(normalP[3] - normalQ[3]) > 0.5f) return 0.f;  // another object, or real against virtual
  const cv::Vec3f np(normalP[0], normalP[1], normalP[2]), nq(normalQ[0], normalQ[1], normalQ[2]);
  const cv::Vec3f d(positionQ[0] - positionP[0], positionQ[1] - positionP[1], positionQ[2] - positionP[2]);
  const float len = std::sqrt(d.dot(d));
  const float s = std::abs(np.dot(d)) / std::max(len, 1e-6f);
  const float c = std::max(np.dot(nq), 0.f), c2 = c * c, c4 = c2 * c2;
  const float w = std::exp(-(s * s) / (kPlaneSine * kPlaneSine)) * c4 * c4;
  return std::isfinite(w) ? w : 0.f;
}

cv::Mat reduceGBuffer(const cv::Mat& channel, int factor) {
  CV_Assert(channel.type() == CV_32FC4 && factor >= 1);
  cv::Mat out(reducedSize(channel.rows, factor), reducedSize(channel.cols, factor), CV_32FC4);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x)
      out.at<cv::Vec4f>(y, x) =
          channel.at<cv::Vec4f>(reducedSource(y, factor, channel.rows), reducedSource(x, factor, channel.cols));
  return out;
}

cv::Vec3f upsampleAt(const cv::Mat& value, const cv::Mat& lowPosition, const cv::Mat& lowNormal, int factor, int x,
                     int y, const cv::Vec4f& position, const cv::Vec4f& normal) {
  if (position[3] < 0.5f) return {0, 0, 0};
  // The pixel in the reduced grid: texel i sits on frame pixel i * factor + factor / 2.
  const float u = float(x - factor / 2) / float(factor), v = float(y - factor / 2) / float(factor);
  const int i0 = static_cast<int>(std::floor(u)), j0 = static_cast<int>(std::floor(v));
  const float tu = u - float(i0), tv = v - float(j0);
  const auto clampX = [&](int i) { return std::clamp(i, 0, value.cols - 1); };
  const auto clampY = [&](int j) { return std::clamp(j, 0, value.rows - 1); };
  cv::Vec3f sum(0, 0, 0);
  float total = 0.f;
  for (int dj = 0; dj < 2; ++dj)
    for (int di = 0; di < 2; ++di) {
      const int i = clampX(i0 + di), j = clampY(j0 + dj);
      const float b = (di ? tu : 1.f - tu) * (dj ? tv : 1.f - tv);
      const float w =
          b * upsampleWeight(position, normal, lowPosition.at<cv::Vec4f>(j, i), lowNormal.at<cv::Vec4f>(j, i));
      const cv::Vec4f q = value.at<cv::Vec4f>(j, i);
      sum += w * cv::Vec3f(q[0], q[1], q[2]);
      total += w;
    }
  if (total > kNoWeight) return sum / total;
  // A surface narrower than a block: the best texel of the 4 x 4 around the pixel.
  float best = kNoWeight;
  cv::Vec3f out(0, 0, 0);
  for (int dj = -1; dj <= 2; ++dj)
    for (int di = -1; di <= 2; ++di) {
      const int i = clampX(i0 + di), j = clampY(j0 + dj);
      const float w = upsampleWeight(position, normal, lowPosition.at<cv::Vec4f>(j, i), lowNormal.at<cv::Vec4f>(j, i));
      if (w > best) {
        best = w;
        const cv::Vec4f q = value.at<cv::Vec4f>(j, i);
        out = {q[0], q[1], q[2]};
      }
    }
  return out;
}

cv::Mat upsample(const cv::Mat& value, const cv::Mat& lowPosition, const cv::Mat& lowNormal, const cv::Mat& position,
                 const cv::Mat& normal, int factor) {
  CV_Assert(value.type() == CV_32FC4 && lowPosition.type() == CV_32FC4 && lowNormal.type() == CV_32FC4);
  CV_Assert(position.type() == CV_32FC4 && normal.type() == CV_32FC4 && position.size() == normal.size());
  CV_Assert(value.size() == lowPosition.size() && value.size() == lowNormal.size());
  cv::Mat out(position.size(), CV_32FC4, cv::Scalar::all(0));
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      const cv::Vec4f p = position.at<cv::Vec4f>(y, x);
      if (p[3] < 0.5f) continue;
      const cv::Vec3f e = upsampleAt(value, lowPosition, lowNormal, factor, x, y, p, normal.at<cv::Vec4f>(y, x));
      out.at<cv::Vec4f>(y, x) = {e[0], e[1], e[2], 1.f};
    }
  return out;
}

}  // namespace mrgi::lighting
