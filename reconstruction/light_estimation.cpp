#include "reconstruction/light_estimation.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>

#include "capture/colour.h"
#include "capture/view_factor.h"

namespace mrgi::reconstruction {
namespace {

/// Solid angle of the spherical triangle (a, b, c) of unit vectors (Van Oosterom & Strackee).
double triangleSolidAngle(const cv::Vec3d& a, const cv::Vec3d& b, const cv::Vec3d& c) {
  const double num = std::abs(a.dot(b.cross(c)));
  const double den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
  return 2.0 * std::atan2(num, den);
}

}  // namespace

bool fisheyePixelToRay(const capture::FisheyeCalibration& c, double u, double v, cv::Vec3d& direction) {
  const double fx = c.K(0, 0), fy = c.K(1, 1), cx = c.K(0, 2), cy = c.K(1, 2), skew = c.K(0, 1) / fx;
  const double yd = (v - cy) / fy;
  const double xd = (u - cx) / fx - skew * yd;
  const double thetaD = std::hypot(xd, yd);
  if (thetaD < 1e-12) {
    direction = {0, 0, 1};
    return true;
  }
  const cv::Vec4d& k = c.D;
  // Newton on f(t) = t (1 + k1 t^2 + k2 t^4 + k3 t^6 + k4 t^8) - thetaD, from t = thetaD.
  double t = thetaD;
  bool converged = false;
  for (int i = 0; i < 30; ++i) {
    const double t2 = t * t;
    const double f = t * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])))) - thetaD;
    const double df = 1 + t2 * (3 * k[0] + t2 * (5 * k[1] + t2 * (7 * k[2] + t2 * 9 * k[3])));
    if (!(df > 1e-6)) return false;  // the model folds over: no unique ray
    const double step = f / df;
    t -= step;
    if (!(t >= 0) || t > CV_PI) return false;
    if (std::abs(step) < 1e-12) {
      converged = true;
      break;
    }
  }
  if (!converged) return false;
  const double s = std::sin(t) / thetaD;
  direction = {xd * s, yd * s, std::cos(t)};
  return true;
}

FisheyeRays fisheyeRays(const capture::FisheyeCalibration& c, double maxThetaRad) {
  CV_Assert(c.width > 0 && c.height > 0);
  const int w = c.width, h = c.height;
  // Rays through pixel corners ((x - 0.5, y - 0.5) for x in 0..w) and centres.
  std::vector<cv::Vec3d> corner(static_cast<size_t>(w + 1) * (h + 1));
  std::vector<uint8_t> cornerOk(corner.size());
  const double cosMax = std::cos(maxThetaRad);
  for (int y = 0; y <= h; ++y)
    for (int x = 0; x <= w; ++x) {
      cv::Vec3d d;
      const size_t i = static_cast<size_t>(y) * (w + 1) + x;
      cornerOk[i] = fisheyePixelToRay(c, x - 0.5, y - 0.5, d) && d[2] >= cosMax;
      corner[i] = d;
    }
  FisheyeRays r;
  r.directions.create(h, w, CV_32FC3);
  r.solidAngle.create(h, w, CV_64FC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i00 = static_cast<size_t>(y) * (w + 1) + x, i10 = i00 + 1, i01 = i00 + w + 1, i11 = i01 + 1;
      cv::Vec3d d;
      const bool ok = fisheyePixelToRay(c, x, y, d);
      r.directions.at<cv::Vec3f>(y, x) = ok ? cv::Vec3f(d) : cv::Vec3f(0, 0, 0);
      double omega = 0;
      if (ok && cornerOk[i00] && cornerOk[i10] && cornerOk[i01] && cornerOk[i11])
        omega = triangleSolidAngle(corner[i00], corner[i10], corner[i11]) +
                triangleSolidAngle(corner[i00], corner[i11], corner[i01]);
      r.solidAngle.at<double>(y, x) = omega;
      r.totalSolidAngle += omega;
    }
  return r;
}

cv::Mat linearRadiance(const cv::Mat& image, double exposure, cv::Mat* saturated, double saturationLevel) {
  CV_Assert(image.channels() == 3 && exposure > 0);
  cv::Mat out;
  if (saturated) saturated->create(image.size(), CV_8UC1);
  if (image.depth() == CV_8U) {
    out = capture::decodeSrgb(image);
    if (saturated)
      for (int y = 0; y < image.rows; ++y)
        for (int x = 0; x < image.cols; ++x) {
          const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
          saturated->at<uchar>(y, x) = (p[0] >= 250 || p[1] >= 250 || p[2] >= 250) ? 255 : 0;
        }
  } else {
    image.convertTo(out, CV_32FC3);
    for (int y = 0; y < out.rows; ++y)
      for (int x = 0; x < out.cols; ++x) {
        cv::Vec3f& p = out.at<cv::Vec3f>(y, x);
        bool sat = false;
        for (int k = 0; k < 3; ++k) {
          if (!(p[k] > 0.f) || !std::isfinite(p[k])) p[k] = std::isinf(p[k]) && p[k] > 0 ? 3e38f : 0.f;
          sat |= p[k] >= saturationLevel;
        }
        if (saturated) saturated->at<uchar>(y, x) = sat ? 255 : 0;
      }
  }
  if (exposure != 1.0) out /= exposure;
  return out;
}

cv::Vec3d totalPower(const cv::Mat& radiance, const FisheyeRays& rays) {
  CV_Assert(radiance.type() == CV_32FC3 && radiance.size() == rays.solidAngle.size());
  cv::Vec3d s(0, 0, 0);
  for (int y = 0; y < radiance.rows; ++y)
    for (int x = 0; x < radiance.cols; ++x) {
      const double o = rays.solidAngle.at<double>(y, x);
      if (o > 0) s += cv::Vec3d(radiance.at<cv::Vec3f>(y, x)) * o;
    }
  return s;
}

namespace {

/// Summed-area tables (double) of everything median cut asks about a rectangle, O(1) per query.
class RegionStats {
 public:
  RegionStats(const cv::Mat& radiance, const FisheyeRays& rays) {
    const int w = radiance.cols, h = radiance.rows;
    cv::Mat a(h, w, CV_64FC4), b(h, w, CV_64FC4), c(h, w, CV_64FC4), d(h, w, CV_64FC4);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double o = rays.solidAngle.at<double>(y, x);
        cv::Vec3d L = o > 0 ? cv::Vec3d(radiance.at<cv::Vec3f>(y, x)) : cv::Vec3d(0, 0, 0);
        for (int k = 0; k < 3; ++k)
          if (!(L[k] > 0) || !std::isfinite(L[k])) L[k] = 0;
        const double e = std::max(0.0, capture::luminance(L)) * o;
        const cv::Vec3d dir(rays.directions.at<cv::Vec3f>(y, x));
        a.at<cv::Vec4d>(y, x) = {e, e * x, e * y, e * (double(x) * x + double(y) * y)};
        b.at<cv::Vec4d>(y, x) = {L[0] * o, L[1] * o, L[2] * o, o};
        c.at<cv::Vec4d>(y, x) = {e * dir[0], e * dir[1], e * dir[2], 0};
        d.at<cv::Vec4d>(y, x) = {o * dir[0], o * dir[1], o * dir[2], 0};
      }
    cv::integral(a, satA_, CV_64F);
    cv::integral(b, satB_, CV_64F);
    cv::integral(c, satC_, CV_64F);
    cv::integral(d, satD_, CV_64F);
  }
  cv::Vec4d energy(const cv::Rect& r) const { return sum(satA_, r); }  ///< (E, Ex, Ey, E(x^2+y^2))
  cv::Vec4d power(const cv::Rect& r) const { return sum(satB_, r); }   ///< (R, G, B, solid angle)
  cv::Vec3d energyDirection(const cv::Rect& r) const { return head(sum(satC_, r)); }
  cv::Vec3d solidAngleDirection(const cv::Rect& r) const { return head(sum(satD_, r)); }
  /// Energy-weighted spatial variance (pixels^2) of a region.
  double variance(const cv::Rect& r) const {
    const cv::Vec4d s = energy(r);
    if (!(s[0] > 0)) return 0;
    return std::max(0.0, s[3] - (s[1] * s[1] + s[2] * s[2]) / s[0]);
  }

 private:
  static cv::Vec4d sum(const cv::Mat& sat, const cv::Rect& r) {
    return sat.at<cv::Vec4d>(r.y + r.height, r.x + r.width) - sat.at<cv::Vec4d>(r.y, r.x + r.width) -
           sat.at<cv::Vec4d>(r.y + r.height, r.x) + sat.at<cv::Vec4d>(r.y, r.x);
  }
  static cv::Vec3d head(const cv::Vec4d& v) { return {v[0], v[1], v[2]}; }
  cv::Mat satA_, satB_, satC_, satD_;
};

/// Splits r in two (false if it is a single pixel).
bool split(const RegionStats& s, const cv::Rect& r, bool varianceSplit, cv::Rect& a, cv::Rect& b) {
  if (r.width < 2 && r.height < 2) return false;
  auto halves = [&](bool vertical, int cut, cv::Rect& lo, cv::Rect& hi) {
    if (vertical)
      lo = {r.x, r.y, cut - r.x, r.height}, hi = {cut, r.y, r.x + r.width - cut, r.height};
    else
      lo = {r.x, r.y, r.width, cut - r.y}, hi = {r.x, cut, r.width, r.y + r.height - cut};
  };
  if (varianceSplit) {
    double best = std::numeric_limits<double>::infinity();
    for (const bool vertical : {true, false}) {
      const int from = (vertical ? r.x : r.y) + 1, to = vertical ? r.x + r.width : r.y + r.height;
      for (int cut = from; cut < to; ++cut) {
        cv::Rect lo, hi;
        halves(vertical, cut, lo, hi);
        const double cost = s.variance(lo) + s.variance(hi);
        if (cost < best) best = cost, a = lo, b = hi;
      }
    }
    if (s.energy(r)[0] > 0) return true;
    // No energy: fall through to the geometric middle.
  }
  const bool vertical = r.width >= r.height;
  const int lo = (vertical ? r.x : r.y) + 1, hi = (vertical ? r.x + r.width : r.y + r.height) - 1;
  const double total = s.energy(r)[0];
  int cut = (lo + hi + 1) / 2;
  if (total > 0) {
    // Smallest cut whose first part holds at least half the energy, then the nearer of it and its left.
    int l = lo, h = hi;
    auto first = [&](int c) {
      cv::Rect p, q;
      halves(vertical, c, p, q);
      return s.energy(p)[0];
    };
    while (l < h) {
      const int m = (l + h) / 2;
      if (first(m) >= 0.5 * total)
        h = m;
      else
        l = m + 1;
    }
    cut = l;
    if (cut > lo && std::abs(first(cut - 1) - 0.5 * total) < std::abs(first(cut) - 0.5 * total)) --cut;
  }
  halves(vertical, cut, a, b);
  return true;
}

EstimatedLight lightOf(const RegionStats& s, const cv::Rect& r) {
  EstimatedLight l;
  l.region = r;
  const cv::Vec4d p = s.power(r);
  l.power = {std::max(0.0, p[0]), std::max(0.0, p[1]), std::max(0.0, p[2])};
  l.solidAngle = std::max(0.0, p[3]);
  cv::Vec3d d = s.energy(r)[0] > 0 ? s.energyDirection(r) : s.solidAngleDirection(r);
  const double n = cv::norm(d);
  l.direction = n > 1e-300 ? d / n : cv::Vec3d(0, 0, 1);
  return l;
}

/// Energy-weighted angular spread of a region (radians): sqrt(1 - |mean direction|) ~ angle / sqrt(2).
double angularSpread(const RegionStats& s, const cv::Rect& r) {
  const double e = s.energy(r)[0];
  if (!(e > 0)) return 0;
  const double m = std::min(1.0, cv::norm(s.energyDirection(r)) / e);
  return std::sqrt(2.0 * (1.0 - m));
}

}  // namespace

std::vector<EstimatedLight> medianCut(const cv::Mat& radiance, const FisheyeRays& rays, const MedianCutOptions& o) {
  CV_Assert(radiance.type() == CV_32FC3 && radiance.size() == rays.solidAngle.size());
  const RegionStats stats(radiance, rays);
  const cv::Rect full(0, 0, radiance.cols, radiance.rows);
  std::vector<cv::Rect> regions{full};
  if (o.count > 0) {
    const int target = std::min<int>(o.count, static_cast<int>(full.area()));
    while (static_cast<int>(regions.size()) < target) {
      // One level: split regions strongest first until the target is met.
      std::vector<cv::Rect> level = regions, next;
      std::stable_sort(level.begin(), level.end(),
                       [&](const cv::Rect& a, const cv::Rect& b) { return stats.energy(a)[0] > stats.energy(b)[0]; });
      size_t i = 0;
      bool progressed = false;
      int count = static_cast<int>(regions.size());
      for (; i < level.size() && count < target; ++i) {
        cv::Rect a, b;
        if (split(stats, level[i], o.varianceSplit, a, b))
          next.push_back(a), next.push_back(b), ++count, progressed = true;
        else
          next.push_back(level[i]);
      }
      for (; i < level.size(); ++i) next.push_back(level[i]);
      regions.swap(next);
      if (!progressed) break;
    }
  } else {
    const double total = stats.energy(full)[0];
    bool changed = true;
    while (changed && static_cast<int>(regions.size()) < o.maxCount) {
      changed = false;
      std::vector<cv::Rect> next;
      for (size_t i = 0; i < regions.size(); ++i) {
        const cv::Rect& r = regions[i];
        cv::Rect a, b;
        const bool wants = stats.energy(r)[0] > o.minEnergyFraction * total && angularSpread(stats, r) > o.maxSpreadRad;
        if (wants && static_cast<int>(regions.size() - i + next.size()) < o.maxCount &&
            split(stats, r, o.varianceSplit, a, b)) {
          next.push_back(a), next.push_back(b), changed = true;
        } else {
          next.push_back(r);
        }
      }
      regions.swap(next);
    }
  }
  std::vector<EstimatedLight> lights;
  lights.reserve(regions.size());
  for (const auto& r : regions) lights.push_back(lightOf(stats, r));
  std::sort(lights.begin(), lights.end(), [](const EstimatedLight& a, const EstimatedLight& b) {
    return capture::luminance(a.power) > capture::luminance(b.power);
  });
  return lights;
}

std::vector<EstimatedLight> lightsToWorld(std::vector<EstimatedLight> lights, const capture::Pose& T) {
  const cv::Matx33d R = capture::rotationOf(T);
  for (auto& l : lights) l.direction = cv::normalize(R * l.direction);
  return lights;
}

cv::Vec3d irradianceFromLights(const std::vector<EstimatedLight>& lights, const cv::Vec3d& n) {
  cv::Vec3d e(0, 0, 0);
  for (const auto& l : lights)
    e += normalIrradiance(l) * capture::capCosine(n.dot(l.direction), std::sin(l.angularRadius));
  return e;
}

cv::Vec3d irradianceFromImage(const cv::Mat& radiance, const FisheyeRays& rays, const cv::Vec3d& n) {
  cv::Vec3d e(0, 0, 0);
  for (int y = 0; y < radiance.rows; ++y)
    for (int x = 0; x < radiance.cols; ++x) {
      const double o = rays.solidAngle.at<double>(y, x);
      if (!(o > 0)) continue;
      const double c = n.dot(cv::Vec3d(rays.directions.at<cv::Vec3f>(y, x)));
      if (c > 0) e += cv::Vec3d(radiance.at<cv::Vec3f>(y, x)) * (o * c);
    }
  return e;
}

cv::Mat renderFisheyeFromLatLong(const cv::Mat& latlong, const FisheyeRays& rays, const cv::Matx33d& R) {
  CV_Assert(latlong.type() == CV_32FC3);
  cv::Mat mapX(rays.directions.size(), CV_32FC1), mapY(rays.directions.size(), CV_32FC1);
  for (int y = 0; y < mapX.rows; ++y)
    for (int x = 0; x < mapX.cols; ++x) {
      const cv::Vec3d d = R * cv::Vec3d(rays.directions.at<cv::Vec3f>(y, x));
      const double u = (std::atan2(d[0], -d[2]) / (2 * CV_PI) + 0.5) * latlong.cols - 0.5;
      const double v = std::acos(std::clamp(d[1], -1.0, 1.0)) / CV_PI * latlong.rows - 0.5;
      mapX.at<float>(y, x) = static_cast<float>(u);
      mapY.at<float>(y, x) = static_cast<float>(v);
    }
  cv::Mat out;
  // Wrap horizontally (longitude), clamp vertically: pad one column each side, replicate rows.
  cv::Mat padded;
  cv::copyMakeBorder(latlong, padded, 1, 1, 1, 1, cv::BORDER_WRAP);
  padded.row(1).copyTo(padded.row(0));
  padded.row(padded.rows - 2).copyTo(padded.row(padded.rows - 1));
  mapX += 1.0, mapY += 1.0;
  cv::remap(padded, out, mapX, mapY, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x)
      if (!(rays.solidAngle.at<double>(y, x) > 0)) out.at<cv::Vec3f>(y, x) = {0, 0, 0};
  return out;
}

}  // namespace mrgi::reconstruction

namespace mrgi::reconstruction {

std::array<double, 9> shBasis2(const cv::Vec3d& d) {
  const double x = d[0], y = d[1], z = d[2];
  return {0.282094791773878,
          0.488602511902920 * y,
          0.488602511902920 * z,
          0.488602511902920 * x,
          1.092548430592079 * x * y,
          1.092548430592079 * y * z,
          0.315391565252520 * (3 * z * z - 1),
          1.092548430592079 * x * z,
          0.546274215296040 * (x * x - y * y)};
}

namespace {

/// The clamped cosine's SH coefficients per basis function of bands 0-2 (A_l = pi, 2 pi / 3, pi / 4): the
/// remainder's irradiance about n is sum_k kClampedCosine[k] c_k y_k(n).
constexpr double kClampedCosine[9] = {CV_PI,     2 * CV_PI / 3, 2 * CV_PI / 3, 2 * CV_PI / 3, CV_PI / 4,
                                      CV_PI / 4, CV_PI / 4,     CV_PI / 4,     CV_PI / 4};

/// The image as at most 64 x 32 direction bins (flux L dOmega and its flux-weighted mean direction): enough
/// for the irradiance at a normal (a smooth function), at a few thousand terms instead of every pixel.
struct FluxBin {
  cv::Vec3d direction, flux;
  double solidAngle;
};
std::vector<FluxBin> fluxBins(const cv::Mat& radiance, const FisheyeRays& rays) {
  constexpr int kW = 64, kH = 32;
  std::vector<FluxBin> bins(kW * kH, FluxBin{{0, 0, 0}, {0, 0, 0}, 0.0});
  std::vector<double> weight(bins.size(), 0.0);
  for (int y = 0; y < radiance.rows; ++y)
    for (int x = 0; x < radiance.cols; ++x) {
      const double o = rays.solidAngle.at<double>(y, x);
      if (!(o > 0)) continue;
      const cv::Vec3d d(rays.directions.at<cv::Vec3f>(y, x));
      const cv::Vec3d f = cv::Vec3d(radiance.at<cv::Vec3f>(y, x)) * o;
      const int u = std::clamp(static_cast<int>((std::atan2(d[1], d[0]) / (2 * CV_PI) + 0.5) * kW), 0, kW - 1);
      const int v = std::clamp(static_cast<int>(std::acos(std::clamp(d[2], -1.0, 1.0)) / CV_PI * kH), 0, kH - 1);
      FluxBin& b = bins[static_cast<size_t>(v * kW + u)];
      const double w = capture::luminance(f) + 1e-30 * o;  // empty bins still get a direction
      b.direction += d * w;
      b.flux += f;
      b.solidAngle += o;
      weight[static_cast<size_t>(v * kW + u)] += w;
    }
  std::vector<FluxBin> out;
  for (size_t i = 0; i < bins.size(); ++i)
    if (weight[i] > 0 && cv::norm(bins[i].direction) > 0)
      out.push_back({cv::normalize(bins[i].direction), bins[i].flux, bins[i].solidAngle});
  return out;
}

/// LightSplitOptions::fitIrradiance: bands 1-2 of the remainder and one common scale s of the lights' powers
/// fitted, relative error weighed, to the image's irradiance at `count` normals; band 0 takes what the scaled
/// lights leave of the image's total, so lights and remainder still hold it. Ten rounds of Lawson's
/// reweighting bring the largest error down, the best round kept.
void fitRemainderToIrradiance(const cv::Mat& radiance, const FisheyeRays& rays, int count, bool scaleLights,
                              LightSplit& split) {
  const std::vector<FluxBin> bins = fluxBins(radiance, rays);
  const double c0Unit = 2 * std::sqrt(CV_PI);  // the power of a unit band-0 coefficient
  cv::Vec3d lightsPower(0, 0, 0);
  for (const auto& l : split.lights) lightsPower += l.power;
  const cv::Vec3d total = lightsPower + split.ambientSh[0] * c0Unit;
  // The scale keeps band 0 non-negative and the lights within a factor 2 of their regions' power.
  double sMax = 2.0;
  for (int c = 0; c < 3; ++c)
    if (lightsPower[c] > 0) sMax = std::min(sMax, total[c] / lightsPower[c]);
  const double sMin = std::min(0.5, sMax);
  // Per normal (rows), per channel: E_image = s (E_lights - A0 y0 P_L / c0Unit) + A0 y0 P_total / c0Unit +
  // sum_{k >= 1} A_k y_k c_k, each row scaled by its weight / the image's irradiance there.
  struct Row {
    double w;
    cv::Vec3d lightsPart, rhs;
    std::array<double, 8> basis;
  };
  std::vector<Row> rowsData;
  for (int i = 0; i < count; ++i) {
    const double z = 1 - (2 * i + 1) / static_cast<double>(count), r = std::sqrt(std::max(0.0, 1 - z * z));
    const double a = i * CV_PI * (3 - std::sqrt(5.0));
    const cv::Vec3d n(r * std::cos(a), r * std::sin(a), z);
    cv::Vec3d E(0, 0, 0);
    double seen = 0;  // the part of the normal's cosine-weighted hemisphere the image covers (1: a whole sphere)
    for (const FluxBin& b : bins) {
      const double c = std::max(0.0, n.dot(b.direction));
      E += b.flux * c;
      seen += b.solidAngle * c / CV_PI;
    }
    const double lum = capture::luminance(E);
    if (!(lum > 0) || !std::isfinite(lum) || !(seen > 0))
      continue;  // a normal the image sends nothing: no relative error
    const auto y = shBasis2(n);
    // Scaled by 1 / E: squared relative error, where the image sees the normal's hemisphere (a fisheye's
    // normals facing away from its field see only its rim: their irradiance is not the room's).
    Row row;
    row.w = std::min(seen, 1.0) / lum;
    const double a0 = kClampedCosine[0] * y[0] / c0Unit;
    row.lightsPart = irradianceFromLights(split.lights, n) - lightsPower * a0;
    row.rhs = E - total * a0;
    for (int k = 1; k < 9; ++k) row.basis[static_cast<size_t>(k - 1)] = kClampedCosine[k] * y[static_cast<size_t>(k)];
    rowsData.push_back(row);
  }
  const int rows = static_cast<int>(rowsData.size());
  if (rows < 16) return;
  // One weighted solve: unknowns s (shared by the channels) and bands 1-2 per channel; s fixed when given.
  const auto solve = [&](const std::vector<double>& weight, double fixedS, double& s, cv::Mat& bands) {
    const bool free = !(fixedS > 0);
    const int o = free ? 1 : 0;
    cv::Mat M(3 * rows, o + 24, CV_64F, cv::Scalar(0)), rhs(3 * rows, 1, CV_64F);
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < rows; ++j) {
        const Row& row = rowsData[static_cast<size_t>(j)];
        const double sw = std::sqrt(weight[static_cast<size_t>(j)]) * row.w;
        const int at = c * rows + j;
        if (free) M.at<double>(at, 0) = sw * row.lightsPart[c];
        for (int k = 0; k < 8; ++k) M.at<double>(at, o + c * 8 + k) = sw * row.basis[static_cast<size_t>(k)];
        rhs.at<double>(at) = sw * (row.rhs[c] - (free ? 0.0 : fixedS * row.lightsPart[c]));
      }
    cv::Mat x;
    if (!cv::solve(M, rhs, x, cv::DECOMP_SVD) || !cv::checkRange(x)) return false;
    s = free ? x.at<double>(0) : fixedS;
    bands = x.rowRange(o, o + 24).clone();
    return true;
  };
  // Least squares, then Lawson's reweighting towards the smallest largest error: each normal's weight grows
  // with its relative error (luminance) at the last solution.
  std::vector<double> weight(static_cast<size_t>(rows), 1.0);
  cv::Mat best;
  double bestS = 1, bestWorst = 1e300;
  constexpr int kRounds = 10;
  for (int round = 0; round <= kRounds; ++round) {
    double s = 1;
    cv::Mat bands;
    if (!solve(weight, scaleLights ? 0.0 : 1.0, s, bands)) break;
    if (!(s >= sMin && s <= sMax) && !solve(weight, std::clamp(s, sMin, sMax), s, bands)) break;
    double worst = 0, sum = 0;
    std::vector<double> e(static_cast<size_t>(rows));
    for (int j = 0; j < rows; ++j) {
      const Row& row = rowsData[static_cast<size_t>(j)];
      cv::Vec3d r = s * row.lightsPart - row.rhs;
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 8; ++k) r[c] += row.basis[static_cast<size_t>(k)] * bands.at<double>(c * 8 + k);
      e[static_cast<size_t>(j)] = std::abs(capture::luminance(r)) * row.w;
      worst = std::max(worst, e[static_cast<size_t>(j)]);
    }
    if (worst < bestWorst) bestWorst = worst, best = bands, bestS = s;
    for (int j = 0; j < rows; ++j) sum += weight[static_cast<size_t>(j)] * e[static_cast<size_t>(j)];
    if (!(sum > 0)) break;
    for (int j = 0; j < rows; ++j) weight[static_cast<size_t>(j)] *= e[static_cast<size_t>(j)] / sum * rows;
  }
  if (best.empty()) return;
  for (auto& l : split.lights) l.power *= bestS;
  split.ambientSh[0] = (total - lightsPower * bestS) * (1 / c0Unit);
  for (int k = 1; k < 9; ++k)
    for (int c = 0; c < 3; ++c) split.ambientSh[static_cast<size_t>(k)][c] = best.at<double>(c * 8 + k - 1);
}

/// LightSplitOptions::lightExtent: each light's half-angle from its region's bright energy.
void giveLightsExtent(const cv::Mat& bright, const FisheyeRays& rays, double scale,
                      std::vector<EstimatedLight>& lights) {
  for (auto& l : lights) {
    cv::Vec3d sum(0, 0, 0);
    double energy = 0;
    const cv::Rect r = l.region & cv::Rect(0, 0, bright.cols, bright.rows);
    for (int y = r.y; y < r.y + r.height; ++y)
      for (int x = r.x; x < r.x + r.width; ++x) {
        const double w = rays.solidAngle.at<double>(y, x);
        if (!(w > 0)) continue;
        const double e = capture::luminance(cv::Vec3d(bright.at<cv::Vec3f>(y, x))) * w;
        if (!(e > 0)) continue;
        sum += e * cv::Vec3d(rays.directions.at<cv::Vec3f>(y, x));
        energy += e;
      }
    if (!(energy > 0)) continue;
    // A disc of uniform radiance of half-angle a has mean resultant length (1 + cos a) / 2.
    const double meanLength = std::clamp(cv::norm(sum) / energy, 0.0, 1.0);
    l.angularRadius = std::min(scale * std::acos(2 * meanLength - 1), kMaxLightAngularRadius);
  }
}

}  // namespace

double splitThreshold(const LightSplitOptions& o, const FisheyeRays& rays) {
  return o.threshold > 0 ? o.threshold : rays.totalSolidAngle >= 0.95 * 4 * CV_PI ? 2.0 : 1.0;
}

LightSplit splitLights(const cv::Mat& radiance, const FisheyeRays& rays, const LightSplitOptions& o) {
  CV_Assert(radiance.type() == CV_32FC3 && radiance.size() == rays.solidAngle.size());
  LightSplit out;
  // The threshold: a multiple of the mean luminance over the field.
  double sumL = 0, sumW = 0;
  for (int y = 0; y < radiance.rows; ++y)
    for (int x = 0; x < radiance.cols; ++x) {
      const double w = rays.solidAngle.at<double>(y, x);
      if (w <= 0) continue;
      sumL += w * std::max(0.0, capture::luminance(cv::Vec3d(radiance.at<cv::Vec3f>(y, x))));
      sumW += w;
    }
  out.thresholdLuminance = sumW > 0 ? splitThreshold(o, rays) * sumL / sumW : 0.0;
  cv::Mat bright(radiance.size(), CV_32FC3, cv::Scalar::all(0));
  out.remainder = cv::Mat(radiance.size(), CV_32FC3, cv::Scalar::all(0));
  for (int y = 0; y < radiance.rows; ++y)
    for (int x = 0; x < radiance.cols; ++x) {
      const double w = rays.solidAngle.at<double>(y, x);
      if (w <= 0) continue;
      const cv::Vec3d L(radiance.at<cv::Vec3f>(y, x));
      const double lum = capture::luminance(L);
      // Above T the pixel's colour is scaled down to luminance T; the excess goes to the lights.
      const double keep = lum > out.thresholdLuminance && lum > 0 ? out.thresholdLuminance / lum : 1.0;
      const cv::Vec3d rest = L * keep;
      bright.at<cv::Vec3f>(y, x) = cv::Vec3f(L - rest);
      out.remainder.at<cv::Vec3f>(y, x) = cv::Vec3f(rest);
      const cv::Vec3f dir = rays.directions.at<cv::Vec3f>(y, x);
      const auto b = shBasis2(cv::Vec3d(dir));
      for (int k = 0; k < 9; ++k) out.ambientSh[k] += rest * (b[k] * w);
    }
  out.lights = medianCut(bright, rays, o.medianCut);
  if (o.lightExtent > 0) giveLightsExtent(bright, rays, o.lightExtent, out.lights);
  if (o.fitIrradiance && o.fitNormals >= 16)
    fitRemainderToIrradiance(radiance, rays, o.fitNormals, o.fitLightScale, out);
  return out;
}

cv::Vec3d shIrradiance(const std::array<cv::Vec3d, 9>& sh, const cv::Vec3d& n) {
  const auto b = shBasis2(n);
  cv::Vec3d E(0, 0, 0);
  for (int k = 0; k < 9; ++k) E += sh[k] * (kClampedCosine[k] * b[k]);
  return E;
}

cv::Vec3d ambientShIrradiance(const std::array<cv::Vec3d, 9>& sh, const cv::Vec3d& n) {
  cv::Vec3d E = shIrradiance(sh, n);
  for (int c = 0; c < 3; ++c) E[c] = std::max(E[c], 0.0);
  return E;
}

cv::Vec3d irradianceFromSplit(const LightSplit& split, const cv::Vec3d& n) {
  return irradianceFromLights(split.lights, n) + shIrradiance(split.ambientSh, n);
}

}  // namespace mrgi::reconstruction
