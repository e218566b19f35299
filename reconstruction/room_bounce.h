#pragma once
/// The light the room sends itself: at every vertex of a fused room, the irradiance arriving from the rest of
/// the room's surface, gathered from the fused radiance (what the camera saw, so every bounce is in it).
/// The albedo of a real surface is its radiance over the irradiance it receives, k_d = pi L / E: the listed
/// lights give E's direct part, and this gives the rest, which a constant ambient only stands in for (in a
/// closed room lit by one lamp it is a third of E or more, and an albedo without it comes out too bright by as
/// much, and every shadow drawn with it too dark).
#include <opencv2/core.hpp>
#include <vector>

#include "reconstruction/mesh_rays.h"
#include "reconstruction/room_model.h"

namespace mrgi::reconstruction {

struct RoomBounceOptions {
  int rays = 32;  ///< cosine-weighted rays per vertex (stratified, each vertex's set turned about its normal)
  /// Rays are cast from every `vertexStride`-th vertex; the others take their mesh neighbours' mean (the
  /// irradiance from the rest of a room varies over tens of centimetres, the vertices lie a voxel apart).
  int vertexStride = 4;
  /// Passes of averaging over a vertex's mesh neighbours (the irradiance from far surfaces is smooth; the
  /// averaging takes the rays' noise out, a pass halving its variance or better).
  int smoothing = 3;
  /// A ray that leaves the fused room through a hole (a ceiling the scan never looked up at) meets the room's
  /// bounding box and finds the radiance of the fused vertex nearest that point, if one lies within `holeReachM`
  /// (the surface continued into the hole from its seen edge: overhead, where a table looks most, the unseen
  /// ceiling near a lamp is brighter than the room's mean). A ray that leaves farther from anything seen finds
  /// the mean radiance of the vertex's rays that found some; where fewer than a quarter did, `outside`
  /// (W/m^2/sr, linear RGB). holeReachM = 0: no continuation. A ray that leaves through an opening the cameras saw
  /// through (RoomMesh::openings: a window) finds the radiance they saw beyond it (the sky) instead.
  double holeReachM = 1.0;
  cv::Vec3d outside{0, 0, 0};
  double offsetM =
      0.02;         ///< rays start this far off the surface along the normal (a voxel: past the mesh's own ripple)
  int threads = 0;  ///< 0: every hardware thread
};

/// Per vertex of `mesh` (indices into its positions), the irradiance (W/m^2, linear RGB, exposure 1) the room
/// sends it: pi times the mean fused radiance of what its rays hit first (barycentric over the hit
/// triangle's vertices); saturated vertices (a lamp, a window: listed or estimated lights stand for them)
/// send nothing. `rays` casts against the same mesh. Deterministic for a given mesh and options.
std::vector<cv::Vec3f> roomBounceIrradiance(const RoomMesh& mesh, const MeshRays& rays,
                                            const RoomBounceOptions& options = {});

}  // namespace mrgi::reconstruction
