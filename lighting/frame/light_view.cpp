#include "lighting/frame/light_view.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <stdexcept>

#include "capture/view_factor.h"
#include "gl/error.h"
#include "lighting/frame/mesh.h"

namespace mrgi::lighting {

Region fitRegion(const cv::Vec3d& lo, const cv::Vec3d& hi, double sizeFactor) {
  const cv::Vec3d extent = hi - lo;
  const double edge = std::max({extent[0], extent[1], extent[2], 1e-3});
  Region r;
  r.side = edge * sizeFactor;
  r.origin = 0.5 * (lo + hi) - cv::Vec3d::all(0.5 * r.side);
  return r;
}

cv::Vec3d irradianceBound(const SceneLight& light, const Region& region) {
  if (light.type == LightType::Directional) return light.irradiance;
  const cv::Vec3d toCentre = region.centre() - light.position;
  const double d = cv::norm(toCentre), r = region.radius();
  if (!(d > r)) return cv::Vec3d::all(std::numeric_limits<double>::infinity());
  if (light.type == LightType::Spot) {
    // The cone misses the sphere when the angle from its axis to the centre exceeds the half angle by more
    // than the sphere's angular radius.
    const double off = std::acos(std::clamp(toCentre.dot(light.direction) / d, -1.0, 1.0));
    if (off - std::asin(r / d) > light.spotHalfAngleDeg * CV_PI / 180.0) return {0, 0, 0};
  }
  return light.intensity / ((d - r) * (d - r));
}

std::vector<size_t> lightsThatMatter(const std::vector<SceneLight>& lights, const cv::Vec3d& ambientRadiance,
                                     const Region& region, double cutoff) {
  std::vector<size_t> kept(lights.size());
  std::iota(kept.begin(), kept.end(), size_t{0});
  if (!(cutoff > 0)) return kept;
  std::vector<cv::Vec3d> bound(lights.size());
  cv::Vec3d total = CV_PI * ambientRadiance;
  for (size_t i = 0; i < lights.size(); ++i) {
    bound[i] = irradianceBound(lights[i], region);
    if (std::isfinite(bound[i][0] + bound[i][1] + bound[i][2])) total += bound[i];
  }
  auto brightest = [](const cv::Vec3d& b) { return std::max({b[0], b[1], b[2]}); };
  std::vector<size_t> order = kept;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return brightest(bound[a]) < brightest(bound[b]); });
  std::vector<bool> skip(lights.size(), false);
  cv::Vec3d skipped{0, 0, 0};
  for (size_t i : order) {
    const cv::Vec3d next = skipped + bound[i];
    bool within = true;
    for (int c = 0; c < 3; ++c) within = within && next[c] <= cutoff * total[c];
    if (!within) break;
    skipped = next;
    skip[i] = true;
  }
  kept.clear();
  for (size_t i = 0; i < lights.size(); ++i)
    if (!skip[i]) kept.push_back(i);
  return kept;
}

LightView fitLightView(const SceneLight& light, const Region& region, int size) {
  LightView v;
  const cv::Vec3d centre = region.centre();
  const double radius = region.radius();
  if (light.type == LightType::Directional) {
    const double back = 4.0 * radius;  // room for occluders in front of the region
    const cv::Vec3d eye = centre - light.direction * back;
    v.viewProj =
        orthographicProjection(radius, 0.0, back + radius) * capture::inversePose(capture::lookAtPose(eye, centre));
    const double texel = 2.0 * radius / size;
    v.texelArea = texel * texel;
    v.shadowBias = 2.0 * texel;
  } else {
    const double dist = cv::norm(centre - light.position);
    if (dist < 1e-6) throw std::invalid_argument("a point light sits at the centre of the region around the objects");
    const double half = std::asin(std::min(radius / dist, std::sin(80.0 * CV_PI / 180.0)));
    v.focalPixels = 0.5 * size / std::tan(half);
    capture::Intrinsics k;
    k.width = k.height = size;
    k.fx = k.fy = v.focalPixels;
    k.cx = k.cy = 0.5 * size - 0.5;
    v.viewProj = projectionFromIntrinsics(k, std::max(1e-3, 0.01 * dist), dist + radius) *
                 capture::inversePose(capture::lookAtPose(light.position, centre));
    v.shadowBias = 2.0 * (dist + radius) / v.focalPixels;
  }
  return v;
}

void fitObjectView(LightView& v, const SceneLight& light, const cv::Vec3d& centre, double radius, int size) {
  radius = std::max(radius, 1e-4);
  v.objectShadowBias = -1;
  if (light.type == LightType::Directional) {
    const cv::Vec3d eye = centre - light.direction * (2.0 * radius);
    v.objectViewProj =
        orthographicProjection(radius, 0.0, 3.0 * radius) * capture::inversePose(capture::lookAtPose(eye, centre));
    v.objectShadowBias = 2.0 * (2.0 * radius / size);
    v.objectNear = centre.dot(light.direction) - radius;
    return;
  }
  const double dist = cv::norm(centre - light.position);
  if (!(dist > 1.05 * radius)) return;  // the light is (almost) among the objects: no single view holds them
  const double half = std::asin(radius / dist);
  const double focal = 0.5 * size / std::tan(half);
  capture::Intrinsics k;
  k.width = k.height = size;
  k.fx = k.fy = focal;
  k.cx = k.cy = 0.5 * size - 0.5;
  v.objectViewProj = projectionFromIntrinsics(k, std::max(1e-4, dist - radius), dist + radius) *
                     capture::inversePose(capture::lookAtPose(light.position, centre));
  v.objectShadowBias = 2.0 * (dist + radius) / focal;
  v.objectNear = dist - radius;
}

std::optional<cv::Vec2d> mapCoordinates(const cv::Matx44d& viewProj, const cv::Vec3d& p) {
  const cv::Vec4d c = viewProj * cv::Vec4d(p[0], p[1], p[2], 1.0);
  if (c[3] <= 0) return std::nullopt;
  const double u = c[0] / c[3], v = c[1] / c[3];
  if (std::abs(u) > 1 || std::abs(v) > 1) return std::nullopt;
  return cv::Vec2d(u * 0.5 + 0.5, v * 0.5 + 0.5);
}

namespace {

/// The shadow test's distance of a point: along a directional light's direction, else from the light.
double lightDistance(const SceneLight& light, const cv::Vec3d& p) {
  return light.type == LightType::Directional ? p.dot(light.direction) : cv::norm(p - light.position);
}

/// The distance of what the map holds where p projects (+inf where nothing or outside the map).
double occluderDistance(const cv::Mat& positions, const SceneLight& light, const cv::Matx44d& viewProj,
                        const cv::Vec3d& p) {
  const std::optional<cv::Vec2d> uv = mapCoordinates(viewProj, p);
  if (!uv) return std::numeric_limits<double>::infinity();
  const int col = std::clamp(static_cast<int>(std::floor((*uv)[0] * positions.cols)), 0, positions.cols - 1);
  const int row = std::clamp(static_cast<int>(std::floor((*uv)[1] * positions.rows)), 0, positions.rows - 1);
  const cv::Vec4f s = positions.at<cv::Vec4f>(row, col);
  if (s[3] < 0.5f) return std::numeric_limits<double>::infinity();
  return lightDistance(light, cv::Vec3d(s[0], s[1], s[2]));
}

}  // namespace

float shadowTest(const cv::Mat& positions, const SceneLight& light, const cv::Matx44d& viewProj, double bias,
                 cv::Vec3d x, const cv::Vec3d& n) {
  if (bias < 0 || positions.empty()) return 1.f;
  x += n * bias;
  return occluderDistance(positions, light, viewProj, x) < lightDistance(light, x) - bias ? 0.f : 1.f;
}

float softObjectsShadow(const cv::Mat& objects, const SceneLight& light, const LightView& view, cv::Vec3d x,
                        const cv::Vec3d& n) {
  const double bias = view.objectShadowBias;
  if (bias < 0 || objects.empty()) return 1.f;
  const cv::Vec3d at = x;  // the receiver, before the normal offset the tests take
  x += n * bias;
  const double self = lightDistance(light, x);
  if (!(self - bias > view.objectNear)) return 1.f;  // in front of the objects' sphere
  const bool directional = light.type == LightType::Directional;
  const cv::Vec3d L = directional ? light.direction : cv::normalize(x - light.position);
  const cv::Vec3d t = cv::normalize(L.cross(std::abs(L[2]) < 0.9 ? cv::Vec3d(0, 0, 1) : cv::Vec3d(1, 0, 0)));
  const cv::Vec3d b = L.cross(t);
  // Penumbra width per metre between the receiver and a blocker at distance d from the light.
  const double sinA = light.sinAngularRadius(1);
  const double tanA = sinA / std::sqrt(std::max(1e-12, 1 - sinA * sinA));
  const auto width = [&](double d) {
    return directional ? (self - d) * tanA : (self - d) * light.extent / std::max(d, 1e-4);
  };
  // Each tap compares with the receiver's tangent plane where the light's ray through the tap meets it (a
  // receiver-plane bias): a curved or tilted receiver does not shadow itself at its taps.
  const double facing = std::min(n.dot(L), -0.1);  // < 0 where the surface faces the light
  const auto tap = [&](int k, int taps, double radius, double& receiver) {
    const double r = radius * std::sqrt((k + 0.5) / taps), a = k * 2.399963229728653;
    const cv::Vec3d o = r * std::cos(a) * t + r * std::sin(a) * b;
    receiver = self - n.dot(o) / facing;
    return x + o;
  };
  const double widest = width(view.objectNear);
  // A penumbra narrower than the map's texel (the bias is two): the hard test.
  if (widest < 0.5 * bias) return shadowTest(objects, light, view.objectViewProj, bias, at, n);
  double sum = 0, receiver = 0;
  int blockers = 0;
  for (int k = 0; k < kSoftShadowSearchTaps; ++k) {
    const cv::Vec3d p = tap(k, kSoftShadowSearchTaps, widest, receiver);
    const double d = occluderDistance(objects, light, view.objectViewProj, p);
    if (d < receiver - bias) sum += d, ++blockers;
  }
  if (blockers == 0) return 1.f;
  if (blockers == kSoftShadowSearchTaps) return 0.f;  // the widest penumbra's disc all covered: the umbra
  const double w = width(sum / blockers);
  int lit = 0;
  for (int k = 0; k < kSoftShadowTaps; ++k) {
    const cv::Vec3d p = tap(k, kSoftShadowTaps, w, receiver);
    lit += !(occluderDistance(objects, light, view.objectViewProj, p) < receiver - bias);
  }
  return static_cast<float>(lit) / kSoftShadowTaps;
}

namespace {
/// direct_light.glsl's objectsVisibility: the objects' map's test, soft for a light with extent (view.soft) when
/// `soft`, hard otherwise.
float objectsVisibility(const ShadowTexels& maps, const SceneLight& light, const LightView& view, const cv::Vec3d& x,
                        const cv::Vec3d& n, bool soft) {
  return soft && view.soft  // view.soft: a light with extent (LightPass::render)
             ? softObjectsShadow(maps.objects, light, view, x, n)
             : shadowTest(maps.objects, light, view.objectViewProj, view.objectShadowBias, x, n);
}
}  // namespace

float smoothShadowTest(const cv::Mat& positions, const SceneLight& light, const cv::Matx44d& viewProj, double bias,
                       cv::Vec3d x, const cv::Vec3d& n) {
  if (bias < 0 || positions.empty()) return 1.f;
  x += n * bias;
  const std::optional<cv::Vec2d> uv = mapCoordinates(viewProj, x);
  if (!uv) return 1.f;
  const double fx = (*uv)[0] * positions.cols - 0.5, fy = (*uv)[1] * positions.rows - 0.5;
  const double x0 = std::floor(fx), y0 = std::floor(fy), wx = fx - x0, wy = fy - y0;
  const double self = lightDistance(light, x) - bias;
  double lit[4];
  for (int k = 0; k < 4; ++k) {
    const int col = std::clamp(static_cast<int>(x0) + (k & 1), 0, positions.cols - 1);
    const int row = std::clamp(static_cast<int>(y0) + (k >> 1), 0, positions.rows - 1);
    const cv::Vec4f s = positions.at<cv::Vec4f>(row, col);
    lit[k] = s[3] < 0.5f || !(lightDistance(light, cv::Vec3d(s[0], s[1], s[2])) < self) ? 1.0 : 0.0;
  }
  return static_cast<float>((lit[0] * (1 - wx) + lit[1] * wx) * (1 - wy) + (lit[2] * (1 - wx) + lit[3] * wx) * wy);
}

float virtualLightVisibility(const ShadowTexels& maps, const SceneLight& light, const LightView& view,
                             const cv::Vec3d& x, const cv::Vec3d& n, bool soft) {
  if (view.objectShadowBias < 0) return smoothShadowTest(maps.rho, light, view.viewProj, view.shadowBias, x, n);
  return smoothShadowTest(maps.mu, light, view.viewProj, view.shadowBias, x, n) *
         objectsVisibility(maps, light, view, x, n, soft);
}

float lightVisibility(const ShadowTexels& maps, const SceneLight& light, const LightView& view, bool withObjects,
                      const cv::Vec3d& x, const cv::Vec3d& n, bool soft) {
  if (!withObjects) return shadowTest(maps.mu, light, view.viewProj, view.shadowBias, x, n);
  if (view.objectShadowBias < 0) return shadowTest(maps.rho, light, view.viewProj, view.shadowBias, x, n);
  return shadowTest(maps.mu, light, view.viewProj, view.shadowBias, x, n) *
         objectsVisibility(maps, light, view, x, n, soft);
}

cv::Vec3d unshadowedIrradiance(const SceneLight& light, const cv::Vec3d& x, const cv::Vec3d& n) {
  if (light.type == LightType::Directional)
    return light.irradiance * capture::capCosine(-n.dot(light.direction), light.sinAngularRadius(1));
  const cv::Vec3d l = light.position - x;
  const double d2 = std::max(l.dot(l), 1e-8);
  const cv::Vec3d ln = l / std::sqrt(d2);
  if (light.type == LightType::Spot && (-ln).dot(light.direction) < light.spotCos()) return {0, 0, 0};
  return light.intensity * (capture::capCosine(n.dot(ln), light.sinAngularRadius(std::sqrt(d2))) / d2);
}

}  // namespace mrgi::lighting
