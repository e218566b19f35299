#pragma once
/// Imperfect volumes (shared/papers/004; algorithms.md §7) as a technique module: the virtual objects'
/// triangles and the real mesh (the fused room, or the frame's depth mesh) become points, N per triangle,
/// voxelised into a grid over the region around the objects in two versions (rho: real + virtual, mu: real
/// only), each voxel lit by the scene's lights through the frame's shadow maps and by the unoccluded ambient;
/// per voxel near a surface, rays march the grid and gather the incident radiance as SH — the ambient where
/// nothing is hit within range, the surfaces' reflected light where something is, and further bounces.
/// Outputs: on real pixels the change the objects make, E^rho - E^mu: the lights' bounce off them and what
/// their shadows take from the real surfaces' bounce (in rho the objects hide nothing: the ambient they hide
/// from real surfaces, and what they reflect of it, are the shading pass's, lighting/object_shadow.h);
/// on the object, its ambient occlusion by real geometry and the bounce real surfaces send it (E^mu minus the
/// unoccluded ambient the shading pass adds: the object's own voxels neither occlude nor light it).
/// Reference math: iv.h.
#include <algorithm>
#include <optional>

#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/techniques/imperfect_volumes/iv.h"
#include "lighting/techniques/technique.h"

namespace mrgi::lighting {

struct ImperfectVolumesKnobs {
  int resolution = 0;       ///< voxels per axis of the grid over the region
  int points = 0;           ///< points per triangle (3-19)
  int rays = 0;             ///< rays per voxel
  int bands = 0;            ///< SH bands of the incident radiance
  double range = 0;         ///< metres: a hit farther than this returns the ambient
  int bounces = 0;          ///< 0: ambient occlusion only
  int objectRays = 0;       ///< rays per virtual-object pixel through the mu volume (0: read the voxels' SH)
  int outerResolution = 0;  ///< voxels per axis of the outer volume the object's rays continue in (0: none)
};
const std::vector<KnobBinding<ImperfectVolumesKnobs>>& imperfectVolumesKnobTable();

/// The points of a frame's scene for the volume (CPU): N per triangle of every virtual object and of the
/// real mesh (at least 4 per voxel of a triangle's area, so that a triangle larger than a voxel leaves no
/// hole), on triangles that reach into the grid, with their interpolated normal and albedo; the points of
/// each voxel contiguous (offsets: voxels + 1 entries). With `without` (the outer volume, iv::outerGrid):
/// the real mesh's triangles only and none of the points inside `without`. Shared by the technique and its tests.
struct IvPoints {
  /// Per point, as the GPU reads it: position (w = 1 virtual), normal, albedo.
  std::vector<cv::Vec4f> data;
  std::vector<uint32_t> offsets;
  size_t count() const { return data.size() / 3; }
  size_t realTriangles = 0, virtualTriangles = 0;
};
IvPoints ivScenePoints(const FrameResources& frame, const iv::Grid& grid, int perTriangle,
                       const iv::Grid* without = nullptr);
/// The outer volume's points: the real mesh outside `inner`, at the inner grid's density per voxel area
/// (perTriangle scaled by (inner voxel / outer voxel)^2, at least 1).
IvPoints ivOuterPoints(const FrameResources& frame, const iv::Grid& inner, const iv::Grid& outer, int perTriangle);

class ImperfectVolumesTechnique final : public Technique {
 public:
  bool accountsForReflectedLight() const override { return true; }  // the objects' bounce, E^rho - E^mu
  explicit ImperfectVolumesTechnique(const TechniqueSetup& setup);

  std::string name() const override { return "imperfect-volumes"; }
  unsigned inputs() const override { return kInputCamera | kInputGeometry | kInputLights | kInputAmbient; }
  void update(const FrameResources& frame, gl::Profiler* profiler) override;
  TechniqueOutputs outputs() const override;
  /// iv_slices: occupancy and ambient occlusion per slice of the grid; iv_ao: the ambient occlusion at each
  /// pixel's surface with the objects (white: open sky, black: none of it).
  std::vector<std::string> debugViews() const override { return {"iv_slices", "iv_ao"}; }
  cv::Mat debugImage(const std::string& view, const DebugContext& context, nlohmann::json& info) const override;
  nlohmann::json stats() const override;
  size_t gpuBytes() const override;

  const ImperfectVolumesKnobs& knobs() const { return knobs_; }
  /// The sphere about the virtual objects whose cone the real-pixel delta samples from every voxel
  /// (iv::coneCorrection, added to rho's incident light), and its rays per voxel: half the gather's, at least 8.
  /// nullopt when the technique serves no real role or no object is placed.
  const std::optional<iv::Bound>& coneBound() const { return coneBound_; }
  int coneRays() const { return std::max(8, knobs_.rays / 2); }
  const std::optional<iv::Grid>& grid() const { return grid_; }
  /// The outer volume's grid (none unless the object's rays continue past the grid).
  const std::optional<iv::Grid>& outerGrid() const { return outerGrid_; }
  /// The last run's volume and gathered light as the reference math holds them (GPU download).
  iv::Volume downloadVolume() const;
  /// The outer volume (empty grid where there is none).
  iv::Volume downloadOuterVolume() const;
  iv::Incident downloadIncident(bool rho) const;
  /// Per voxel, the ambient the objects hide from its real surface (iv::ambientHiddenByObjects; empty unless
  /// the object casts its own rays).
  std::vector<cv::Vec3f> downloadHidden() const;

  /// The most bytes the rays' hits may take (8 per voxel ray, iv_hits.comp): within it each needed voxel's rays
  /// are marched once for the hidden ambient, both gathers and every bounce; past it each of those passes
  /// marches them itself (the same hits). Default kDefaultHitsBudget (a 64³ grid's surfaces at 256 rays fit).
  static constexpr size_t kDefaultHitsBudget = size_t{64} << 20;
  void setHitsBudget(size_t bytes) { hitsBudget_ = bytes; }
  /// Whether the last build kept the rays' hits.
  bool hitsCached() const { return hitsCached_; }

 private:
  void build(const FrameResources& frame, gl::Profiler* profiler);
  void gather(const FrameResources& frame, bool rho);

  ImperfectVolumesKnobs knobs_;
  bool real_ = false, virtual_ = false;
  gl::Program injectProgram_, gatherProgram_, reflectProgram_, hiddenProgram_, coneProgram_, readoutProgram_,
      hitsProgram_;
  size_t hitsBudget_ = kDefaultHitsBudget;
  bool hitsCached_ = false;
  /// Uses a pass that casts rays from the needed voxels: the grid, the rays and range; binds the voxels (2),
  /// their occupancy (14), the needed list (3) and the directions (4); for a pass that reads the rays' hits
  /// (every one but iv_hits.comp itself) also the ambient, whether the hits are kept, and the hits (1).
  void useVoxelRays(const gl::Program& p, const FrameResources& frame, bool readsHits = true) const;
  std::optional<iv::Bound> coneBound_;
  std::optional<iv::Grid> grid_, outerGrid_;
  /// The frame versions the volume was built from (geometry, lights, ambient).
  std::optional<std::array<uint64_t, 3>> builtFrom_;
  gl::Buffer points_, offsets_, voxels_, needed_, directions_, incidentRho_, incidentMu_, occlusionRho_, occlusionMu_,
      reflected_, bounce_, computed_, objectDirections_, reflectedSum_, hidden_, outerPoints_, outerOffsets_,
      outerVoxels_, occupancy_, outerOccupancy_, hits_;
  size_t neededCount_ = 0, pointCount_ = 0, outerPointCount_ = 0;
  IrradianceTargets out_;
  gl::VertexArray emptyVao_;
  nlohmann::json stats_ = nlohmann::json::object();
  const FrameResources* frame_ = nullptr;  ///< of the last update (its G-buffer, for the AO view)
};

}  // namespace mrgi::lighting
