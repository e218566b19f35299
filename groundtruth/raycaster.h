#pragma once
/// Ray queries against a Scene with Embree (libembree). Thread-safe for concurrent queries.
#include <optional>

#include "groundtruth/scene.h"

struct RTCDeviceTy;
struct RTCSceneTy;

namespace mrgi::groundtruth {

struct Hit {
  float t = 0;                 ///< distance along the (unit) ray direction, metres
  int triangle = -1;           ///< index into Scene::triangles; -1 when a light's sphere was hit
  int light = -1;              ///< index into Scene::lights when a light's sphere was hit
  cv::Vec3f position, normal;  ///< normal: unit geometric normal facing the ray's origin side
  cv::Vec3f shading;           ///< unit interpolated vertex normal on the normal's side (= normal when flat)
  cv::Vec3f albedo;            ///< material albedo times texture and vertex albedo at the hit
  int material = -1;           ///< index into Scene::materials; -1 for a light's sphere
};

class RayCaster {
 public:
  explicit RayCaster(const Scene& scene);
  ~RayCaster();
  RayCaster(const RayCaster&) = delete;
  RayCaster& operator=(const RayCaster&) = delete;

  /// Closest hit of the ray origin + t dir, t in (tNear, tFar); dir must be unit length. Light spheres are
  /// hit only when hitLights is true (camera rays); a camera ray that misses is cast once more nudged by
  /// ~1e-6 rad, so rays through a mesh vertex exactly never slip through.
  std::optional<Hit> intersect(cv::Vec3f origin, cv::Vec3f dir, float tNear = 1e-4f, float tFar = 1e30f,
                               bool hitLights = true) const;
  /// True if any triangle lies on the segment origin + t dir, t in (tNear, tFar).
  bool occluded(cv::Vec3f origin, cv::Vec3f dir, float tNear, float tFar) const;

  /// Direct radiance leaving a hit towards the viewer: Lambertian albedo/pi times the lights'
  /// irradiance with hard shadows, plus albedo * ambient; a light sphere's own radiance I/(pi r^2).
  cv::Vec3f shadeDirect(const Hit& hit) const;

  /// Light i as seen from a surface point p with (shading) normal n: unit direction towards the light and
  /// the irradiance it delivers at normal incidence (I/d^2 or E), zero when p is outside a spot's cone, in
  /// the emitter, or shadowed (the shadow ray leaves from p offset along the geometric normal g).
  struct Incident {
    cv::Vec3f direction;
    cv::Vec3f irradiance;
  };
  Incident incident(size_t light, cv::Vec3f p, cv::Vec3f g) const;

  const Scene& scene() const { return scene_; }

 private:
  const Scene& scene_;
  RTCDeviceTy* device_ = nullptr;
  RTCSceneTy* rtcScene_ = nullptr;
};

}  // namespace mrgi::groundtruth
