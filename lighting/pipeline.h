#pragma once
/// The per-frame lighting pipeline: the frame's shared resources (lighting/frame/frame.h) -> the scene's
/// techniques, one instance per distinct technique, each serving the roles the scene gives it
/// (lighting/techniques/registry.h) -> the shared shading pass (direct light, shadows, ambient, plus the
/// techniques' outputs) for the compositor. It names no technique: everything technique-specific sits behind
/// lighting/techniques/technique.h.
///
/// Only what the inputs require runs: the G-buffer when the camera or geometry moved; the RSMs and every
/// technique's per-light work when the lights or geometry changed; a technique's update when one of the
/// inputs it declares changed; the shading when anything did. A skipped stage's results are the last run's,
/// which equal what it would compute again.
#include <array>
#include <cmath>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "gl/objects.h"
#include "gl/profiler.h"
#include "gl/program.h"
#include "lighting/ambient.h"
#include "lighting/frame/frame.h"
#include "lighting/scene_file.h"
#include "lighting/techniques/registry.h"
#include "lighting/techniques/technique.h"
#include "lighting/terms_history.h"

namespace mrgi::lighting {

struct PipelineConfig {
  PipelineConfig();
  int width = 640, height = 480;      ///< G-buffer / output size (camera colour resolution)
  TechniqueChoice technique;          ///< default: the registry's first technique
  KnobSet knobs;                      ///< every group complete (defaults)
  std::optional<Region> fixedRegion;  ///< overrides fitting the region to the virtual objects (tests)
  /// Reports the progress of a technique's long precompute (what, fraction 0..1); may be empty.
  std::function<void(const std::string& what, double fraction)> progress;
  /// A folder where techniques may keep what they precompute between runs (beside a saved room: files of
  /// their own, named by what they were computed from); empty: nothing is kept.
  std::string cacheDir;
  /// The frame group's and the technique's knob values, set by name ("lpv", "resolution"); throws
  /// std::invalid_argument for an unknown group or knob, or a value out of its declared range.
  PipelineConfig& set(const std::string& group, const std::string& knob, double value);
};

/// The config a scene asks for at an output size.
PipelineConfig pipelineConfig(const SceneDescription& scene, int width, int height);

/// The GPU memory a pipeline of this config will hold for `lights` lights (frame resources, techniques,
/// shading targets), bytes, estimated before anything is allocated.
size_t estimateGpuBytes(const PipelineConfig& config, size_t lights);

class LightingPipeline {
 public:
  /// Needs a current GL 4.5 context.
  LightingPipeline(const PipelineConfig& config, const std::vector<VirtualObject>& objects);

  /// The real mesh in the lighting world (empty = no real geometry). Every call counts as a change.
  void setRealMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices) {
    frame_->setRealMesh(std::move(vertices), std::move(indices));
  }
  /// The real surface as the camera sees it now, as a mesh for the footprint (FrameResources::setViewMesh).
  void setViewMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices) {
    frame_->setViewMesh(std::move(vertices), std::move(indices));
  }
  /// The real surface per camera pixel, camera frame, for the G-buffer (FrameResources::setViewSurface).
  void setViewSurface(const cv::Mat& positions, const cv::Mat& normals, int stride,
                      float maxRelativeJump = reconstruction::kDepthMeshMaxRelativeJump) {
    frame_->setViewSurface(positions, normals, stride, maxRelativeJump);
  }
  /// The real surfaces' albedo per camera pixel for the G-buffer, and which of each pixel's camera channels are
  /// clipped (FrameResources::setRealPixelAlbedo).
  void setRealPixelAlbedo(const cv::Mat& albedo, const cv::Mat& clipped = cv::Mat()) {
    frame_->setRealPixelAlbedo(albedo, clipped);
  }
  /// The camera's white in scene radiance (1 / exposure) for the frames that follow: where a real pixel's channel
  /// is clipped, the objects' delta is taken from the lights' prediction above it (lighting/clipped_real.glsl).
  /// 0 (the default): none taken.
  void setCameraWhite(double white) { cameraWhite_ = std::isfinite(white) && white > 0 ? white : 0.0; }
  /// Where object i sits in the lighting world.
  void setObjectTransform(size_t i, const cv::Matx44d& T_world_object) {
    frame_->setObjectTransform(i, T_world_object);
  }
  /// The ambient's directional part for the next runs: radiance as SH bands 0-2 (index l(l+1)+m, the basis
  /// of reconstruction::shBasis2), lighting world; the virtual object gets its clamped-cosine irradiance
  /// on top of the uniform ambient. Zero (the default) adds nothing. A change reruns the shading pass.
  void setAmbientSh(const std::array<cv::Vec3d, 9>& sh) {
    if (sh == ambientSh_) return;
    ambientSh_ = sh;
    frame_->setAmbientSh(sh);
    shadeAt_.reset();
  }
  /// The ambient (uniform and SH) over every direction as a lat-long map seen from the objects (a room's remainder
  /// after its lights), for what the objects hide of it (Ambient::map) while no hidden ambient is set; null: the
  /// SH alone. A change reruns the shading pass.
  void setAmbientMap(std::shared_ptr<const RadianceMap> map) {
    if (map == ambientMap_) return;
    ambientMap_ = std::move(map);
    ++hiddenSerial_;
    shadeAt_.reset();
  }
  /// Whether the ambient (uniform and SH) is an environment seen at the virtual objects — the room's fused
  /// radiance or a fisheye image — which already holds the light real surfaces bounce onto them. Then the
  /// shading pass does not add the virtual-role technique's bounce again, and a technique that serves only
  /// the virtual role is not run (nor builds its own inputs). Off by default (listed lights and ambient).
  void setEnvironment(bool holdsRealBounce) {
    if (holdsRealBounce == environment_) return;
    environment_ = holdsRealBounce;
    shadeAt_.reset();
    for (auto& at : techniqueAt_) at.reset();
  }
  bool environment() const { return environment_; }
  /// What the objects hide from the real surfaces around them, for the shading pass's shadow of the ambient
  /// (lighting/object_shadow.h): radiance, lighting world. nullopt (the default): the ambient itself. A room
  /// lit by listed lights hands its surfaces seen from the objects, whose light the listed ambient only stands
  /// in for, with their radiance map (Ambient::map: what each object hides across its cap). A change reruns the
  /// shading pass.
  void setHiddenAmbient(const std::optional<Ambient>& hidden) {
    const auto same = [](const std::optional<Ambient>& a, const std::optional<Ambient>& b) {
      return a.has_value() == b.has_value() && (!a || (a->uniform == b->uniform && a->sh == b->sh && a->map == b->map));
    };
    if (same(hidden, hiddenAmbient_)) return;
    hiddenAmbient_ = hidden;
    ++hiddenSerial_;
    shadeAt_.reset();
  }
  /// The builders of the techniques' own inputs from a frame or a room (lighting/frame/technique_input.h): the
  /// technique's name and its builder, for each technique in use that has one.
  std::vector<std::pair<std::string, std::unique_ptr<TechniqueInputBuilder>>> inputBuilders() const;
  /// A technique's own input (built by its builder) for the next runs.
  void setTechniqueInput(const std::string& technique, std::shared_ptr<const TechniqueInput> input) {
    frame_->setTechniqueInput(technique, std::move(input));
  }

  /// Renders what changed and shades every pixel. Stages timed on profiler ("gbuffer", "rsm", the
  /// techniques' own stages, "shade"). lights: at most kMaxLights.
  void run(const CameraView& camera, const std::vector<SceneLight>& lights, const cv::Vec3d& ambientRadiance,
           gl::Profiler* profiler);
  /// Stages the last run skipped because their inputs had not changed: of "gbuffer", "rsm", each
  /// technique's name (its update), "shade".
  const std::vector<std::string>& skippedStages() const { return skipped_; }
  /// Whether the shading pass runs its whole program only over objectsFootprint (default) or over every pixel
  /// (the same image, for comparison).
  void setBoundedShading(bool bounded) { boundedShading_ = bounded; }
  /// The pixels the last run's shading pass ran its whole program over (lighting/shadow_footprint.h): the
  /// whole image, or the objects and their direct shadow.
  const cv::Rect& shadedFootprint() const { return footprint_; }
  /// Indices (into the last run's lights) of the lights it rendered: those that matter at the objects'
  /// region (lightsThatMatter, frame knob light_cutoff); every light when no object is placed.
  const std::vector<size_t>& lightsRendered() const { return lightsKept_; }
  /// The next run computes every stage.
  void invalidate();

  /// RGBA32F: rgb = delta (real) or radiance (virtual), a = 1 on virtual pixels (compositor input).
  const gl::Texture& shade() const { return shade_; }
  /// GPU memory of the textures this pipeline and its techniques hold, bytes; meshes and small buffers not counted.
  size_t gpuBytes() const;
  /// CV_32FC4 downloads of the shading result and of its debug irradiance (E_delta / E_indirect, W/m^2).
  cv::Mat downloadShade() const;
  cv::Mat downloadIrradiance() const;
  /// The object terms of the last run on the reduced grid (CV_32FC4, rgb W/m^2, a = 1 where computed; empty
  /// when the shading pass computed them per pixel), and with object_terms_history the points (xyz, w = 1)
  /// and normals they were computed at.
  cv::Mat downloadObjectTerms(int channel = 0) const;
  /// G-buffer channels (CV_32FC4): 0 position, 1 normal, 2 albedo (a = virtual).
  cv::Mat downloadGBuffer(int channel) const { return frame_->downloadGBuffer(channel); }
  /// The last light's RSMs (rho = real + virtual, mu = real only).
  RsmTexels downloadRsm(bool rho) const { return frame_->downloadRsm(rho); }
  const FrameResources& frame() const { return *frame_; }
  /// The region of the last run (nullopt when no object was placed and no fixed region is set).
  const std::optional<Region>& region() const { return frame_->region(); }

  const TechniqueChoice& choice() const { return config_.technique; }
  /// The technique instances (one per distinct technique of the choice).
  const std::vector<std::unique_ptr<Technique>>& techniques() const { return techniques_; }
  /// The instance serving a role, or nullptr ("none").
  Technique* techniqueFor(Role role) const;
  /// The instance of a technique by registry name, or nullptr.
  Technique* technique(const std::string& name) const;
  /// Per technique (by name) its stats, for those that ran in the last run.
  nlohmann::json stats() const;

 private:
  PipelineConfig config_;
  std::unique_ptr<FrameResources> frame_;
  std::vector<std::unique_ptr<Technique>> techniques_;
  Technique* real_ = nullptr;
  Technique* virtual_ = nullptr;
  /// The shading pass's variants, compiled when first used: bit 0 soft shadows, bit 1 upsampling of reduced
  /// technique outputs, bit 2 the object terms from the reduced pass (code a pass does not run still costs
  /// llvmpipe: each only where it is needed).
  std::array<gl::Program, 32> shadePrograms_;  ///< soft | upsample | reduced terms | real only | shared upsample
  gl::Program unlitProgram_;                   ///< the pass with no virtual object (shade.frag SHADE_UNLIT)
  bool boundedShading_ = true;
  double cameraWhite_ = 0;  ///< setCameraWhite's
  cv::Rect footprint_;
  /// The object terms at the reduced view (lighting/object_terms.frag), bit 0 the soft-shadow variant, bit 1
  /// the one carrying the terms over frames (object_terms_history); their targets (terms, points, normals),
  /// allocated at the reduced view's size when first used, two of each with the history (this run's and the
  /// last one's, alternately).
  std::array<gl::Program, 4> objectTermsPrograms_;
  std::array<gl::Texture, 2> objectTerms_, termsPosition_, termsNormal_;
  std::array<gl::Framebuffer, 2> objectTermsFb_;
  int termsCurrent_ = 0;  ///< which of the two holds the last run's terms
  /// The last run's camera and what its terms depended on besides the camera, when the history may carry over.
  std::optional<HistoryCamera> termsCamera_;
  std::vector<double> termsInputs_;
  gl::Texture shade_, irradiance_;
  gl::Framebuffer shadeFb_;
  gl::VertexArray emptyVao_;
  /// What each consumer last computed from.
  std::optional<FrameVersions> gbufferAt_, lightsAt_, shadeAt_;
  std::array<cv::Vec3d, 9> ambientSh_{};
  bool environment_ = false;
  std::optional<Ambient> hiddenAmbient_;
  std::shared_ptr<const RadianceMap> ambientMap_;
  /// Counts the hidden ambients and ambient maps set (the object terms' history carries over within one).
  unsigned hiddenSerial_ = 0;
  /// hiddenAmbient_'s map on the GPU (uHiddenMap) and the map it holds.
  gl::Texture hiddenMap_;
  std::shared_ptr<const RadianceMap> hiddenMapSource_;
  /// A technique with nothing to do: it serves only the virtual role and the environment holds its bounce.
  bool idle(const Technique& t) const;
  std::vector<std::optional<FrameVersions>> techniqueAt_;
  std::vector<std::string> skipped_;
  std::vector<size_t> lightsKept_;
};

}  // namespace mrgi::lighting
