#pragma once
/// One frame's shared lighting resources, owned once and read by every technique: the inputs of a run and the
/// versions that say what changed, and the passes that render from them (lighting/frame/passes.h): the camera's
/// G-buffer (real mesh + virtual objects, explicit mask, depth test both ways), the virtual objects, the real
/// scene (mesh, real-surface area lights), the lights with their light views fitted to the region that
/// matters, per light RSM^rho (real + virtual) and RSM^mu (real only), the shadow maps, and version counters
/// that say what changed. Everything lives in the lighting world (for replay: the marker frame), metres,
/// linear RGB. Techniques (lighting/techniques/) declare which versions their results depend on; the
/// pipeline (lighting/pipeline.h) reruns a consumer only when one of them moved.
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/checks.h"
#include "capture/types.h"
#include "gl/objects.h"
#include "gl/profiler.h"
#include "gl/program.h"
#include "lighting/frame/passes.h"
#include "lighting/frame/technique_input.h"
#include "lighting/knobs.h"
#include "lighting/object_shadow.h"
#include "lighting/scene.h"
#include "reconstruction/depth_filter.h"

namespace mrgi::lighting {

constexpr int kMaxLights = capture::kMaxLightCount;

/// Knobs of the shared resources (scene key "frame").
struct FrameKnobs {
  int rsmSize = 0;        ///< RSM texels per side
  int shadowSize = 0;     ///< texels per side of the objects' shadow maps
  double sizeFactor = 0;  ///< region side / the objects' largest bounding-box edge
  double lightCutoff =
      0;  ///< share of the irradiance bound at the region the skipped lights may carry (lightsThatMatter)
  int softShadowLights = 0;  ///< how many lights with extent (the brightest at the region) cast soft shadows
  double renderScale = 1;    ///< resolution of per-pixel technique outputs, of the frame's (lighting/upsample.h)
  /// resolution of the shading pass's object terms on real surfaces while renderScale is 1 (else renderScale's)
  double objectTermsScale = 0.5;
  /// weight of the previous frame's object terms where its surface is the texel's (lighting/terms_history.h)
  double objectTermsHistory = 0;
};
/// The divisor of the frame's resolution the shading pass's object terms are computed at: render_scale's when
/// it reduces the techniques' outputs, else object_terms_scale's (lighting/upsample.h renderFactor).
int objectTermsFactor(const FrameKnobs& knobs);
/// The knob table of FrameKnobs (declared once: lighting/frame/frame.cpp).
const std::vector<KnobBinding<FrameKnobs>>& frameKnobTable();
const KnobGroup& frameKnobGroup();

struct FrameConfig {
  int width = 640, height = 480;  ///< G-buffer / output size (camera colour resolution)
  FrameKnobs knobs = knobsFrom(frameKnobTable(), {});
  std::optional<Region> fixedRegion;  ///< overrides fitting the region to the virtual objects (tests)
};

/// Which inputs changed: counters bumped on every change, compared by consumers.
struct FrameVersions {
  uint64_t camera = 0, geometry = 0, lights = 0, ambient = 0, own = 0;
};

/// Inputs a consumer's results depend on (bit set).
enum FrameInput : unsigned {
  kInputCamera = 1u,    ///< intrinsics, pose, clip planes (the G-buffer)
  kInputGeometry = 2u,  ///< real mesh and object placements (G-buffer, RSMs, region)
  kInputLights = 4u,    ///< the lights (RSMs, shadow maps)
  kInputAmbient = 8u,   ///< the ambient radiance
  kInputOwn = 16u,      ///< the techniques' own inputs from the frame (technique_input.h)
};

class FrameResources {
 public:
  /// Needs a current GL 4.5 context.
  FrameResources(const FrameConfig& config, const std::vector<VirtualObject>& objects);

  const FrameConfig& config() const { return config_; }
  int width() const { return config_.width; }
  int height() const { return config_.height; }
  int rsmSize() const { return config_.knobs.rsmSize; }

  // ---- inputs (set by the pipeline before a run)
  /// The real mesh (lighting world); kept on the CPU too (realVertices()): pass temporaries to move them.
  void setRealMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices);
  /// The real surface as the camera sees it now (the frame's depth) as a mesh, lighting world: what the shading
  /// pass's footprint asks of the surface the camera sees (cameraVertices) when the real mesh is another (a
  /// fused room model, which still casts the shadows and fills the RSMs). Empty: the real mesh.
  void setViewMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices);
  /// The same surface per camera pixel (positions and normals in the camera frame, CV_32FC3 at the frame's
  /// size; FrameGeometry::setViewSurface), which the G-buffer draws, with setRealPixelAlbedo's albedo, instead
  /// of rasterising the view mesh or the real mesh. Empty: none. A change counts as a camera change.
  void setViewSurface(const cv::Mat& positions, const cv::Mat& normals, int stride,
                      float maxRelativeJump = reconstruction::kDepthMeshMaxRelativeJump);
  /// The real surfaces' albedo per camera pixel (CV_32FC3 linear, the G-buffer's size; a negative value:
  /// none at that pixel), which the G-buffer takes instead of the vertices' interpolated albedo: a mesh over
  /// every other depth pixel blurs a texture (a tag's cells) that the camera sees sharp, and a shadow drawn
  /// over it with it. Empty (or another size): the vertices'. A change counts as a camera change.
  /// `clipped`: each pixel's clipped camera channels (GBufferPass::setPixelAlbedo).
  void setRealPixelAlbedo(const cv::Mat& albedo, const cv::Mat& clipped = cv::Mat());
  void setObjectTransform(size_t i, const cv::Matx44d& T_world_object);
  /// The ambient's directional part (radiance as SH bands 0-2, lighting world; LightingPipeline::setAmbientSh);
  /// a change counts as an ambient change at the next update().
  void setAmbientSh(const std::array<cv::Vec3d, 9>& sh) { ambientSh_ = sh; }
  /// A technique's own input (technique_input.h) for the next run; a change counts as a kInputOwn change.
  void setTechniqueInput(const std::string& technique, std::shared_ptr<const TechniqueInput> input);
  /// Compares with the last run's inputs and bumps the versions of what changed. Returns the versions.
  const FrameVersions& update(const CameraView& camera, const std::vector<SceneLight>& lights,
                              const cv::Vec3d& ambient);
  /// Everything counts as changed at the next update().
  void invalidate();

  const FrameVersions& versions() const { return versions_; }
  const CameraView& camera() const { return camera_; }
  const std::vector<SceneLight>& lights() const { return lights_; }
  const cv::Vec3d& ambient() const { return ambient_; }
  const std::array<cv::Vec3d, 9>& ambientSh() const { return ambientSh_; }
  /// The real mesh as last set (CPU copy, lighting world).
  const std::vector<MeshVertex>& realVertices() const { return geometry_.realVertices(); }
  const std::vector<uint32_t>& realIndices() const { return geometry_.realIndices(); }
  /// The mesh the camera sees (the G-buffer's): the view mesh when set, else the real mesh (CPU copies).
  const std::vector<MeshVertex>& cameraVertices() const { return geometry_.cameraVertices(); }
  const std::vector<uint32_t>& cameraIndices() const { return geometry_.cameraIndices(); }
  const std::vector<FrameObject>& objects() const { return geometry_.objects(); }
  /// The technique's own input as last set, nullptr when none.
  const TechniqueInput* techniqueInput(const std::string& technique) const;
  /// World bounding box of the placed objects (nullopt without objects).
  std::optional<std::pair<cv::Vec3d, cv::Vec3d>> objectBounds() const { return geometry_.objectBounds(); }
  /// The region of the last run (nullopt when no object was placed and no fixed region is set).
  const std::optional<Region>& region() const { return region_; }

  // ---- stages (run by the pipeline)
  void fitRegionToObjects();
  void renderGBuffer();
  /// Light i's view, RSMs (rho, mu) and the objects' shadow map; their positions go into the shadow arrays.
  void renderLight(size_t i);
  void clearLightViews() { lightPass_.clear(); }

  /// Draws the real mesh (and the objects when includeVirtual) with `program` (uModel, uNormalModel,
  /// uViewProj, uVirtual, uObject set here).
  void drawScene(const gl::Program& program, bool includeVirtual, const cv::Matx44d& viewProj) const {
    geometry_.drawScene(program, includeVirtual, viewProj);
  }
  /// Draws the objects alone (uModel, uNormalModel, uVirtual = 1, uObject set here; uViewProj by the caller).
  void drawObjects(const gl::Program& program) const { geometry_.drawObjects(program); }

  // ---- results
  const gl::Texture& gPosition() const { return gbuffer_.position(); }  ///< xyz world, w = 1 where a surface was seen
  /// xyz unit normal towards the camera, w = object index + 1 (0 real)
  const gl::Texture& gNormal() const { return gbuffer_.normal(); }
  const gl::Texture& gAlbedo() const { return gbuffer_.albedo(); }  ///< rgb albedo, a = 1 on virtual surfaces
  const gl::Texture& gDepth() const { return gbuffer_.depth(); }
  /// The G-buffer a technique renders its per-pixel outputs at: the frame's own, or at render_scale its copy at
  /// 1/factor (lighting/upsample.h), whose outputs the shading pass upsamples joint-bilaterally. Current after
  /// renderGBuffer().
  GBufferView techniqueView() const { return gbuffer_.reducedView(); }
  /// The G-buffer the shading pass computes the objects' terms on real surfaces at (lighting/object_terms.frag):
  /// techniqueView() when render_scale reduces it, else the frame's at object_terms_scale. Current after
  /// renderGBuffer().
  GBufferView objectTermsView() const { return gbuffer_.termsView(); }
  /// The G-buffer at the frame's size, as a view.
  GBufferView gbufferView() const { return gbuffer_.view(); }
  /// Light views of the lights rendered so far this run (all of them after the RSM stage).
  const std::vector<LightView>& lightViews() const { return lightPass_.views(); }
  /// The RSMs of the light rendered last.
  const Rsm& rsmRho() const { return lightPass_.rsmRho(); }
  const Rsm& rsmMu() const { return lightPass_.rsmMu(); }
  RsmTexels downloadRsm(bool rho) const { return lightPass_.downloadRsm(rho); }
  /// Per light: RSM^rho / RSM^mu world positions (layer = light index; allocated for the lights of the run).
  const gl::Texture& shadowRho() const { return lightPass_.shadowRho(); }
  const gl::Texture& shadowMu() const { return lightPass_.shadowMu(); }
  /// Per light: the objects' world positions in their own view (LightView::objectViewProj).
  const gl::Texture& shadowObjects() const { return lightPass_.shadowObjects(); }
  /// Light i's layers of the three shadow arrays (lights of the last run).
  ShadowTexels downloadShadowTexels(size_t i) const { return lightPass_.downloadShadowTexels(i); }
  /// Binds the three shadow arrays where lighting/direct_light.glsl reads them (units 12, 13, 14).
  void bindShadowMaps() const { lightPass_.bindShadowMaps(); }
  /// A zeroed RGBA32F texture of the output size (stands in for an output no technique provides).
  const gl::Texture& zero();
  /// CV_32FC4 G-buffer channel: 0 position, 1 normal, 2 albedo (a = virtual); `reduced`: the reduced copy's
  /// (objectTermsView(), which is techniqueView() when render_scale reduces it).
  cv::Mat downloadGBuffer(int channel, bool reduced = false) const;
  size_t gpuBytes() const;
  /// What these resources will hold on the GPU for `lights` lights, bytes (before allocating any).
  static size_t estimateBytes(const FrameConfig& config, size_t lights);

 private:
  FrameConfig config_;
  FrameGeometry geometry_;
  GBufferPass gbuffer_;
  LightPass lightPass_;
  std::vector<bool> soft_;  ///< per light: its objects' shadow is soft (renderLight)
  bool viewDirty_ = false;
  std::map<std::string, std::shared_ptr<const TechniqueInput>> techniqueInputs_;
  std::optional<Region> region_;
  CameraView camera_;
  std::vector<SceneLight> lights_;
  cv::Vec3d ambient_{0, 0, 0};
  std::array<cv::Vec3d, 9> ambientSh_{};
  FrameVersions versions_;
  struct Seen {
    std::vector<double> camera, objects, lights, ambient;
  };
  std::optional<Seen> seen_;
  bool geometryDirty_ = true, ownDirty_ = true;
  gl::Texture zero_;
};

/// The uniforms of lighting/direct_light.glsl (uLightCount, uLightType[i], ...) for `lights` seen through
/// `views` (a light without a view: nothing occludes it).
void setLightUniforms(const gl::Program& p, const std::vector<SceneLight>& lights, const std::vector<LightView>& views);

/// The objects' glossy lobes for a shader declaring `uniform float uSpecular[16], uExponent[16]` (its
/// MAX_OBJECTS): object k's material specular and Phong exponent, 0 beyond the frame's objects.
constexpr int kShaderMaxObjects = 16;
void setObjectLobes(const gl::Program& p, const FrameResources& frame);
/// The frame's ambient (uniform radiance and its SH part) as a pass's uAmbient and uAmbientSh[9].
void setAmbientUniforms(const gl::Program& p, const FrameResources& frame);

}  // namespace mrgi::lighting
