#include "reconstruction/distant_lights.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "reconstruction/mesh_rays.h"

namespace mrgi::reconstruction {
namespace {

/// A surface point the fit uses: where it is, which way it faces, and its irradiance pi L / albedo.
struct Sample {
  cv::Vec3d origin, normal;
  cv::Vec3d irradiance;
};

/// How well a direction explains the samples' irradiance: the least-squares fit E = rest + sun c(w) per channel,
/// with c(w) = max(0, n . w) V(x, w).
struct Fit {
  double explained = -1;  ///< R^2 of the green channel (-1: not a candidate)
  double litShare = 0;
  cv::Vec3d sun{0, 0, 0}, rest{0, 0, 0};
};

Fit fitDirection(const std::vector<Sample>& samples, const cv::Vec3d& w, const MeshRays& rays,
                 const DistantLightOptions& o) {
  const size_t n = samples.size();
  std::vector<double> c(n, 0.0);
  std::atomic<size_t> lit{0};
  cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& r) {
    size_t mine = 0;
    for (int i = r.start; i < r.end; ++i) {
      const Sample& s = samples[static_cast<size_t>(i)];
      const double facing = s.normal.dot(w);
      if (facing <= 0) continue;
      if (rays.occluded(s.origin, w, 1e3)) continue;
      c[static_cast<size_t>(i)] = facing;
      ++mine;
    }
    lit += mine;
  });
  Fit f;
  f.litShare = static_cast<double>(lit.load()) / static_cast<double>(n);
  if (f.litShare < o.minLitShare || f.litShare > 1 - o.minLitShare) return f;
  double mc = 0;
  cv::Vec3d my(0, 0, 0);
  for (size_t i = 0; i < n; ++i) mc += c[i], my += samples[i].irradiance;
  mc /= static_cast<double>(n);
  my /= static_cast<double>(n);
  double vc = 0;
  cv::Vec3d cov(0, 0, 0), vy(0, 0, 0);
  for (size_t i = 0; i < n; ++i) {
    const double dc = c[i] - mc;
    const cv::Vec3d dy = samples[i].irradiance - my;
    vc += dc * dc;
    cov += dc * dy;
    vy += dy.mul(dy);
  }
  if (!(vc > 0) || !(vy[1] > 0)) return f;
  for (int k = 0; k < 3; ++k) {
    f.sun[k] = cov[k] / vc;
    f.rest[k] = my[k] - f.sun[k] * mc;
  }
  if (!(f.sun[1] > 0)) return f;
  f.explained = cov[1] * cov[1] / (vc * vy[1]);
  return f;
}

/// Two unit vectors completing `w` to an orthonormal basis.
void basisAround(const cv::Vec3d& w, cv::Vec3d& u, cv::Vec3d& v) {
  const cv::Vec3d a = std::abs(w[2]) < 0.9 ? cv::Vec3d(0, 0, 1) : cv::Vec3d(1, 0, 0);
  u = cv::normalize(a.cross(w));
  v = w.cross(u);
}

}  // namespace

std::optional<DistantLight> findDistantLight(const std::vector<cv::Vec3f>& positions,
                                             const std::vector<cv::Vec3f>& normals,
                                             const std::vector<cv::Vec3f>& radiance,
                                             const std::vector<cv::Vec3f>& albedo, const MeshRays& rays,
                                             const DistantLightOptions& o) {
  const size_t count = std::min({positions.size(), normals.size(), radiance.size(), albedo.size()});
  std::vector<size_t> usable;
  for (size_t i = 0; i < count; ++i) {
    const cv::Vec3f& a = albedo[i];
    const cv::Vec3f& l = radiance[i];
    const cv::Vec3f& nn = normals[i];
    bool ok = cv::norm(nn) > 0.5;
    for (int k = 0; k < 3 && ok; ++k) ok = a[k] > 0.01f && std::isfinite(l[k]) && l[k] >= 0;
    if (ok) usable.push_back(i);
  }
  if (usable.size() < 100) return std::nullopt;
  const size_t stride = std::max<size_t>(1, usable.size() / static_cast<size_t>(std::max(1, o.maxPoints)));
  std::vector<Sample> samples;
  for (size_t j = 0; j < usable.size(); j += stride) {
    const size_t i = usable[j];
    Sample s;
    s.normal = cv::normalize(cv::Vec3d(normals[i]));
    s.origin = cv::Vec3d(positions[i]) + o.rayOffsetM * s.normal;
    for (int k = 0; k < 3; ++k) s.irradiance[k] = CV_PI * radiance[i][k] / albedo[i][k];
    samples.push_back(s);
  }

  // The coarse search: a Fibonacci set over the whole sphere (the light may shine up through a floor's opening).
  const int candidates = std::max(8, o.candidates);
  Fit best;
  cv::Vec3d bestW(0, 0, 1);
  const double golden = CV_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < candidates; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / candidates, r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const cv::Vec3d w(r * std::cos(golden * i), r * std::sin(golden * i), z);
    const Fit f = fitDirection(samples, w, rays, o);
    if (f.explained > best.explained) best = f, bestW = w;
  }
  if (best.explained < 0) return std::nullopt;
  // Refinement: a 7 x 7 grid of directions around the best, its spacing halved each round (from the coarse set's).
  double step = std::sqrt(4 * CV_PI / candidates) / 3;
  for (int round = 0; round < o.refineSteps; ++round, step /= 2) {
    cv::Vec3d u, v;
    basisAround(bestW, u, v);
    const cv::Vec3d centre = bestW;
    for (int a = -3; a <= 3; ++a)
      for (int b = -3; b <= 3; ++b) {
        if (a == 0 && b == 0) continue;
        const cv::Vec3d w = cv::normalize(centre + std::tan(a * step) * u + std::tan(b * step) * v);
        const Fit f = fitDirection(samples, w, rays, o);
        if (f.explained > best.explained) best = f, bestW = w;
      }
  }
  if (best.explained < o.minExplained) return std::nullopt;
  DistantLight light;
  light.towards = bestW;
  light.irradiance = best.sun;
  light.rest = best.rest;
  light.explained = best.explained;
  light.litShare = best.litShare;
  return light;
}

}  // namespace mrgi::reconstruction
