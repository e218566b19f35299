#pragma once
/// The persistent model of the real room: every frame's filtered depth fused with its pose into a truncated
/// signed distance volume (Open3D's VoxelBlockGrid: voxel blocks allocated where surfaces are seen), so
/// that light from surfaces out of the current view is still there, and real objects that move are carved
/// away by later observations. The lighting world is the marker frame.
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <unordered_map>
#include <vector>

#include "capture/types.h"
#include "reconstruction/albedo.h"

namespace mrgi::reconstruction {

class MeshRays;  // reconstruction/mesh_rays.h

struct RoomOptions {
  double voxelM = 0.02;  ///< voxel edge (metres)
  double truncM = 0.08;  ///< truncation distance of the signed distance (metres, at least 2 voxels)
  int maxBlocks =
      8192;  ///< memory budget in voxel blocks (16^3 voxels each); frames that would grow past it are not integrated
  double maxDepthM = 4.0;  ///< depth beyond this is not integrated
  /// A frame's pose is checked against the model before it is integrated: of its depth points that land in
  /// observed space, more than `outlierFraction` lying farther than `outlierM` from the fused surface mean
  /// the pose disagrees with the model, and the frame is not integrated (needs `minOverlap` of its points
  /// in observed space to judge; less is a new view and is integrated).
  double outlierM = 0.03;
  double outlierFraction = 0.3;
  double minOverlap = 0.25;
  /// Fused appearance: every `appearanceStride`-th pixel's colour (0: chosen from the focal length, one
  /// sample per 2 mrad, i.e. 2 at 320x240 and 4 at 640x480 for a Kinect-like lens) is an observation of the surface it
  /// sees, as linear radiance at exposure 1 (decoded sRGB / the frame's exposure). Observations at grazing angles
  /// (|cos| < grazingCos between the depth normal and the view ray), on depth edges, or with a channel at or
  /// above `clipLevel` (8-bit) are not averaged in; clipped ones only bound the radiance from below. The
  /// rest are weighted by confidence cos / z^2 (the sensor's noise grows with z^2, its footprint with
  /// 1 / cos); after `appearanceMemory` observations of a voxel older ones fade, so a surface whose light
  /// changes follows.
  int appearanceStride = 0;
  double grazingCos = 0.26;
  int clipLevel = 250;
  int appearanceMemory = 64;
  /// Throws InputError naming `where` if a value is out of range.
  void validate(const std::string& where) const;
};

/// What one integrate() call did.
struct RoomIntegration {
  bool integrated = false;
  std::string refused;      ///< why not: "pose disagrees with the model", "memory budget", "no valid depth"
  double overlap = 0;       ///< fraction of the frame's sampled points in observed space
  double inconsistent = 0;  ///< of those, the fraction farther than outlierM from the surface
  size_t newBlocks = 0;     ///< blocks this frame allocated (or would have)
};

/// Where the cameras saw through the room: cells (edge `cellM`, lighting world, cell (i, j, k) spanning
/// [i, i + 1) cellM along x and so on) crossed by camera rays that returned no depth (a window onto the sky, a
/// door open onto the outside; a surface past the fusion's range returns depth and is not one). A surface the cameras
/// never looked at leaves a gap in the mesh too, but none of these cells beyond it: a ray that leaves the room through
/// an opening can be told from one that leaves it through a gap.
struct RoomOpenings {
  double cellM = 0.1;
  std::vector<cv::Vec3i> cells;     ///< sorted, each once
  std::vector<cv::Vec3f> radiance;  ///< per cell: the mean linear radiance (exposure 1) its rays saw beyond
  std::vector<uint8_t> clipped;     ///< per cell: 1 where most of them were clipped (a lower bound)
  bool recorded = false;            ///< false: the room holds no record (a room saved before it was kept)
  /// The index of the cell holding p, or -1.
  int find(const cv::Vec3d& p) const;
  bool contains(const cv::Vec3d& p) const { return find(p) >= 0; }
  /// For a ray from `origin` (inside the box [lo, hi] around the room) along unit `w` that meets none of the room:
  /// the cell it leaves through, looked for where it crosses the box and a few cells beyond, or -1 (a gap the
  /// cameras never looked through, or no record).
  int beyond(const cv::Vec3d& lo, const cv::Vec3d& hi, const cv::Vec3d& origin, const cv::Vec3d& w) const;
};

/// A triangle mesh of the model's surface in the lighting world, with the fused appearance per vertex.
struct RoomMesh {
  std::vector<cv::Vec3f> positions, normals;
  /// Linear radiance at exposure 1 (RoomOptions: confidence-weighted over the accepted observations);
  /// for a saturated vertex a lower bound (the clip level over the exposure).
  std::vector<cv::Vec3f> radiance;
  std::vector<float> confidence;   ///< summed observation weight (0: only Open3D's colour average was there)
  std::vector<uint8_t> saturated;  ///< 1: every observation was clipped (a lamp, a window)
  std::vector<uint32_t> indices;
  RoomOpenings openings;
  size_t triangleCount() const { return indices.size() / 3; }
};

class RoomModel {
 public:
  explicit RoomModel(const RoomOptions& options = {});
  ~RoomModel();
  RoomModel(RoomModel&&) noexcept;
  RoomModel& operator=(RoomModel&&) noexcept;

  /// Fuses one frame: depth in metres (CV_32FC1, 0 = invalid) and its colour (CV_8UC3 RGB, sRGB) on the same
  /// pixel grid with intrinsics K, seen from T_world_camera. The pose is checked first (see RoomOptions).
  /// The colour's linear radiance is its decoded value / `exposure`. Only this frame's observations are
  /// touched: the cost is bounded by the frame, not the model.
  RoomIntegration integrate(const cv::Mat& depth, const cv::Mat& colour, const capture::Intrinsics& K,
                            const capture::Pose& T_world_camera, double exposure = 1.0);
  /// The pose check alone: the fractions integrate() would decide on, and whether it would refuse.
  RoomIntegration checkPose(const cv::Mat& depth, const capture::Intrinsics& K,
                            const capture::Pose& T_world_camera) const;
  /// Signed distance to the fused surface at a point of the lighting world (metres, trilinear; positive in
  /// free space), or NaN where the volume has not been observed. It is the fusion's projective distance
  /// (along the viewing rays), at least the Euclidean one and at most the truncation distance.
  double signedDistance(const cv::Vec3d& p) const;

  RoomMesh mesh() const;
  size_t blocks() const;
  size_t bytes() const;            ///< voxel storage
  size_t appearanceBytes() const;  ///< fused appearance storage (voxels with observations)
  int framesIntegrated() const { return integrated_; }
  int framesRefused() const { return refused_; }
  const RoomOptions& options() const { return options_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  RoomOptions options_;
  int integrated_ = 0, refused_ = 0;
};

/// Each vertex's neighbours along a triangle mesh's edges (`vertices` of them; indices past them left out).
std::vector<std::vector<uint32_t>> meshNeighbours(const std::vector<uint32_t>& indices, size_t vertices);
/// Values not `known` take the mean of their known neighbours, ring by ring (each ring from the values known
/// before it), until none is left that a known one reaches or `rings` rings are done; filled values become known.
void fillFromNeighbours(std::vector<cv::Vec3f>& values, std::vector<uint8_t>& known,
                        const std::vector<std::vector<uint32_t>>& neighbours, int rings = 64);

/// Per-vertex albedo of the room under known lights (all in the lighting world), as estimateAlbedo does per
/// pixel: k_d = pi * L / E with E the lights' direct irradiance (shadows ray-cast against the room itself)
/// plus the ambient. A vertex in a light's shadow is measured under the other lights; the edges of the shadows,
/// saturated, grazing or unlit vertices are rejected and filled from their mesh neighbours; the status says which
/// (AlbedoStatus).
struct RoomAlbedo {
  std::vector<cv::Vec3f> albedo;
  std::vector<AlbedoStatus> status;
  /// What a pass that bounces the lights off the room's surfaces (RSMs, injected points) should take as their
  /// albedo so that they send their fused radiance: albedo x (E / (E_lights + ambient)), at most 1, with E the
  /// vertex's whole irradiance (the room's bounce included; the albedo itself where no light reaches it). Such
  /// passes bounce the lights' irradiance once; in a closed room the rest of its light is a third or more of
  /// what its surfaces send. Equal to `albedo` without the room's bounce.
  std::vector<cv::Vec3f> sent;
  /// 1: a light the vertex faces is blocked by the room (the vertex measured under the other lights).
  std::vector<uint8_t> inShadow;
};

/// What estimateRoomAlbedo keeps between calls on successive meshes of one room (a live fusion's refreshes),
/// so that a refreshed room costs what changed in it, not the whole room: every vertex's shadow rays, keyed by
/// the voxel edge the vertex lies on (marching cubes puts one vertex on an edge between two voxel centres).
/// A later mesh re-casts only what its change can affect: the rays of vertices that are new or moved more than
/// a quarter voxel; rays of the other vertices that a new or moved triangle now crosses; and rays whose
/// occluder moved or went (a vertex of the earlier mesh within 1.5 voxels of where the ray was blocked). The
/// radiance, the irradiance and the status are then recomputed for every vertex (no rays: cheap). The lights'
/// positions and directions key the shadows (their intensities do not move any): lights that moved (more than
/// half a voxel, or 0.3 degrees for a distant one) or a different count re-cast everything.
class RoomAlbedoCache {
 public:
  explicit RoomAlbedoCache(double voxelM = RoomOptions{}.voxelM);
  struct Stats {
    size_t vertices = 0, changedVertices = 0;  ///< of the last mesh: all, and new or moved
    size_t raysCast = 0;                       ///< shadow rays cast against the whole mesh
    size_t raysRechecked = 0;                  ///< rays that were free, cast again against the changed triangles only
    size_t raysReused = 0;                     ///< rays kept with no ray cast
    bool full = true;                          ///< everything was cast (first mesh, or the lights moved)
  };
  const Stats& lastStats() const { return stats_; }
  /// One flag per vertex and light (row-major, vertex-major): 1 where something blocks the segment from just
  /// off the vertex (2 cm along its normal) to the light; updates the cache to `mesh`.
  /// `rays`: rays against `mesh` the caller has built already (else built here when needed).
  std::vector<uint8_t> shadows(const RoomMesh& mesh, const AlbedoLights& lights, const MeshRays* rays = nullptr);

 private:
  struct Entry {
    cv::Vec3f position;
    std::vector<float> blockedAt;  ///< per light: distance along the ray to what blocks it, < 0 when free
  };
  double voxelM_;
  std::vector<cv::Vec3d> lightKeys_;
  std::vector<uint8_t> lightDistant_;
  std::unordered_map<uint64_t, Entry> entries_;
  Stats stats_;
};
/// With a cache, the shadow rays of vertices and lights the change since the cache's last mesh cannot affect
/// are not cast again (RoomAlbedoCache).
/// `bounce` (roomBounceIrradiance, one per vertex): the irradiance the room sends each vertex, in E instead of
/// the lights' ambient. `rays`: rays against `mesh` the caller has already (one BVH per room, not one per use).
RoomAlbedo estimateRoomAlbedo(const RoomMesh& mesh, const AlbedoLights& lightsInWorld,
                              const AlbedoOptions& options = {}, RoomAlbedoCache* cache = nullptr,
                              const std::vector<cv::Vec3f>* bounce = nullptr, const MeshRays* rays = nullptr);

/// The texture the fused room blurs over its voxels, recovered from a frame: the ratio of the radiance a pixel
/// observes (rgb8 its 8-bit value, pixelRadiance the same at exposure 1) to the fused radiance of the room
/// vertex it sees, per channel, clamped to [1/4, 4]. The room vertex's albedo times it is π L_pixel / E, the
/// pixel's own albedo under the room's irradiance. Where a channel of the pixel is clipped (>= 250) the ratio
/// is a lower bound and only raises: at least 1 (a clipped white patch the voxels blurred with black ones
/// takes its white back). 1 where the room's radiance is too dark to divide by (< 1e-3).
cv::Vec3f albedoDetail(const cv::Vec3b& rgb8, const cv::Vec3f& pixelRadiance, const cv::Vec3f& roomRadiance);

/// A saved room: ROOM/room.ply (binary PLY: positions, normals, 8-bit sRGB colour for viewers),
/// ROOM/room_appearance.npy (float32, one row per vertex: linear radiance r, g, b, confidence, saturated)
/// ROOM/room_openings.npy (float32, one row per opening cell: i, j, k, the radiance seen through it r, g, b,
/// clipped; absent when none was seen) and ROOM/room.json (format, version 2, options, frames, bounds, the
/// session it came from, "openings": its cell edge and file, or null). Version 1 rooms (no appearance file) load
/// with the PLY colour as radiance; rooms without "openings" have no record of them (RoomOpenings::recorded).
struct RoomInfo {
  RoomOptions options;
  int framesIntegrated = 0, framesRefused = 0;
  size_t blocks = 0, bytes = 0, appearanceBytes = 0;
  std::string session;
};
void saveRoom(const std::string& dir, const RoomMesh& mesh, const RoomInfo& info);
/// Loads a saved room; every problem (missing files, malformed JSON or PLY, indices out of range, an empty
/// mesh) is an InputError naming the file.
RoomMesh loadRoom(const std::string& dir, RoomInfo* info = nullptr);

}  // namespace mrgi::reconstruction
