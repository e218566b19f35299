#pragma once
/// Kinect-VAL's own input: the real scene as light sources, real-surface virtual area lights (Lambertian discs
/// of the seen radiance) from RGB-D pixels, fused over frames in a world-space surfel map, or from a room model.
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <unordered_map>
#include <vector>

#include "capture/types.h"
#include "lighting/frame/technique_input.h"
#include "reconstruction/room_model.h"

namespace mrgi::lighting {

/// One virtual area light (GPU layout: 3 × vec4).
struct Val {
  cv::Vec3f position;  ///< disc centre, world
  float area = 0;      ///< m²
  cv::Vec3f normal;    ///< unit, the emitting side
  float weight = 1;    ///< averaging weight: lum(φ_j) / mean lum(φ) × mean area (m²); see setValWeights
  cv::Vec3f flux;      ///< W (RGB)
  float pad = 0;
};
static_assert(sizeof(Val) == 48);

/// VALs from an RGB-D frame: every stride-th valid pixel with a normal, position and normal moved into the
/// world, area (z/fx)(z/fy) stride² cos α / <n, −view>+ (α off the optical axis, cos clamped at 0.1), radiance = the
/// linear colour / π per unit albedo... i.e. a Lambertian emitter of the seen radiance: φ = π L a.
std::vector<Val> valsFromRgbd(const cv::Mat& positions, const cv::Mat& normals, const cv::Mat& linearColour,
                              const capture::Intrinsics& k, const capture::Pose& T_world_camera, int stride);
/// VALs from the fused room (reconstruction::RoomMesh, lighting world): the mesh's area gathered into cells
/// of `cell` metres (each vertex a third of its triangles' area), per cell the area-weighted mean position
/// and normal and the flux π L A of its vertices' fused radiance (exposure 1) — the Lambertian emitter of
/// what the camera saw, over every surface the room holds, not only those in view. `indices`: the triangles
/// to take (default: all the room's; the frame pipeline passes those left after clearing around lights).
/// Saturated vertices (lamps: only a lower bound, and a light of their own) give none. The cell doubles until there are
/// at most maxVals; cells whose normals cancel (a thin object's two sides) are dropped.
std::vector<Val> valsFromRoom(const reconstruction::RoomMesh& room, float cell = 0.04f, size_t maxVals = 16384,
                              const std::vector<uint32_t>* indices = nullptr);

/// Sets every VAL's averaging weight: its flux luminance over the set's mean (1 when that is 0) times the
/// set's mean area, so that ε + weight · cos ϑ_j cos ϑ_i / (π d² + a_j) ∝ lum(E_j) is a form-factor-sized number.
void setValWeights(std::vector<Val>& vals);

/// Beyond the paper: real-surface VALs fused over frames in a world-space map keyed by voxel, so surfaces
/// that left the view keep lighting the object and the light does not flicker with sensor noise.
struct SurfelOptions {
  float voxel = 0.02f;  ///< metres
  float decay = 0.0f;   ///< confidence kept per frame by a surfel the frame should have seen but did not:
                        ///< 0 drops it (the frame is authoritative for what it sees; otherwise a surface
                        ///< quantised into a neighbouring voxel this time counts twice)
  float minConfidence = 0.05f;
  float maxConfidence = 10.f;
};

class SurfelMap {
 public:
  explicit SurfelMap(const SurfelOptions& o = {}) : o_(o) {}
  /// Integrates one frame's VALs (world frame). A surfel not observed decays only where the frame should
  /// have seen it: it projects into the image (view: T_world_camera, k) and the frame's depth there is
  /// valid and not in front of it by more than two voxels. Surfels out of view or hidden keep their light.
  /// Without a view (depth empty) every unobserved surfel decays.
  void integrate(const std::vector<Val>& vals, const cv::Mat& depth = cv::Mat(), const capture::Intrinsics& k = {},
                 const capture::Pose& T_world_camera = capture::identityPose());
  /// One VAL per surfel: confidence-weighted mean position, normal, radiance and area.
  std::vector<Val> vals() const;
  size_t size() const { return map_.size(); }
  void clear() { map_.clear(); }

 private:
  struct Surfel {
    cv::Vec3f position{0, 0, 0}, normal{0, 0, 0}, exitance{0, 0, 0};  ///< running means (exitance = φ/a)
    float area = 0, confidence = 0;
  };
  SurfelOptions o_;
  std::unordered_map<uint64_t, Surfel> map_;
};

/// The real VALs of a frame or a room, as the frame holds them for Kinect-VAL (FrameResources::techniqueInput).
struct RealVals : TechniqueInput {
  std::vector<Val> vals;
  size_t surfels = 0;  ///< the surfel map's size when fused over frames
  nlohmann::json facts() const override;
};

/// How Kinect-VAL's real VALs are built: every stride-th RGB-D pixel, fused over frames in a SurfelMap when
/// `fusion`; from a room, its surfaces gathered into 4 cm cells (at most 16384).
class RealValBuilder : public TechniqueInputBuilder {
 public:
  RealValBuilder(int stride, bool fusion, const SurfelOptions& surfels);
  std::shared_ptr<const TechniqueInput> fromFrame(const InputFrame& frame) override;
  std::shared_ptr<const TechniqueInput> fromRoom(const reconstruction::RoomMesh& room,
                                                 const std::vector<uint32_t>& indices) override;

 private:
  int stride_;
  std::optional<SurfelMap> surfels_;
};

}  // namespace mrgi::lighting
