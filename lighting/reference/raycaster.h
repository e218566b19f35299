#pragma once
/// Ray queries against a Scene with Embree (libembree). Thread-safe for concurrent queries.
#include <optional>

#include "lighting/reference/scene.h"

struct RTCDeviceTy;
struct RTCSceneTy;

namespace mrgi::lighting::reference {

struct Hit {
  float t = 0;        ///< distance along the (unit) ray direction, metres
  int triangle = -1;  ///< index into Scene::triangles; -1 when a light's sphere was hit
  int light = -1;     ///< index into Scene::lights when a light's sphere was hit
  cv::Vec3f position, normal;  ///< normal: unit geometric normal facing the ray's origin side
  cv::Vec3f albedo;            ///< material albedo times texture at the hit
};

class RayCaster {
 public:
  explicit RayCaster(const Scene& scene);
  ~RayCaster();
  RayCaster(const RayCaster&) = delete;
  RayCaster& operator=(const RayCaster&) = delete;

  /// Closest hit of the ray origin + t dir, t in (tNear, tFar); dir must be unit length. Light spheres are
  /// hit only when hitLights is true.
  std::optional<Hit> intersect(cv::Vec3f origin, cv::Vec3f dir, float tNear = 1e-4f, float tFar = 1e30f,
                               bool hitLights = true) const;
  /// True if any triangle lies on the segment origin + t dir, t in (tNear, tFar).
  bool occluded(cv::Vec3f origin, cv::Vec3f dir, float tNear, float tFar) const;

  /// Direct radiance leaving a hit towards the viewer: Lambertian albedo/pi times the point lights'
  /// irradiance with hard shadows, plus albedo * ambient; a light sphere's own radiance I/(pi r^2).
  cv::Vec3f shadeDirect(const Hit& hit) const;

  const Scene& scene() const { return scene_; }

 private:
  const Scene& scene_;
  RTCDeviceTy* device_ = nullptr;
  RTCSceneTy* rtcScene_ = nullptr;
};

}  // namespace mrgi::lighting::reference
