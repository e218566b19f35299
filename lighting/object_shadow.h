#pragma once
/// The objects' shadow of the ambient on real surfaces (the shading pass, lighting/object_shadow.glsl is the
/// GPU twin): a real surface point x with normal n loses what the ambient sends it through the solid angle the
/// objects cover and gains what the objects reflect of it towards x,
///   dE(x) = -integral over the objects of (L_ambient(w) - L_object(-w)) cos(theta) dw,
/// with L_object the object's diffuse reflection of the ambient, albedo x E_ambient(-w) / pi (its face
/// turned towards x has the normal -w). Under a uniform ambient a white object hides almost nothing
/// (1 - albedo of it); under a room the table beneath it is dark, so its underside is, and the table around
/// it loses the bright walls and ceiling behind it. Each object stands as one sphere (occluderSphere); a
/// sphere's integral is its view factor from the surface element (the exact closed form, the sphere partly
/// below the horizon included) times the difference along the direction of its centre. Error: exact for a
/// sphere under a uniform ambient; the SH part varies across a large sphere's cap by its bands 1-2 (a sphere
/// 1.5 radii away covers a cap of 42 degrees), and a sphere's visible face has normals over a cap about -w;
/// overlapping objects are counted twice, so the total is clamped at the point's ambient irradiance either
/// way. What the lights send the objects and they reflect is the techniques' bounce, not this.
#include <opencv2/core.hpp>
#include <vector>

#include "lighting/ambient.h"
#include "lighting/scene_file.h"

namespace mrgi::lighting {

struct OccluderSphere {
  cv::Vec3f centre{0, 0, 0};
  float radius = 0;
  cv::Vec3f albedo{0, 0, 0};  ///< diffuse albedo of what it reflects of the ambient (0: it only hides)
};

/// The sphere an object stands as, in its model space: centred on its bounding box, with the object's mean
/// solid angle from afar (Cauchy: a convex body's mean projected area is a quarter of its surface area, so
/// r = sqrt(A / 4 pi)); a sphere's mesh gives itself (to its tessellation), a flat or thin object a smaller
/// sphere than its box. Computed once per mesh (it sums every triangle's area).
OccluderSphere occluderSphere(const Mesh& mesh);
/// A model-space sphere placed by the object's transform (its scale: the cube root of the determinant).
OccluderSphere placeSphere(const OccluderSphere& model, const cv::Matx44d& T_world_object);
/// occluderSphere(mesh) placed by T_world_object.
inline OccluderSphere occluderSphere(const Mesh& mesh, const cv::Matx44d& T_world_object) {
  return placeSphere(occluderSphere(mesh), T_world_object);
}
/// A virtual object's sphere where the scene places it (T_marker_object), with its material's albedo.
inline OccluderSphere occluderSphere(const VirtualObject& object) {
  OccluderSphere s = occluderSphere(object.mesh, object.T_marker_object);
  s.albedo = object.material.albedo;
  return s;
}

/// The view factor from a surface element at x with unit normal n to a sphere: the fraction of the
/// element's cosine-weighted hemisphere (pi) the sphere covers. 0 behind the element, 1 when x is inside.
double sphereViewFactor(const cv::Vec3d& x, const cv::Vec3d& n, const OccluderSphere& s);

/// The irradiance the spheres take from (x, n) under `ambient`, net of what they reflect of it towards x
/// (W/m^2; positive: subtract it, negative: the objects brighten x), within +- the ambient's irradiance about n.
cv::Vec3f ambientShadow(const Ambient& ambient, const cv::Vec3f& x, const cv::Vec3f& n,
                        const std::vector<OccluderSphere>& spheres);

}  // namespace mrgi::lighting
