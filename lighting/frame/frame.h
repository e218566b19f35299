#pragma once
/// One frame's shared lighting resources, owned once and read by every technique: the camera and its
/// G-buffer (real mesh + virtual objects, explicit mask, depth test both ways), the virtual objects, the real
/// scene (mesh, real-surface area lights), the lights with their light views fitted to the region that
/// matters, per light RSM^rho (real + virtual) and RSM^mu (real only), the shadow maps, and version counters
/// that say what changed. Everything lives in the lighting world (for replay: the marker frame), metres,
/// linear RGB. Techniques (lighting/techniques/) declare which versions their results depend on; the
/// pipeline (lighting/pipeline.h) reruns a consumer only when one of them moved.
#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "capture/checks.h"
#include "capture/types.h"
#include "gl/objects.h"
#include "gl/profiler.h"
#include "gl/program.h"
#include "lighting/frame/technique_input.h"
#include "lighting/knobs.h"
#include "lighting/object_shadow.h"
#include "lighting/scene.h"
#include "reconstruction/depth_filter.h"

namespace mrgi::lighting {

constexpr int kMaxLights = capture::kMaxLightCount;

/// Interleaved vertex of every mesh the pipeline draws.
struct MeshVertex {
  cv::Vec3f position;  ///< model frame, metres
  cv::Vec3f normal;    ///< unit
  cv::Vec3f albedo;    ///< linear RGB
};

/// A mesh on the GPU (immutable; rebuilt when its vertices change).
class GpuMesh {
 public:
  GpuMesh() = default;
  GpuMesh(const std::vector<MeshVertex>& vertices, const std::vector<uint32_t>& indices);
  void draw() const;
  bool empty() const { return count_ == 0; }

 private:
  gl::Buffer vertices_, indices_;
  gl::VertexArray vao_;
  GLsizei count_ = 0;
};

/// The real-scene mesh in the lighting world: DepthMesh vertices (camera frame) moved by T_world_camera,
/// each with the albedo estimated at its pixel (albedo CV_32FC3, linear; empty = 0.5 grey).
void buildRealVertices(const reconstruction::DepthMesh& mesh, const cv::Mat& albedo,
                       const capture::Pose& T_world_camera, std::vector<MeshVertex>& vertices,
                       std::vector<uint32_t>& indices);

/// Appends the parallelogram p0 + s e1 + t e2 (s, t in [0, 1]) as an n x n grid of triangle pairs facing
/// e1 x e2, of one albedo (test and benchmark scenes: a floor, a wall).
void appendGridQuad(std::vector<MeshVertex>& vertices, std::vector<uint32_t>& indices, const cv::Vec3f& p0,
                    const cv::Vec3f& e1, const cv::Vec3f& e2, const cv::Vec3f& albedo, int n = 8);

/// Camera matrices (OpenCV camera frame: x right, y down, z forward). Image row 0 maps to NDC y = -1, so
/// framebuffer rows come back in cv::Mat order.
cv::Matx44d projectionFromIntrinsics(const capture::Intrinsics& k, double nearPlane, double farPlane);
cv::Matx44d orthographicProjection(double halfExtent, double nearPlane, double farPlane);
std::array<float, 16> toGl(const cv::Matx44d& m);
/// Inverse transpose of T's rotation part (normals).
cv::Matx33f normalMatrix(const cv::Matx44d& T);
void setMat3(const gl::Program& p, const std::string& name, const cv::Matx33f& m);
void setVec3(const gl::Program& p, const std::string& name, const cv::Vec3d& v);
/// uLightType of the shaders: 0 point, 1 spot, 2 directional.
int shaderLightType(LightType t);
/// A timed stage when there is a profiler (GPU timer queries too when `gpu`).
std::optional<gl::Profiler::Scope> timed(gl::Profiler* profiler, const char* name, bool gpu = true);

/// The region that matters for the virtual objects: an axis-aligned cube in the lighting world, centred on
/// the objects' bounding box, side = size factor x its largest edge (never below 1 mm). Light views are
/// fitted to it; volume techniques place their grids in it.
struct Region {
  cv::Vec3d origin{0, 0, 0};  ///< the corner with the smallest coordinates
  double side = 1.0;
  cv::Vec3d centre() const { return origin + cv::Vec3d::all(0.5 * side); }
  /// Radius of the bounding sphere.
  double radius() const { return 0.5 * std::sqrt(3.0) * side; }
};
Region fitRegion(const cv::Vec3d& lo, const cv::Vec3d& hi, double sizeFactor);

/// The most unshadowed irradiance `light` can give a point of the region's bounding sphere, whatever the
/// point's normal (W/m^2 per channel): a directional light's irradiance; a point light's intensity over the
/// squared distance to the sphere's nearest point; a spot's the same, or exactly 0 when its cone misses the
/// sphere. Infinite for a point or spot light inside the sphere. Bounds the light's share of everything the
/// objects change: their direct light, the shadow they cast (its receivers lie behind them from the light),
/// what they bounce.
cv::Vec3d irradianceBound(const SceneLight& light, const Region& region);
/// The lights worth rendering for the region, by index in `lights` (in order): the dimmest lights (by
/// irradianceBound, ascending) are left out for as long as, in every channel, the bounds of those left out
/// sum to at most `cutoff` of the sum over all lights with a finite bound plus the ambient's irradiance
/// (pi x ambient radiance). cutoff 0: every light. A light with an infinite bound is always kept.
std::vector<size_t> lightsThatMatter(const std::vector<SceneLight>& lights, const cv::Vec3d& ambientRadiance,
                                     const Region& region, double cutoff);

/// How one light sees the region: perspective for point/spot lights (frustum around the region's bounding
/// sphere), orthographic for directional ones (fitted to the region).
struct LightView {
  cv::Matx44d viewProj;
  double focalPixels = 0;  ///< perspective
  double texelArea = 0;    ///< orthographic, m^2
  double shadowBias = 0;   ///< metres
  /// The objects' shadow map: the same light fitted to the objects' bounding sphere (holding them alone).
  /// objectShadowBias < 0: none (a point light too close to the objects for one view; RSM^rho tests them).
  cv::Matx44d objectViewProj = cv::Matx44d::eye();
  double objectShadowBias = -1;  ///< metres
};
LightView fitLightView(const SceneLight& light, const Region& region, int rsmSize);
/// Adds the objects' view to `view`: orthographic over the sphere (centre, radius) for a directional light,
/// a perspective frustum around it for a point or spot light (none when the light is within 1.05 radii).
void fitObjectView(LightView& view, const SceneLight& light, const cv::Vec3d& centre, double radius, int size);

struct CameraView {
  capture::Intrinsics intrinsics;
  capture::Pose T_world_camera;
  double nearPlane = 0.05, farPlane = 20.0;
};

/// RSM texels as read back from the GPU (CV_32FC4 each, size x size): world position (w = 1 where a surface
/// was seen), normal facing the light (w = object index + 1 on virtual surfaces, 0 on real ones), reflected flux
/// (albedo x flux through the texel, W), incident flux through the texel (W).
struct RsmTexels {
  cv::Mat position, normal, flux, direct;
};

/// One light's shadow maps as downloaded (CV_32FC4 world positions, w = 1 where a surface was seen):
/// RSM^mu, and either the objects' map or, where the light's view has none, RSM^rho (the other empty).
struct ShadowTexels {
  cv::Mat rho, mu, objects;
};

/// The GPU textures of one reflective shadow map (RGBA32F, size x size, nearest filtering).
struct Rsm {
  gl::Texture position, normal, flux, direct, depth;
  gl::Framebuffer fb;
};

/// Knobs of the shared resources (scene key "frame").
struct FrameKnobs {
  int rsmSize = 0;        ///< RSM texels per side
  int shadowSize = 0;     ///< texels per side of the objects' shadow maps
  double sizeFactor = 0;  ///< region side / the objects' largest bounding-box edge
  double lightCutoff =
      0;  ///< share of the irradiance bound at the region the skipped lights may carry (lightsThatMatter)
};
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

/// A virtual object as the frame holds it: its mesh in model space (also on the GPU), material, placement.
struct FrameObject {
  VirtualObject source;  ///< mesh (model space, scaled) and material (a copy)
  GpuMesh gpu;
  OccluderSphere sphere;  ///< the sphere it stands as for the shadow of the ambient, model space (object_shadow.h)
  cv::Matx44d T_world_object = cv::Matx44d::eye();
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
  /// The real surface as the camera sees it now (the frame's depth), drawn into the G-buffer instead of
  /// the real mesh, which still casts the shadows and fills the RSMs (a fused room model). Sharper where
  /// real surfaces occlude virtual ones. Empty: the real mesh everywhere. A change counts as a camera change.
  void setViewMesh(const std::vector<MeshVertex>& vertices, const std::vector<uint32_t>& indices);
  /// The real surfaces' albedo per camera pixel (CV_32FC3 linear, the G-buffer's size; a negative value:
  /// none at that pixel), which the G-buffer takes instead of the vertices' interpolated albedo: a mesh over
  /// every other depth pixel blurs a texture (a tag's cells) that the camera sees sharp, and a shadow drawn
  /// over it with it. Empty (or another size): the vertices'. A change counts as a camera change.
  void setRealPixelAlbedo(const cv::Mat& albedo);
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
  const std::vector<MeshVertex>& realVertices() const { return realVertices_; }
  const std::vector<uint32_t>& realIndices() const { return realIndices_; }
  const std::vector<FrameObject>& objects() const { return objects_; }
  /// The technique's own input as last set, nullptr when none.
  const TechniqueInput* techniqueInput(const std::string& technique) const;
  /// World bounding box of the placed objects (nullopt without objects).
  std::optional<std::pair<cv::Vec3d, cv::Vec3d>> objectBounds() const;
  /// The region of the last run (nullopt when no object was placed and no fixed region is set).
  const std::optional<Region>& region() const { return region_; }

  // ---- stages (run by the pipeline)
  void fitRegionToObjects();
  void renderGBuffer();
  /// Light i's view, RSMs (rho, mu) and the objects' shadow map; their positions go into the shadow arrays.
  void renderLight(size_t i);
  void clearLightViews() { views_.clear(); }

  /// Draws the real mesh (and the objects when includeVirtual) with `program` (uModel, uNormalModel,
  /// uViewProj, uVirtual, uObject set here).
  void drawScene(const gl::Program& program, bool includeVirtual, const cv::Matx44d& viewProj,
                 bool cameraView = false) const;
  /// Draws the objects alone (uModel, uNormalModel, uVirtual = 1, uObject set here; uViewProj by the caller).
  void drawObjects(const gl::Program& program) const;

  // ---- results
  const gl::Texture& gPosition() const { return gPosition_; }  ///< xyz world, w = 1 where a surface was seen
  const gl::Texture& gNormal() const {
    return gNormal_;
  }  ///< xyz unit normal towards the camera, w = object index + 1 (0 real)
  const gl::Texture& gAlbedo() const { return gAlbedo_; }  ///< rgb albedo, a = 1 on virtual surfaces
  const gl::Texture& gDepth() const { return gDepth_; }
  /// Light views of the lights rendered so far this run (all of them after the RSM stage).
  const std::vector<LightView>& lightViews() const { return views_; }
  /// The RSMs of the light rendered last.
  const Rsm& rsmRho() const { return rsmRho_; }
  const Rsm& rsmMu() const { return rsmMu_; }
  RsmTexels downloadRsm(bool rho) const;
  /// Per light: RSM^rho / RSM^mu world positions (layer = light index; allocated for the lights of the run).
  const gl::Texture& shadowRho() const { return shadowRho_; }
  const gl::Texture& shadowMu() const { return shadowMu_; }
  /// Per light: the objects' world positions in their own view (LightView::objectViewProj).
  const gl::Texture& shadowObjects() const { return shadowObjects_; }
  /// Light i's layers of the three shadow arrays (lights of the last run).
  ShadowTexels downloadShadowTexels(size_t i) const;
  /// Binds the three shadow arrays where lighting/direct_light.glsl reads them (units 12, 13, 14).
  void bindShadowMaps() const;
  /// A zeroed RGBA32F texture of the output size (stands in for an output no technique provides).
  const gl::Texture& zero();
  /// CV_32FC4 G-buffer channel: 0 position, 1 normal, 2 albedo (a = virtual).
  cv::Mat downloadGBuffer(int channel) const;
  size_t gpuBytes() const;
  /// What these resources will hold on the GPU for `lights` lights, bytes (before allocating any).
  static size_t estimateBytes(const FrameConfig& config, size_t lights);

 private:
  Rsm makeRsm(int size) const;
  void renderRsm(Rsm& rsm, const SceneLight& light, const LightView& view, bool includeVirtual);

  FrameConfig config_;
  std::vector<FrameObject> objects_;
  GpuMesh realMesh_, viewMesh_;
  gl::Texture pixelAlbedo_;  ///< setRealPixelAlbedo's, RGB32F
  bool hasPixelAlbedo_ = false;
  bool viewDirty_ = false;
  std::map<std::string, std::shared_ptr<const TechniqueInput>> techniqueInputs_;
  std::optional<Region> region_;
  CameraView camera_;
  std::vector<SceneLight> lights_;
  cv::Vec3d ambient_{0, 0, 0};
  std::array<cv::Vec3d, 9> ambientSh_{};
  std::vector<MeshVertex> realVertices_;
  std::vector<uint32_t> realIndices_;
  FrameVersions versions_;
  struct Seen {
    std::vector<double> camera, objects, lights, ambient;
  };
  std::optional<Seen> seen_;
  bool geometryDirty_ = true, ownDirty_ = true;

  gl::Program gbufferProgram_, rsmProgram_, shadowProgram_;
  gl::Texture objectPosition_, objectDepth_;
  gl::Framebuffer objectFb_;
  gl::Texture gPosition_, gNormal_, gAlbedo_, gDepth_;
  gl::Framebuffer gbufferFb_;
  Rsm rsmRho_, rsmMu_;
  gl::Texture shadowRho_, shadowMu_, shadowObjects_, zero_;
  std::vector<LightView> views_;
};

/// The uniforms of lighting/direct_light.glsl (uLightCount, uLightType[i], ...) for `lights` seen through
/// `views` (a light without a view: nothing occludes it).
void setLightUniforms(const gl::Program& p, const std::vector<SceneLight>& lights, const std::vector<LightView>& views);

/// C++ twin of lighting/direct_light.glsl: one shadow-map test (1 lit, 0 occluded; bias < 0: no map, lit),
/// a light's visibility with or without the objects, and a light's irradiance before shadowing.
float shadowTest(const cv::Mat& positions, const SceneLight& light, const cv::Matx44d& viewProj, double bias,
                 cv::Vec3d x, const cv::Vec3d& n);
float lightVisibility(const ShadowTexels& maps, const SceneLight& light, const LightView& view, bool withObjects,
                      const cv::Vec3d& x, const cv::Vec3d& n);
cv::Vec3d unshadowedIrradiance(const SceneLight& light, const cv::Vec3d& x, const cv::Vec3d& n);

/// CV_32FC4 download of an RGBA32F 2D texture.
cv::Mat download4(const gl::Texture& t);

/// The objects' glossy lobes for a shader declaring `uniform float uSpecular[16], uExponent[16]` (its
/// MAX_OBJECTS): object k's material specular and Phong exponent, 0 beyond the frame's objects.
constexpr int kShaderMaxObjects = 16;
void setObjectLobes(const gl::Program& p, const FrameResources& frame);
/// The frame's ambient (uniform radiance and its SH part) as a pass's uAmbient and uAmbientSh[9].
void setAmbientUniforms(const gl::Program& p, const FrameResources& frame);

}  // namespace mrgi::lighting
