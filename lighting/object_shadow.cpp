#include "lighting/object_shadow.h"

#include <algorithm>
#include <cmath>

#include "capture/view_factor.h"

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

cv::Vec3f ambientShadow(const Ambient& ambient, const cv::Vec3f& x, const cv::Vec3f& n,
                        const std::vector<OccluderSphere>& spheres) {
  cv::Vec3f e(0, 0, 0);
  for (const auto& s : spheres) {
    const double f = sphereViewFactor(cv::Vec3d(x), cv::Vec3d(n), s);
    if (f <= 0) continue;
    const cv::Vec3f d = s.centre - x;
    const float len = static_cast<float>(cv::norm(d));
    const cv::Vec3f w = len > 0 ? d / len : n;
    const cv::Vec3f hidden = ambient.radiance(w),
                    reflected = s.albedo.mul(ambient.irradiance(-w)) * static_cast<float>(1 / CV_PI);
    e += static_cast<float>(CV_PI * f) * (hidden - reflected);
  }
  const cv::Vec3f full = ambient.irradiance(n);
  for (int c = 0; c < 3; ++c) e[c] = std::isfinite(e[c]) ? std::clamp(e[c], -full[c], full[c]) : 0.0f;
  return e;
}

}  // namespace mrgi::lighting
