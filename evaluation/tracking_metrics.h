#pragma once
// Measures of tracking beyond the marker: a trajectory against the ground truth (absolute trajectory error,
// relative pose error per frame) and a fused room against the room fused at the true poses (how far its
// surface lies from the other's, how much of the other it covers).
#include <optional>
#include <vector>

#include "capture/types.h"
#include "reconstruction/room_model.h"

namespace mrgi::evaluation {

struct TrajectoryError {
  int frames = 0, tracked = 0;       ///< frames with a ground-truth pose, and of those the ones with an estimate
  double ateRmseM = 0, ateMaxM = 0;  ///< camera position against the truth (metres), over the tracked frames
  /// Relative pose error between consecutive tracked frames (the motion's error, metres and degrees), RMS.
  double rpeRmseM = 0, rpeRmseDeg = 0;
  double lastM = 0;  ///< the last tracked frame's position error
};
/// `estimate[i]` (nullopt: lost) against `truth[i]`, both camera to world in the same world.
TrajectoryError trajectoryError(const std::vector<std::optional<capture::Pose>>& estimate,
                                const std::vector<capture::Pose>& truth);

struct SurfaceDistance {
  size_t points = 0;
  double meanM = 0, p90M = 0;  ///< distance of `from`'s vertices to `to`'s surface
  double within2cm = 0;        ///< fraction of `from`'s vertices within 2 cm of `to`'s surface
};
/// How far the surface of `from` lies from the surface of `to`: per vertex of `from`, the distance to the
/// nearest vertex of `to` along that vertex's normal (point to plane), at most the Euclidean distance.
/// Swap the arguments for the coverage of one room by the other. Empty rooms give infinite distances.
SurfaceDistance surfaceDistance(const reconstruction::RoomMesh& from, const reconstruction::RoomMesh& to);

}  // namespace mrgi::evaluation
