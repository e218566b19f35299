#include "lighting/techniques/splatting/splat.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "capture/colour.h"

namespace mrgi::lighting::splat {

namespace {
/// Luminance of |c| (a subtracted light weighs by its magnitude).
float absLum(const cv::Vec3f& c) {
  return static_cast<float>(capture::luminance({std::abs(c[0]), std::abs(c[1]), std::abs(c[2])}));
}
}  // namespace

float peakPerFlux(float exponent) {
  return exponent > 0 ? (exponent + 1.0f) / (2.0f * std::numbers::pi_v<float>) : 1.0f / std::numbers::pi_v<float>;
}

float widenedExponent(float exponent, float d, float widen) {
  if (!(widen > 0)) return exponent;
  return std::min(exponent, exponent * d / widen);
}

cv::Vec3f intensity(const PixelLight& l, const cv::Vec3f& w, float d) {
  const float cn = l.normal.dot(w);
  if (!(cn > 0)) return {0, 0, 0};
  if (!(l.exponent > 0)) return l.flux * (cn / std::numbers::pi_v<float>);
  const float P = widenedExponent(l.exponent, d, l.widen);
  const float ca = std::max(l.axis.dot(w), 0.0f);
  // cos^0 = 1 (also for ca = 0: the fully widened lobe is uniform over the hemisphere).
  const float lobe = P > 0 ? std::pow(ca, P) : 1.0f;
  return l.flux *
         ((P + 1.0f) / (2.0f * std::numbers::pi_v<float>)*lobe);  // normalised at every widened P', also P' = 0
}

cv::Vec3f irradiance(const PixelLight& l, const cv::Vec3f& x, const cv::Vec3f& n) {
  const cv::Vec3f v = x - l.position;
  const float d2 = v.dot(v);
  if (!(d2 > 0) || !std::isfinite(d2)) return {0, 0, 0};
  const float d = std::sqrt(d2);
  const cv::Vec3f w = v / d;
  const float cr = -n.dot(w);
  if (!(cr > 0)) return {0, 0, 0};
  return intensity(l, w, d) * (cr / (d2 + std::max(l.area, 0.0f) / std::numbers::pi_v<float>));
}

float outline(float x, float n) {
  if (!(x > 0) || x >= 1) return 0;
  return std::pow(x, n / (n + 2)) * std::sqrt(std::max(0.0f, 1 - std::pow(x, 4 / (n + 2))));
}

Ellipse boundingEllipse(float n) {
  Ellipse e;
  e.centre = std::pow(n / (n + 2), (n + 2) / 4);
  e.halfHeight = outline(e.centre, n);
  e.halfWidth = std::max(e.centre, 1 - e.centre);
  return e;
}

SplatBox splatBox(const PixelLight& l, float iLow) {
  SplatBox b;
  const float n = l.exponent > 0 ? l.exponent : 1.0f;
  const cv::Vec3f axis = l.exponent > 0 ? l.axis : l.normal;
  b.axes[0] = axis;
  const cv::Vec3f helper = std::abs(axis[0]) < 0.9f ? cv::Vec3f(1, 0, 0) : cv::Vec3f(0, 1, 0);
  b.axes[1] = cv::normalize(axis.cross(helper));
  b.axes[2] = axis.cross(b.axes[1]);
  const float i0 = absLum(l.flux) * peakPerFlux(l.exponent);
  const float R = iLow > 0 && i0 > 0 ? std::sqrt(i0 / iLow) : 0.0f;
  const Ellipse e = boundingEllipse(n);
  float lo = (e.centre - e.halfWidth) * R, hi = (e.centre + e.halfWidth) * R, lateral = e.halfHeight * R;
  if (l.exponent > 0 && l.widen > 0 && R > 0) {  // the widened lobe near the light: the ball of radius a
    lo = std::min(lo, -l.widen);
    hi = std::max(hi, l.widen);
    lateral = std::max(lateral, l.widen);
  }
  b.centre = l.position + axis * (0.5f * (lo + hi));
  b.half = {0.5f * (hi - lo), lateral, lateral};
  return b;
}

float scaledILow(const PixelLight& l, float scale) { return scale * absLum(l.flux); }

bool insideBox(const SplatBox& b, const cv::Vec3f& x) {
  const cv::Vec3f v = x - b.centre;
  for (int k = 0; k < 3; ++k)
    if (std::abs(v.dot(b.axes[k])) > b.half[k]) return false;
  return true;
}

float boxCoverage(const SplatBox& b, const cv::Vec3f& x) {
  const cv::Vec3f v = x - b.centre;
  float u = 0;
  for (int k = 0; k < 3; ++k) {
    if (!(b.half[k] > 0)) return 0.f;
    u = std::max(u, std::abs(v.dot(b.axes[k])) / b.half[k]);
  }
  return std::clamp((1.f + kBoxFade - u) / kBoxFade, 0.f, 1.f);
}

cv::Vec3f splatIrradiance(const PixelLight& l, const cv::Vec3f& x, const cv::Vec3f& n, float iLow) {
  return insideBox(splatBox(l, iLow), x) ? irradiance(l, x, n) : cv::Vec3f(0, 0, 0);
}

Pyramid buildPyramid(const cv::Mat& importance) {
  int side = 1;
  while (side < std::max(importance.cols, importance.rows)) side *= 2;
  cv::Mat base = cv::Mat::zeros(side, side, CV_64F);
  cv::Mat src;
  importance.convertTo(src, CV_64F);
  for (int y = 0; y < src.rows; ++y)
    for (int x = 0; x < src.cols; ++x) {
      const double v = src.at<double>(y, x);
      base.at<double>(y, x) = std::isfinite(v) && v > 0 ? v : 0.0;
    }
  Pyramid p;
  p.levels.push_back(base);
  while (p.levels.back().rows > 1) {
    const cv::Mat& f = p.levels.back();
    cv::Mat c(f.rows / 2, f.cols / 2, CV_64F);
    for (int y = 0; y < c.rows; ++y)
      for (int x = 0; x < c.cols; ++x)
        c.at<double>(y, x) = f.at<double>(2 * y, 2 * x) + f.at<double>(2 * y, 2 * x + 1) +
                             f.at<double>(2 * y + 1, 2 * x) + f.at<double>(2 * y + 1, 2 * x + 1);
    p.levels.push_back(c);
  }
  return p;
}

Warped warp(const Pyramid& p, cv::Vec2d u) {
  Warped out;
  if (p.levels.empty() || !(p.levels.back().at<double>(0, 0) > 0)) return out;
  int x = 0, y = 0;
  double w = 1;
  for (int k = static_cast<int>(p.levels.size()) - 2; k >= 0; --k) {
    const cv::Mat& f = p.levels[static_cast<size_t>(k)];
    x *= 2, y *= 2;
    const double t0 = f.at<double>(y, x), t1 = f.at<double>(y, x + 1);
    const double b0 = f.at<double>(y + 1, x), b1 = f.at<double>(y + 1, x + 1);
    // Vertical: the top row with probability Φ_r.
    const double r = (t0 + t1) / (t0 + t1 + b0 + b1);
    if (u[1] < r) {
      u[1] = u[1] / r;
      w /= 2 * r;
    } else {
      u[1] = (u[1] - r) / (1 - r);
      w /= 2 * (1 - r);
      y += 1;
    }
    // Horizontal within the chosen row (method A).
    const double l = y % 2 == 0 ? t0 : b0, rr = y % 2 == 0 ? t1 : b1;
    const double c = l / (l + rr);
    if (u[0] < c) {
      u[0] = u[0] / c;
      w /= 2 * c;
    } else {
      u[0] = (u[0] - c) / (1 - c);
      w /= 2 * (1 - c);
      x += 1;
    }
    u = {std::clamp(u[0], 0.0, std::nextafter(1.0, 0.0)), std::clamp(u[1], 0.0, std::nextafter(1.0, 0.0))};
  }
  out.texel = {x, y};
  out.weight = w;
  return out;
}

cv::Vec2d samplePoint(int i) {
  // R2: the plastic number's powers (Roberts 2018), offset 0.5.
  constexpr double g = 1.32471795724474602596;
  constexpr double a1 = 1.0 / g, a2 = 1.0 / (g * g);
  const double x = 0.5 + a1 * i, y = 0.5 + a2 * i;
  return {x - std::floor(x), y - std::floor(y)};
}

double warpedEstimate(const Pyramid& p, const cv::Mat& f, int n) {
  const double texels = static_cast<double>(p.levels.front().total());
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const Warped s = warp(p, samplePoint(i));
    if (s.texel.x < 0 || s.texel.x >= f.cols || s.texel.y >= f.rows) continue;
    sum += f.at<double>(s.texel) * texels * s.weight;
  }
  return sum / std::max(n, 1);
}

float texelArea(const cv::Vec3f& direct, const cv::Vec3f& beam, float cosine) {
  const int c = beam[0] >= beam[1] && beam[0] >= beam[2] ? 0 : (beam[1] >= beam[2] ? 1 : 2);
  const float across = beam[c] > 0 ? direct[c] / beam[c] : 0.0f;
  return across / std::max(cosine, 0.1f);
}

cv::Vec3f ambientFlux(const cv::Vec3f& flux, const cv::Vec3f& direct, const cv::Vec3f& eAmbient, float area,
                      float share) {
  cv::Vec3f a(0, 0, 0);
  for (int c = 0; c < 3; ++c) {
    const float albedo = direct[c] > 0 ? std::clamp(flux[c] / direct[c], 0.0f, 1.0f) : 0.0f;
    a[c] = albedo * eAmbient[c] * area * share;
    if (!std::isfinite(a[c]) || a[c] < 0) a[c] = 0;
  }
  return a;
}

cv::Vec3f occluderFlux(const cv::Vec3f& ambientBehind, float area, float share) {
  cv::Vec3f o(0, 0, 0);
  for (int c = 0; c < 3; ++c) {
    o[c] = -static_cast<float>(CV_PI) * std::max(ambientBehind[c], 0.0f) * area * share;
    if (!std::isfinite(o[c])) o[c] = 0;
  }
  return o;
}

float rsmOcclusion(const cv::Mat& position, const cv::Mat& normal, cv::Point t, float radius) {
  static const cv::Point dirs[8] = {{1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}, {-1, -1}, {0, -1}, {1, -1}};
  const cv::Vec4f p = position.at<cv::Vec4f>(t), n4 = normal.at<cv::Vec4f>(t);
  if (!(p[3] > 0.5f) || !(radius > 0)) return 0.0f;
  const cv::Vec3f x(p[0], p[1], p[2]), n(n4[0], n4[1], n4[2]);
  float occ = 0;
  for (int r : {2, 5})
    for (const cv::Point& d : dirs) {
      const cv::Point q = t + r * d;
      if (q.x < 0 || q.y < 0 || q.x >= position.cols || q.y >= position.rows) continue;
      const cv::Vec4f o = position.at<cv::Vec4f>(q);
      if (!(o[3] > 0.5f)) continue;
      const cv::Vec3f v = cv::Vec3f(o[0], o[1], o[2]) - x;
      const float len = std::sqrt(v.dot(v));
      if (!(len > 0) || len >= radius) continue;
      if (n.dot(v) > 0.2f * len) occ += 1.0f - len / radius;
    }
  return std::min(occ / 16.0f, 0.9f);
}

double importance(const cv::Vec3f& flux, float ao, float exponent) {
  const double l = absLum(flux);
  const double v = l * (1.0 - std::clamp(ao, 0.0f, 1.0f)) * (1.0 + std::max(exponent, 0.0f));
  return std::isfinite(v) && v > 0 ? v : 0.0;
}

cv::Vec3f gather(const std::vector<PixelLight>& lights, const cv::Vec3f& x, const cv::Vec3f& n) {
  cv::Vec3f e(0, 0, 0);
  for (const PixelLight& l : lights) e += irradiance(l, x, n);
  return e;
}

int farSamples(int count, int level) {
  if (count <= 0) return 0;
  long long stride = 1;
  for (int k = 0; k < level && stride < count; ++k) stride *= kFarStride;
  return static_cast<int>((count + stride - 1) / stride);
}

float farWeight(int count, int level) {
  const int m = farSamples(count, level);
  return m > 0 ? static_cast<float>(count) / static_cast<float>(m) : 0.0f;
}

cv::Vec3f splatFar(const PixelLight& l, const cv::Vec3f& x, const cv::Vec3f& n, float iLow, int sample, int count,
                   int levels) {
  if (!(iLow > 0)) return {0, 0, 0};
  float weight = 0, inner = 0, cut = iLow;
  for (int k = 0; k <= levels; ++k, cut /= kFarStride) {
    if (sample >= farSamples(count, k)) break;
    const SplatBox box = splatBox(l, cut);
    const float outer = k < levels ? boxCoverage(box, x) : (insideBox(box, x) ? 1.f : 0.f);
    weight += farWeight(count, k) * (outer - inner);
    inner = outer;
  }
  return weight != 0 ? weight * irradiance(l, x, n) : cv::Vec3f(0, 0, 0);
}

cv::Vec3f gatherBounded(const std::vector<PixelLight>& lights, const cv::Vec3f& x, const cv::Vec3f& n, float iLow) {
  cv::Vec3f e(0, 0, 0);
  for (const PixelLight& l : lights) e += splatIrradiance(l, x, n, iLow);
  return e;
}

}  // namespace mrgi::lighting::splat
