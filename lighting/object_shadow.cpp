#include "lighting/object_shadow.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "capture/view_factor.h"
#include "lighting/frame/light_view.h"

namespace mrgi::lighting {

OccluderSphere occluderSphere(const Mesh& mesh) {
  OccluderSphere s;
  if (mesh.positions.empty()) return s;
  cv::Vec3f lo = mesh.positions[0], hi = lo;
  for (const auto& p : mesh.positions)
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], p[c]), hi[c] = std::max(hi[c], p[c]);
  double area = 0;
  for (size_t i = 0; i + 2 < mesh.indices.size(); i += 3) {
    const cv::Vec3d a(mesh.positions[mesh.indices[i]]), b(mesh.positions[mesh.indices[i + 1]]),
        d(mesh.positions[mesh.indices[i + 2]]);
    area += 0.5 * cv::norm((b - a).cross(d - a));
  }
  s.centre = 0.5f * (lo + hi);
  const double r = std::sqrt(area / (4 * CV_PI));
  s.radius = std::isfinite(r) ? static_cast<float>(r) : 0.f;
  return s;
}

OccluderSphere placeSphere(const OccluderSphere& model, const cv::Matx44d& T) {
  const cv::Vec4d w = T * cv::Vec4d(model.centre[0], model.centre[1], model.centre[2], 1.0);
  // The transform's scale (uniform in practice: the cube root of its determinant) scales the radius.
  const cv::Matx33d R(T(0, 0), T(0, 1), T(0, 2), T(1, 0), T(1, 1), T(1, 2), T(2, 0), T(2, 1), T(2, 2));
  const double r = model.radius * std::cbrt(std::abs(cv::determinant(R)));
  OccluderSphere s;
  s.albedo = model.albedo;
  s.centre = cv::Vec3f(static_cast<float>(w[0]), static_cast<float>(w[1]), static_cast<float>(w[2]));
  s.radius = std::isfinite(r) ? static_cast<float>(r) : 0.f;
  return s;
}

double sphereViewFactor(const cv::Vec3d& x, const cv::Vec3d& n, const OccluderSphere& s) {
  const cv::Vec3d d = cv::Vec3d(s.centre) - x;
  const double dist = cv::norm(d), r = s.radius;
  if (!(r > 0) || !std::isfinite(dist)) return 0.0;
  if (dist <= r) return 1.0;
  return capture::sphereViewFactor(dist / r, n.dot(d) / dist);
}

namespace {

/// Over the spheres seen from (x, n): what they hide of `ambient` (pi F times its radiance along each centre)
/// and what they would reflect of it towards x were their surroundings unshadowed (F albedo E(-w)); the GLSL
/// twin is ambientShadowParts.
void ambientShadowParts(const Ambient& ambient, const cv::Vec3f& x, const cv::Vec3f& n,
                        const std::vector<OccluderSphere>& spheres, cv::Vec3f& hides, cv::Vec3f& reflects,
                        bool throughMap) {
  hides = reflects = cv::Vec3f(0, 0, 0);
  for (const auto& s : spheres) {
    const double f = sphereViewFactor(cv::Vec3d(x), cv::Vec3d(n), s);
    if (!(f >= kObjectsMinViewFactor)) continue;
    const cv::Vec3f d = s.centre - x;
    const float len = static_cast<float>(cv::norm(d));
    const cv::Vec3f w = len > 0 ? d / len : n;
    // The cap the sphere covers: half-angle alpha, sin alpha = r / distance (1 - cos alpha without cancellation).
    const float sinA = len > s.radius ? s.radius / len : 1.0f;
    const float oneMinusCos = sinA * sinA / (1 + std::sqrt(std::max(0.0f, 1 - sinA * sinA)));
    hides += static_cast<float>(CV_PI * f) *
             (throughMap && ambient.map ? ambient.map->capMean(w, oneMinusCos, n) : ambient.radiance(w));
    reflects += static_cast<float>(f) * s.albedo.mul(ambient.irradiance(-w));
  }
}

}  // namespace

cv::Vec3f ambientShadow(const Ambient& ambient, const cv::Vec3f& x, const cv::Vec3f& n,
                        const std::vector<OccluderSphere>& spheres, const cv::Vec3f& lit) {
  cv::Vec3f hides, reflects;
  ambientShadowParts(ambient, x, n, spheres, hides, reflects, true);
  cv::Vec3f e = hides - lit.mul(reflects);
  const cv::Vec3f full = ambient.irradiance(n);
  for (int c = 0; c < 3; ++c) e[c] = std::isfinite(e[c]) ? std::clamp(e[c], -full[c], full[c]) : 0.0f;
  return e;
}

cv::Vec3f litFraction(const Ambient& hidden, const cv::Vec3f& x, const cv::Vec3f& n,
                      const std::vector<OccluderSphere>& spheres, const cv::Vec3f& directWithout,
                      const cv::Vec3f& directWith) {
  cv::Vec3f hides, reflects;
  ambientShadowParts(hidden, x, n, spheres, hides, reflects, false);
  const cv::Vec3f full = hidden.irradiance(n);
  cv::Vec3f out;
  for (int c = 0; c < 3; ++c) {
    const float kept = directWith[c] + full[c] - std::clamp(hides[c], 0.f, full[c]);
    const float v = kept / std::max(directWithout[c] + full[c], 1e-6f);
    out[c] = std::isfinite(v) ? std::clamp(v, 0.f, 1.f) : 1.f;
  }
  return out;
}

FacedGround facedGround(const cv::Vec3f& x, const cv::Vec3f& n, const std::vector<OccluderSphere>& spheres) {
  FacedGround g;
  g.point = x;
  double best = 0;
  for (const auto& s : spheres) {
    const double f = sphereViewFactor(cv::Vec3d(x), cv::Vec3d(n), s);
    if (!(f > best)) continue;
    best = f;
    const cv::Vec3f toX = x - s.centre;
    const float dist = static_cast<float>(cv::norm(toX));
    const float sinB = dist > 0 ? std::clamp(-toX.dot(n) / dist, 0.f, 1.f) : 1.f;
    g.weight = std::isfinite(sinB) ? sinB * sinB : 0.f;
    g.point = s.centre - (s.centre - x).dot(n) * n;
  }
  return g;
}

cv::Vec3d reflectionSample(int k) {
  // Fibonacci spiral: z uniform in (0, 1) (equal areas), the azimuth advanced by the golden angle.
  const double z = 1.0 - (k + 0.5) / kReflectionSamples, rho = std::sqrt(std::max(0.0, 1.0 - z * z));
  const double phi = 2.399963229728653 * k;
  return {rho * std::cos(phi), rho * std::sin(phi), z};
}

cv::Vec3f reflectedLight(const cv::Vec3f& x, const cv::Vec3f& n, const std::vector<OccluderSphere>& spheres,
                         const std::vector<SceneLight>& lights, const LightReaches& reaches) {
  cv::Vec3d e(0, 0, 0);
  const cv::Vec3d xd(x), nd(n);
  for (const auto& s : spheres) {
    const double f = sphereViewFactor(xd, nd, s);
    if (f < kObjectsMinViewFactor || s.albedo == cv::Vec3f(0, 0, 0)) continue;
    const cv::Vec3d c(s.centre), toX = xd - c;
    const double dist = cv::norm(toX), r = s.radius;
    if (!(dist > 0)) continue;
    // The samples on the half facing x, in a frame about v, the direction from the centre to x, and their
    // form-factor weights w_k = cos(at p) cos(at x) / R^2 (up to the constant area of a sample).
    const cv::Vec3d v = toX / dist;
    const cv::Vec3d t = cv::normalize(v.cross(std::abs(v[2]) < 0.9 ? cv::Vec3d(0, 0, 1) : cv::Vec3d(1, 0, 0)));
    const cv::Vec3d b = v.cross(t);
    std::array<cv::Vec3d, kReflectionSamples> normals;
    std::array<double, kReflectionSamples> w{};
    double weights = 0;
    for (int k = 0; k < kReflectionSamples; ++k) {
      const cv::Vec3d h = reflectionSample(k);
      normals[k] = h[0] * t + h[1] * b + h[2] * v;
      const cv::Vec3d d = xd - (c + r * normals[k]);
      const double r2 = d.dot(d);
      w[k] = r2 > 0 ? std::max(0.0, normals[k].dot(d)) * std::max(0.0, -nd.dot(d)) / (r2 * r2) : 0.0;
      weights += w[k];
    }
    if (!(weights > 0)) continue;
    for (size_t i = 0; i < lights.size(); ++i) {
      const SceneLight& light = lights[i];
      const bool directional = light.type == LightType::Directional;
      const cv::Vec3d l = directional ? -light.direction : cv::normalize(light.position - c), facing = c + r * l;
      if (unshadowedIrradiance(light, facing, l) == cv::Vec3d(0, 0, 0)) continue;  // outside a spot's cone
      if (reaches && !reaches(i, facing, l)) continue;
      double lit = 0;
      for (int k = 0; k < kReflectionSamples; ++k) {
        const cv::Vec3d p = c + r * normals[k], toLight = directional ? l : light.position - p;
        const double cosine = directional
                                  ? normals[k].dot(l)
                                  : normals[k].dot(toLight) / std::pow(std::max(toLight.dot(toLight), 1e-8), 1.5);
        if (cosine > 0) lit += cosine * w[k];
      }
      e += f * cv::Vec3d(s.albedo).mul(directional ? light.irradiance : light.intensity) * (lit / weights);
    }
  }
  cv::Vec3f out;
  for (int c = 0; c < 3; ++c) out[c] = std::isfinite(e[c]) ? static_cast<float>(std::max(e[c], 0.0)) : 0.f;
  return out;
}

}  // namespace mrgi::lighting
