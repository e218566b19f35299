#pragma once
/// A distant light the camera never saw directly (the sun through a window), found from the light it casts on the
/// room: the sunlit patches and the shadows the room's own geometry bounds them with. For a candidate direction w
/// a surface point x is lit by it when its normal faces w and a ray from x towards w leaves the room through an
/// opening the cameras saw through (DistantLightRays). Where that predicts an edge between two neighbouring points
/// of one surface (one lit, one in the room's shadow), the measured irradiance pi L / albedo should step up by the
/// light's irradiance times n . w; the direction whose predicted edges the room's light agrees with most is the
/// light's, refined around the best of a coarse set of directions. Differences across the edges are blind to light
/// that varies smoothly (a lamp's falloff, the walls' bounce) and to albedo that changes elsewhere. Its irradiance
/// comes from 30 cm pieces of the surfaces it both lights and leaves in shadow (the medians either side, over the
/// shadowed side's albedo). What the light leaves stays with the room's other light (its SH remainder).
#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

namespace mrgi::reconstruction {

class MeshRays;
struct RoomOpenings;

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
  /// A light is kept when its edges agree (their steps' mean over root mean square at least minConsistency) and are
  /// many enough to tell from noise (that ratio times the square root of their count, a t-statistic, at least
  /// minScore). On the bundled rooms: the sun through the synthetic window (ray cast and path traced) about 0.6 and
  /// 7; the best direction of rooms without a sun 0.51 and 3.1 (tabletop-scan), 0.71 and 5.6 but a fiftieth of the
  /// room's light (tabletop-synth's first 8 frames: its lamp's shadows), 0.61 over the ViSP desk's printed tags
  /// (minPieceShare below), 0.35 and 9.6 in the ICL living room (whose sunlit floor the search does not yet explain).
  double minConsistency = 0.4;
  double minScore = 5.0;
  /// ... and when the patches it lights are brighter than its shadows by at least this share of them (the light's
  /// irradiance over the shadowed points' mean): the edges of a lamp's shadows explain a faint distant light.
  double minContrast = 0.5;
  /// ... and when the pieces of surface it both lights and shadows mostly show it (their lit side brighter): a
  /// texture's edges (a board of printed tags) can line up with a direction's predicted edges, but not piece by
  /// piece. The sun through the synthetic window: 10-12 of 13-14 pieces; the ViSP desk's best direction: 2 of 6.
  int minPiecesShowing = 3;
  double minPieceShare = 0.5;
  double minLitShare = 0.002;  ///< the share of the points it must light, and leave unlit
  double clipRadiance = 0.95;  ///< a channel's radiance at or above this is a lower bound (the sensor's white)
  /// Set: no search; the light is measured from this direction (the edges it predicts), kept whatever its
  /// consistency. A direction found with one albedo is measured with another so.
  std::optional<cv::Vec3d> towards;
};

struct DistantLight {
  cv::Vec3d towards{0, 0, 1};     ///< unit direction from the room towards the light
  cv::Vec3d irradiance{0, 0, 0};  ///< at normal incidence, unoccluded (per channel): the pieces' weighted median
  std::array<bool, 3> lowerBound{false, false, false};  ///< per channel: every lit side was clipped
  cv::Vec3d rest{0, 0, 0};  ///< the mean irradiance of the points it faces and the room shadows
  double consistency = 0;   ///< mean over root mean square of the edges' steps (1: all agree)
  int edges = 0;            ///< neighbour pairs across its predicted edges
  double litShare = 0;      ///< share of the sampled points it lights
  int pieces = 0;           ///< 30 cm pieces of surface it both lights and leaves in the room's shadow
  int piecesShowing = 0;    ///< of them, those whose lit side is brighter than their shadowed side
  /// Whether the irradiance only bounds the light from below (its sunlit patches clipped).
  bool atLeast() const { return lowerBound[0] || lowerBound[1] || lowerBound[2]; }
};

/// Whether a distant light towards w reaches a point: rays against the room, and where a ray meets none of it,
/// whether it leaves through an opening the cameras saw through (RoomOpenings; without a record, wherever it
/// leaves) or through a gap they never looked at (an unseen ceiling), which tells nothing either way. Leaving is
/// judged where the ray crosses the box around `positions`.
class DistantLightRays {
 public:
  /// Keeps references to `rays` and `openings` (may be null).
  DistantLightRays(const std::vector<cv::Vec3f>& positions, const MeshRays& rays, const RoomOpenings* openings);
  /// 1: reaches `origin` (off its surface already); 0: the room is in the way; -1: unknown (leaves by a gap).
  int reaches(const cv::Vec3d& origin, const cv::Vec3d& w) const;
  /// How much of a distant light towards w a surface point (`position`, unit `normal`) takes: n . w where it faces
  /// w and the light reaches it (reaches(), from `offsetM` along the normal), else 0.
  double lightOn(const cv::Vec3d& position, const cv::Vec3d& normal, const cv::Vec3d& w, double offsetM = 0.01) const;
  /// For a ray that meets none of the room: the opening cell (RoomOpenings' index) it leaves through, or -1 (a
  /// gap, or no record).
  int opening(const cv::Vec3d& origin, const cv::Vec3d& w) const;

 private:
  const MeshRays& rays_;
  const RoomOpenings* openings_;
  cv::Vec3d lo_, hi_;
};

/// The strongest distant light explaining the room's irradiance: vertices `positions` with `normals` (unit),
/// `radiance` (linear), `albedo` (diffuse, > 0; a vertex of albedo 0 is not used) and `saturated` (1: every
/// observation clipped, its radiance a lower bound; may be empty), the
/// room's rays `rays` and `openings` (DistantLightRays). None when no direction explains enough (a room lit by its
/// lamps and walls alone).
std::optional<DistantLight> findDistantLight(
    const std::vector<cv::Vec3f>& positions, const std::vector<cv::Vec3f>& normals,
    const std::vector<cv::Vec3f>& radiance, const std::vector<cv::Vec3f>& albedo, const std::vector<uint8_t>& saturated,
    const MeshRays& rays, const DistantLightOptions& options = {}, const RoomOpenings* openings = nullptr);

}  // namespace mrgi::reconstruction
