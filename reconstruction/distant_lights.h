#pragma once
/// A distant light the camera never saw directly (the sun through a window), found from the light it casts on the
/// room: the sunlit patches and the shadows the room's own geometry bounds them with. For a candidate direction w
/// a surface point x is lit by it when its normal faces w and a ray from x towards w leaves the room (MeshRays:
/// nothing of the room on the way). Where that predicts an edge between two neighbouring points of one surface
/// (one lit, one in the room's shadow), the measured irradiance pi L / albedo should step up by the light's
/// irradiance times n . w; the direction whose predicted edges the room's light agrees with most is the light's,
/// refined around the best of a coarse set of directions. Differences across the edges are blind to light that
/// varies smoothly (a lamp's falloff, the walls' bounce) and to albedo that changes elsewhere. What the light
/// leaves stays with the room's other light (its SH remainder).
#include <optional>
#include <vector>

namespace mrgi::reconstruction {

class MeshRays;

struct DistantLightOptions {
  cv::Vec3d up{0, 0, 1};           ///< the room's up (the marker's z, the first frame's floor normal)
  double minElevationSin = -0.05;  ///< the light lies above this (sine of its elevation over the horizon)
  int candidates = 600;            ///< directions over that hemisphere in the coarse search (a Fibonacci set)
  int coarseKept = 6;              ///< the coarse directions that explain most, each searched around by its edges
  int refineSteps = 3;             ///< rounds of refinement, each a finer 7 x 7 grid around the best so far
  int maxPoints = 12000;           ///< surface points sampled (evenly through the vertices)
  double edgeRadiusM = 0.08;       ///< neighbours within this distance on the same surface make the edges
  double rayOffsetM = 0.01;        ///< rays start this far along the normal (off the surface they leave)
  double minFacing = 0.05;         ///< an edge's points face the light at least this much (n . w)
  int minEdges = 30;               ///< predicted edges a direction needs to be judged
  double minConsistency = 0.6;     ///< mean over root mean square of the edges' steps: the light is kept above it
  double minLitShare = 0.002;      ///< the share of the points it must light, and leave unlit
};

struct DistantLight {
  cv::Vec3d towards{0, 0, 1};     ///< unit direction from the room towards the light
  cv::Vec3d irradiance{0, 0, 0};  ///< at normal incidence, unoccluded (per channel): the edges' median step
  cv::Vec3d rest{0, 0, 0};        ///< the mean irradiance of the points it faces and the room shadows
  double consistency = 0;         ///< mean over root mean square of the edges' steps (1: all agree)
  int edges = 0;                  ///< neighbour pairs across its predicted edges
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
