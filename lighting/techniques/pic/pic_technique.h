#pragma once
/// Precomputed illuminance composition (shared/papers/002; algorithms.md §1 and §6) as a technique module for
/// the virtual object: the static real mesh (the fused room model with --room) is precomputed once —
/// surfels, their hierarchy, a grid of SH caches over the region the objects are in, linked to a cut of the
/// hierarchy with Embree visibility, and bounce receivers on a hierarchy cut — and relit every run on the
/// GPU: the lights' direct light onto the surfels (visibility by Embree rays when the lights move), flux pulled
/// up the hierarchy, each cache's SH radiance gathered over its links (YCoCg, chroma with fewer bands), the
/// object shaded from the eight caches around each pixel: irradiance by the clamped cosine, glossy radiance
/// by the Phong lobe. Each run computes `bounces` bounces from the direct light, or (progressive) adds them
/// to the last run's.
/// Real pixels: none (it describes the room's light at the object, not the change the object makes to the
/// room); combine it with a real-pixel technique ({"real": "imperfect-volumes", "virtual": "pic"}).
/// Reference math: pic.h.
#include <memory>
#include <vector>

#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/techniques/pic/pic.h"
#include "lighting/techniques/technique.h"

namespace mrgi::reconstruction {
class MeshRays;
}

namespace mrgi::lighting {

struct PicKnobs {
  int surfels = 0;           ///< surfels over the static mesh
  int bands = 0;             ///< SH bands of the caches
  int chromaBands = 0;       ///< bands of the caches' chroma (0: as many as bands)
  int links = 0;             ///< links per cache
  int grid = 0;              ///< caches per axis of the grid over the region
  int receivers = 0;         ///< bounce receivers (0: no bounce)
  int bounces = 0;           ///< bounces per run
  bool progressive = false;  ///< the bounce light carries over between runs
  bool rgb9e5 = false;       ///< flux stored as RGB9E5 (else RGBA32F)
};
const std::vector<KnobBinding<PicKnobs>>& picKnobTable();

class PicTechnique final : public Technique {
 public:
  explicit PicTechnique(const TechniqueSetup& setup);
  ~PicTechnique() override;

  std::string name() const override { return "pic"; }
  unsigned inputs() const override { return kInputCamera | kInputGeometry | kInputLights | kInputAmbient; }
  void update(const FrameResources& frame, gl::Profiler* profiler) override;
  TechniqueOutputs outputs() const override;
  /// pic_surfels: the surfels over the composite, coloured by their radiosity; pic_caches: the caches, coloured
  /// by their mean incident radiance (outlined red where negative, grey where they lie behind geometry).
  /// pic_cut: the hierarchy cut linked to the cache at the grid's centre, a colour per linked node.
  std::vector<std::string> debugViews() const override { return {"pic_surfels", "pic_caches", "pic_cut"}; }
  cv::Mat debugImage(const std::string& view, const DebugContext& context, nlohmann::json& info) const override;
  nlohmann::json stats() const override { return stats_; }
  size_t gpuBytes() const override;

  const PicKnobs& knobs() const { return knobs_; }
  int chromaBands() const;
  /// Precomputed state (CPU), for tests and views.
  const std::vector<pic::Surfel>& surfels() const { return surfels_; }
  const pic::Hierarchy& hierarchy() const { return hierarchy_; }
  const pic::CacheLinks& caches() const { return caches_; }
  const pic::Receivers& receivers() const { return receivers_; }
  const pic::CacheLinks& receiverLinks() const { return receiverLinks_; }
  cv::Vec3f gridCentre() const { return gridCentre_; }
  float gridSide() const { return gridSide_; }
  int precomputes() const { return precomputes_; }
  /// Precomputes read back from the cache folder instead (TechniqueSetup::cacheDir).
  int cacheLoads() const { return cacheLoads_; }
  /// GPU downloads: the nodes' flux, the caches' (or receivers') stored SH (YCoCg layout, pic.glsl).
  std::vector<cv::Vec3f> downloadFlux() const;
  std::vector<float> downloadCaches(bool receivers) const;
  /// A stored cache (pic.glsl layout) as RGB coefficients.
  std::vector<cv::Vec3f> decodeCache(const std::vector<float>& stored, size_t cache) const;

 private:
  void precomputeMesh(const FrameResources& frame);
  void placeGrid(const cv::Vec3f& centre, float side);
  /// The surfels' GPU records (pic.glsl PicSurfel), after a precompute or a new albedo.
  void uploadSurfels();
  void uploadLinks(const pic::CacheLinks& links, gl::Buffer& nodes, gl::Buffer& factors, gl::Buffer& transfer);
  void lightAndPull(const FrameResources& frame, bool bounce);
  void gather(const FrameResources& frame, bool receivers);

  /// The file a precompute is kept in (empty without a cache folder): pic_<part>_<key>.bin.
  std::string cacheFile(const char* part, uint64_t key) const;

  PicKnobs knobs_;
  std::function<void(const std::string&, double)> progress_;
  std::string cacheDir_;
  gl::Program lightProgram_, pullProgram_, gatherProgram_, readoutProgram_;
  gl::Texture irradiance_, radiance_;
  gl::Framebuffer fb_;
  gl::VertexArray emptyVao_;

  pic::SurfaceMesh mesh_;
  uint64_t meshKey_ = 0, albedoKey_ = 0, geometryKey_ = 0;
  std::unique_ptr<reconstruction::MeshRays> rays_;
  std::vector<pic::Surfel> surfels_;
  pic::Hierarchy hierarchy_;
  pic::Receivers receivers_;
  pic::CacheLinks caches_, receiverLinks_;
  cv::Vec3f gridCentre_{0, 0, 0};
  float gridSide_ = 0;
  bool gridValid_ = false, receiversLit_ = false;
  std::vector<SceneLight> visibilityLights_;
  int precomputes_ = 0, cacheLoads_ = 0, levelsCount_ = 0;
  std::vector<int> levelFirst_, levelCount_;

  gl::Buffer surfelBuffer_, visibility_, fluxF_, fluxP_, children_, levelNodes_;
  gl::Buffer cacheNodes_, cacheFactors_, cacheTransfer_, cacheBack_, cacheSh_;
  gl::Buffer receiverNodes_, receiverFactors_, receiverTransfer_, receiverSh_;
  nlohmann::json stats_ = nlohmann::json::object();
};

}  // namespace mrgi::lighting
