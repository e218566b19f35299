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
/// way. With the ambient's radiance map (Ambient::map: a room's surfaces seen from the objects) a sphere hides
/// pi F times the map's mean radiance over the cap it covers, weighted by the cosine about n
/// (RadianceMap::capMean): against the path tracer's shadow under a room, within its noise (1 % a ring) where the
/// SH bands were up to 30 % off (object_shadow_test); the lit fractions keep the SH bands. What the lights send the
/// objects and they reflect is the techniques' bounce, not this.
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

#include "lighting/ambient.h"
#include "lighting/scene.h"
#include "lighting/scene_file.h"

namespace mrgi::lighting {

/// A sphere whose view factor from a surface element is under this adds nothing there: neither the ambient it
/// hides and reflects nor the lights it reflects (beyond about ten radii on the plane a sphere rests on; what it
/// would add is under a thousandth of the element's own ambient irradiance, less than a 1/255 step of the
/// pixel). The shading pass skips a real pixel's object terms where no sphere reaches it and no objects' map
/// shadows it (lighting/shade.frag).
constexpr double kObjectsMinViewFactor = 1e-3;

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

/// The irradiance the spheres take from (x, n) under `ambient`, net of what they reflect of it towards x (each
/// sphere seen at a view factor of at least kObjectsMinViewFactor)
/// (W/m^2; positive: subtract it, negative: the objects brighten x), within +- the ambient's irradiance about n.
/// `lit` scales what they reflect: the faces they turn towards x see x's surroundings and the ground under
/// them, which their shadows darken (litFraction, blendLit; 1: unshadowed surroundings).
cv::Vec3f ambientShadow(const Ambient& ambient, const cv::Vec3f& x, const cv::Vec3f& n,
                        const std::vector<OccluderSphere>& spheres, const cv::Vec3f& lit = {1, 1, 1});

/// The fraction of its light a real point (x, n) keeps beside the objects, per channel in [0, 1]:
/// (E_direct with the objects + E_hidden - what the spheres hide of the hidden light) / (E_direct without them
/// + E_hidden), E_hidden the hidden light's irradiance about n. Near a sphere resting on a table under a lamp,
/// the table in its shadow is what the sphere's underside sees: it reflects the dark table, not the lit one
/// the camera saw (without it the shadow's core came out a quarter as dark as the path tracer's).
cv::Vec3f litFraction(const Ambient& hidden, const cv::Vec3f& x, const cv::Vec3f& n,
                      const std::vector<OccluderSphere>& spheres, const cv::Vec3f& directWithout,
                      const cv::Vec3f& directWith);

/// The ground under the face of a sphere turned towards (x, n), that of the sphere x sees most: the foot of its
/// centre on x's plane, and how much of what the face sees it is, weight = sin^2 b with b the angle under the
/// plane of the direction from the centre to x. Near the contact the face looks straight down at the plane
/// under the sphere (weight 1), which the sphere's own shadows darken whether or not x is lit; from afar it
/// looks sideways at x's surroundings (weight -> 0). sin^2 b has the ends of the view factor from the face to
/// the disc of one radius under the sphere (1 at the contact, 0 at the equator); the shading pass blends the lit
/// fraction at x towards the one at the foot by it (blendLit). Measured on tabletop-scan (Kinect-VAL, the
/// room, listed lights): whole-pipeline delta 0.426 with x's alone, 0.409 with the weight sin b, 0.398 with sin^2 b.
struct FacedGround {
  cv::Vec3f point{0, 0, 0};
  float weight = 0;  ///< 0: no sphere seen from x (point = x)
};
FacedGround facedGround(const cv::Vec3f& x, const cv::Vec3f& n, const std::vector<OccluderSphere>& spheres);
/// The lit fraction of what the objects' faces turned towards x see: lit at x blended towards lit at the ground
/// under them (facedGround's weight).
inline cv::Vec3f blendLit(const cv::Vec3f& atX, const cv::Vec3f& atGround, float weight) {
  return atX + weight * (atGround - atX);
}

/// What the spheres reflect of the lights onto a real surface element (x, n): the objects' bounce of the
/// lights, for a real-role technique that has none of its own (the shading pass adds it). Each sphere is
/// Lambertian, L(p) = albedo E(p, m) / pi on its point p of normal m, E the lights' irradiance there (a lamp's
/// intensity x cos / distance^2 from p, a directional light's irradiance x cos); a light counts where it
/// lights the sphere's point facing it (a spot's cone) and reaches it (`reaches`). The radiance x receives is the mean
/// of L over kReflectionSamples equal-area points of the half of the sphere facing x, weighed by the form factor cos(at
/// p) cos(at x) / R^2 of those above x's horizon; the mean times the sphere's exact view factor (pi F) is the
/// irradiance, so a uniformly bright sphere is exact and the samples only shape the mean. Points whose view factor is
/// under kObjectsMinViewFactor get nothing. Against a fine
/// quadrature of the sphere (object_shadow_test: a sphere resting on a plane, lit aslant, from the side and by a lamp):
/// within 15 % from three radii from its centre, 25 % at two (of the fully lit sphere's irradiance where less is lit).
constexpr int kReflectionSamples = 16;
/// Point k of the equal-area spiral on the half sphere about +z (k < kReflectionSamples).
cv::Vec3d reflectionSample(int k);
/// `reaches(i, p, l)`: whether light i reaches the sphere's point p facing it (direction l); unset: every light
/// does (the GPU twin: the real scene's shadow map, lighting::lightVisibility without the objects).
using LightReaches = std::function<bool(size_t light, const cv::Vec3d& p, const cv::Vec3d& l)>;
cv::Vec3f reflectedLight(const cv::Vec3f& x, const cv::Vec3f& n, const std::vector<OccluderSphere>& spheres,
                         const std::vector<SceneLight>& lights, const LightReaches& reaches = {});

}  // namespace mrgi::lighting
