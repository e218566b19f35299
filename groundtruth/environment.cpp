#include "groundtruth/environment.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "capture/colour.h"

namespace mrgi::groundtruth {
namespace {

/// Index i with cdf[i] <= x < cdf[i + 1] (cdf ascending, cdf.front() = 0, cdf.back() = 1).
int findInterval(const float* cdf, int n, float x) {
  const float* it = std::upper_bound(cdf, cdf + n + 1, x);
  return std::clamp(static_cast<int>(it - cdf) - 1, 0, n - 1);
}
}  // namespace

EnvironmentMap::EnvironmentMap(const cv::Mat& radiance, float scale) {
  CV_Assert(radiance.type() == CV_32FC3 && radiance.cols > 0 && radiance.rows > 0);
  image_ = radiance.clone();
  for (auto it = image_.begin<cv::Vec3f>(); it != image_.end<cv::Vec3f>(); ++it)
    for (int c = 0; c < 3; ++c) {
      const float v = (*it)[c] * scale;
      (*it)[c] = std::isfinite(v) && v > 0.f ? v : 0.f;
    }
  const int W = image_.cols, H = image_.rows;
  // Weight of a texel: its luminance times its solid angle (proportional to sin theta).
  std::vector<double> weight(static_cast<size_t>(W) * H), rowSum(H, 0.0);
  for (int y = 0; y < H; ++y) {
    const double sinTheta = std::sin(std::numbers::pi_v<float> * (y + 0.5) / H);
    for (int x = 0; x < W; ++x) {
      const double w = capture::luminance(cv::Vec3d(image_.at<cv::Vec3f>(y, x))) * sinTheta;
      weight[static_cast<size_t>(y) * W + x] = w;
      rowSum[y] += w;
    }
  }
  double total = 0;
  for (double r : rowSum) total += r;
  integral_ = total * (2.0 * std::numbers::pi_v<float> / W) * (std::numbers::pi_v<float> / H);
  rowCdf_.assign(H + 1, 0.f);
  colCdf_.assign(static_cast<size_t>(H) * (W + 1), 0.f);
  texelPdf_.assign(static_cast<size_t>(W) * H, 0.f);
  if (!(total > 0)) return;
  double acc = 0;
  for (int y = 0; y < H; ++y) {
    acc += rowSum[y];
    rowCdf_[y + 1] = static_cast<float>(acc / total);
    float* cdf = &colCdf_[static_cast<size_t>(y) * (W + 1)];
    double a = 0;
    for (int x = 0; x < W; ++x) {
      const double w = weight[static_cast<size_t>(y) * W + x];
      a += w;
      cdf[x + 1] = rowSum[y] > 0 ? static_cast<float>(a / rowSum[y]) : static_cast<float>(x + 1) / W;
      texelPdf_[static_cast<size_t>(y) * W + x] = static_cast<float>(w / total);
    }
    cdf[W] = 1.f;
  }
  rowCdf_[H] = 1.f;
}

cv::Vec2f EnvironmentMap::uvOf(const cv::Vec3f& d) {
  const float theta = std::acos(std::clamp(d[1], -1.f, 1.f));
  const float phi = std::atan2(d[0], -d[2]);  // (-pi, pi], 0 at -z
  float u = 0.5f + phi / (2.f * std::numbers::pi_v<float>);
  if (u >= 1.f) u -= 1.f;
  return {u, theta / std::numbers::pi_v<float>};
}

cv::Vec3f EnvironmentMap::directionOf(float u, float v) {
  const float phi = (u - 0.5f) * 2.f * std::numbers::pi_v<float>, theta = v * std::numbers::pi_v<float>;
  const float s = std::sin(theta);
  return {s * std::sin(phi), std::cos(theta), -s * std::cos(phi)};
}

cv::Vec3f EnvironmentMap::radiance(const cv::Vec3f& d) const {
  const cv::Vec2f uv = uvOf(d);
  const int x = std::clamp(static_cast<int>(uv[0] * image_.cols), 0, image_.cols - 1);
  const int y = std::clamp(static_cast<int>(uv[1] * image_.rows), 0, image_.rows - 1);
  return image_.at<cv::Vec3f>(y, x);
}

EnvironmentMap::Sample EnvironmentMap::sample(float u1, float u2, float u3) const {
  Sample s;
  if (!(integral_ > 0)) return s;
  const int W = image_.cols, H = image_.rows;
  const int y = findInterval(rowCdf_.data(), H, u1);
  const float* cdf = &colCdf_[static_cast<size_t>(y) * (W + 1)];
  const int x = findInterval(cdf, W, u2);
  // Uniform within the texel in (u, v): u2 re-used within its interval, u3 along the row.
  const float du = cdf[x + 1] - cdf[x];
  const float fx = du > 0.f ? std::clamp((u2 - cdf[x]) / du, 0.f, 0.999999f) : 0.5f;
  const float v = (y + u3) / H, u = (x + fx) / W;
  s.direction = directionOf(u, v);
  s.radiance = image_.at<cv::Vec3f>(y, x);
  s.pdf = pdf(s.direction);
  return s;
}

float EnvironmentMap::pdf(const cv::Vec3f& d) const {
  if (!(integral_ > 0)) return 0.f;
  const cv::Vec2f uv = uvOf(d);
  const int W = image_.cols, H = image_.rows;
  const int x = std::clamp(static_cast<int>(uv[0] * W), 0, W - 1),
            y = std::clamp(static_cast<int>(uv[1] * H), 0, H - 1);
  const float sinTheta = std::sin(std::numbers::pi_v<float> * uv[1]);
  if (!(sinTheta > 1e-7f)) return 0.f;
  // p(texel) spread uniformly over the texel's (u, v) area 1/(W H), which covers (2 pi^2 sin theta) / (W H) sr.
  return texelPdf_[static_cast<size_t>(y) * W + x] * static_cast<float>(W * H) /
         (2.f * std::numbers::pi_v<float> * std::numbers::pi_v<float> * sinTheta);
}

}  // namespace mrgi::groundtruth
