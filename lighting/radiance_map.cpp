#include "lighting/radiance_map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace mrgi::lighting {

RadianceMap::RadianceMap(const cv::Mat& latLong) {
  if (latLong.empty() || (latLong.type() != CV_32FC3 && latLong.type() != CV_64FC3) || latLong.cols % 2 ||
      latLong.cols != 2 * latLong.rows || latLong.rows < 4)
    throw std::invalid_argument("radiance map: a lat-long RGB image twice as wide as high, at least 8 x 4");
  cv::Mat level;
  latLong.convertTo(level, CV_32FC3);
  if (!cv::checkRange(level.reshape(1), true, nullptr, 0.0, std::numeric_limits<float>::max()))
    throw std::invalid_argument("radiance map: negative or non-finite radiance");
  levels_.push_back(level);
  while (levels_.back().cols > 1 || levels_.back().rows > 1) {
    const cv::Mat& a = levels_.back();
    cv::Mat b(std::max(1, a.rows / 2), std::max(1, a.cols / 2), CV_32FC3);
    for (int v = 0; v < b.rows; ++v)
      for (int u = 0; u < b.cols; ++u) {
        cv::Vec3f s(0, 0, 0);
        int n = 0;
        for (int dv = 0; dv < 2; ++dv)
          for (int du = 0; du < 2; ++du) {
            const int y = 2 * v + dv, x = 2 * u + du;
            if (y < a.rows && x < a.cols) s += a.at<cv::Vec3f>(y, x), ++n;
          }
        b.at<cv::Vec3f>(v, u) = s / static_cast<float>(n);
      }
    levels_.push_back(b);
  }
}

namespace {

/// The golden angle's cosine and sine (2.39996... radians).
constexpr float kGoldenCos = -0.737368878f, kGoldenSin = 0.675490294f;

/// GL's bilinear read of one level at texture coordinates (s, t): s repeats, t clamps to the edge.
cv::Vec3f bilinear(const cv::Mat& m, float s, float t) {
  const float x = s * static_cast<float>(m.cols) - 0.5f, y = t * static_cast<float>(m.rows) - 0.5f;
  const float fx = std::floor(x), fy = std::floor(y), ax = x - fx, ay = y - fy;
  const auto col = [&](int i) { return ((i % m.cols) + m.cols) % m.cols; };
  const auto row = [&](int j) { return std::clamp(j, 0, m.rows - 1); };
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  const cv::Vec3f& a = m.at<cv::Vec3f>(row(y0), col(x0));
  const cv::Vec3f& b = m.at<cv::Vec3f>(row(y0), col(x0 + 1));
  const cv::Vec3f& c = m.at<cv::Vec3f>(row(y0 + 1), col(x0));
  const cv::Vec3f& d = m.at<cv::Vec3f>(row(y0 + 1), col(x0 + 1));
  return (1 - ay) * ((1 - ax) * a + ax * b) + ay * ((1 - ax) * c + ax * d);
}

}  // namespace

cv::Vec3f RadianceMap::sample(const cv::Vec3f& w, float lod) const {
  constexpr float kPi = 3.14159265358979f;
  float s = std::atan2(w[1], w[0]) / (2 * kPi);
  s -= std::floor(s);
  const float t = std::acos(std::clamp(w[2], -1.0f, 1.0f)) / kPi;
  if (!std::isfinite(s) || !std::isfinite(t)) return {0, 0, 0};
  const float l = std::isfinite(lod) ? std::clamp(lod, 0.0f, maxLevel()) : 0.0f;
  const int l0 = static_cast<int>(std::floor(l)), l1 = std::min(l0 + 1, static_cast<int>(levels_.size()) - 1);
  const float f = l - static_cast<float>(l0);
  const cv::Vec3f a = bilinear(levels_[static_cast<size_t>(l0)], s, t);
  return f > 0 ? a + f * (bilinear(levels_[static_cast<size_t>(l1)], s, t) - a) : a;
}

float RadianceMap::texelSolidAngle() const {
  constexpr float kPi = 3.14159265358979f;
  return (2 * kPi / static_cast<float>(width())) * (kPi / static_cast<float>(height()));
}

float RadianceMap::lodFor(float solidAngle) const {
  const float lod = 0.5f * std::log2(solidAngle / texelSolidAngle());
  return std::isfinite(lod) ? std::clamp(lod, 0.0f, maxLevel()) : 0.0f;
}

int RadianceMap::capSamples(float oneMinusCosAlpha) const {
  const float perTexel = std::ceil(2 * 3.14159265358979f * oneMinusCosAlpha / texelSolidAngle());
  return std::isfinite(perTexel) ? static_cast<int>(std::clamp(perTexel, 1.0f, static_cast<float>(kCapSamples))) : 1;
}

cv::Vec3f RadianceMap::capMean(const cv::Vec3f& w, float oneMinusCosAlpha, const cv::Vec3f& n) const {
  const cv::Vec3f t = cv::normalize(w.cross(std::abs(w[2]) < 0.9f ? cv::Vec3f(0, 0, 1) : cv::Vec3f(1, 0, 0)));
  const cv::Vec3f b = w.cross(t);
  // Each direction read at the level of a quarter of its share of the cap (half the spacing between them): a
  // coarser level blurs what lies past the cap's rim into it (a cap of 51 degrees beside a bright band: 5.5 %
  // over its integral at the share itself, 1.8 % at a quarter). A smaller cap: a direction per texel at level 0.
  const int count = capSamples(oneMinusCosAlpha);
  const float lod = lodFor(2 * 3.14159265358979f * oneMinusCosAlpha / static_cast<float>(4 * count));
  cv::Vec3f sum(0, 0, 0);
  float weights = 0;
  // Equal solid angles: cos theta uniform over [cos alpha, 1]; the azimuth steps by the golden angle, its cosine
  // and sine turned by a rotation each step (no trigonometry per direction).
  float cosPhi = 1, sinPhi = 0;
  for (int k = 0; k < count; ++k) {
    const float oneMinusCos = oneMinusCosAlpha * (static_cast<float>(k) + 0.5f) / static_cast<float>(count);
    const float c = 1 - oneMinusCos, sn = std::sqrt(std::max(0.0f, oneMinusCos * (2 - oneMinusCos)));
    const cv::Vec3f d = sn * cosPhi * t + sn * sinPhi * b + c * w;
    const float turned = cosPhi * kGoldenCos - sinPhi * kGoldenSin;
    sinPhi = sinPhi * kGoldenCos + cosPhi * kGoldenSin;
    cosPhi = turned;
    const float weight = std::max(0.0f, d.dot(n));
    if (!(weight > 0)) continue;
    sum += weight * sample(d, lod);
    weights += weight;
  }
  return weights > 0 ? sum / weights : sample(w, lod);
}

}  // namespace mrgi::lighting
