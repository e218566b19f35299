#pragma once
/// A distant light the camera never saw directly (the sun through a window), found from the light it casts on the
/// room: the sunlit patches and the shadows the room's own geometry bounds them with. For a candidate direction w
/// every sampled surface point x is lit by it when its normal faces w and a ray from x towards w leaves the room
/// (MeshRays: nothing of the room on the way). The surface's irradiance pi L(x) / albedo(x) is then
///   E(x) = E_rest + E_sun max(0, n(x) . w) V(x, w)
/// and the direction whose lit/unlit pattern explains the measured irradiance best (least squares over the points,
/// E_rest and E_sun fitted for each direction) is the light's, refined around the best of a coarse set of
/// directions. What the fit leaves unexplained stays with the room's other light (its SH remainder).
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

namespace mrgi::reconstruction {

class MeshRays;

struct DistantLightOptions {
  int candidates = 600;       ///< directions over the sphere in the coarse search (a Fibonacci set)
  int refineSteps = 3;        ///< rounds of refinement, each a finer 7 x 7 grid around the best so far
  int maxPoints = 4000;       ///< surface points sampled (evenly through the vertices)
  double rayOffsetM = 0.01;   ///< rays start this far along the normal (off the surface they leave)
  double minExplained = 0.3;  ///< the share of the irradiance's variance the light must explain to be kept
  double minLitShare = 0.01;  ///< and the share of the points it must light, and leave unlit
};

struct DistantLight {
  cv::Vec3d towards{0, 0, 1};     ///< unit direction from the room towards the light
  cv::Vec3d irradiance{0, 0, 0};  ///< at normal incidence, unoccluded (per channel)
  cv::Vec3d rest{0, 0, 0};        ///< the irradiance the fit leaves to the room's other light (its mean)
  double explained = 0;           ///< share of the irradiance's variance (green) the light explains
  double litShare = 0;            ///< share of the sampled points it lights
};

/// The strongest distant light explaining the room's irradiance: vertices `positions` with `normals` (unit),
/// `radiance` (linear) and `albedo` (diffuse, > 0; a vertex of albedo 0 or saturated radiance is not used), the
/// room's rays `rays`. None when no direction explains enough (a room lit by its lamps and walls alone).
std::optional<DistantLight> findDistantLight(const std::vector<cv::Vec3f>& positions,
                                             const std::vector<cv::Vec3f>& normals,
                                             const std::vector<cv::Vec3f>& radiance,
                                             const std::vector<cv::Vec3f>& albedo, const MeshRays& rays,
                                             const DistantLightOptions& options = {});

}  // namespace mrgi::reconstruction
