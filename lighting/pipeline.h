#pragma once
/// The per-frame lighting pipeline of `mrgi replay`: G-buffer (real mesh + virtual objects, explicit mask,
/// occlusion both ways) -> per light RSM^rho (real + virtual) and RSM^mu (real only) -> light propagation
/// volumes (DLPV delta injection, or the naive two-volume difference) -> per-pixel shading for the compositor.
/// Everything lives in the lighting world (for replay: the marker frame), metres, linear RGB.
#include <array>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "capture/types.h"
#include "gl/objects.h"
#include "gl/profiler.h"
#include "gl/program.h"
#include "lighting/lpv.h"
#include "lighting/scene_file.h"
#include "lighting/val.h"
#include "lighting/val_gpu.h"
#include "reconstruction/depth_filter.h"

namespace mrgi::lighting {

constexpr int kMaxLights = 16;

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
void buildRealVertices(const reconstruction::DepthMesh& mesh, const cv::Mat& albedo, const capture::Pose& T_world_camera,
                       std::vector<MeshVertex>& vertices, std::vector<uint32_t>& indices);

/// Camera matrices (OpenCV camera frame: x right, y down, z forward). Image row 0 maps to NDC y = -1, so
/// framebuffer rows come back in cv::Mat order.
cv::Matx44d projectionFromIntrinsics(const capture::Intrinsics& k, double nearPlane, double farPlane);
cv::Matx44d orthographicProjection(double halfExtent, double nearPlane, double farPlane);
std::array<float, 16> toGl(const cv::Matx44d& m);

/// How one light sees the volume: perspective for point/spot lights (frustum around the volume's
/// bounding sphere), orthographic for directional ones (fitted to the volume).
struct LightView {
  cv::Matx44d viewProj;
  double focalPixels = 0;  ///< perspective
  double texelArea = 0;    ///< orthographic, m^2
  double shadowBias = 0;   ///< metres
};
LightView fitLightView(const SceneLight& light, const LpvGrid& grid, int rsmSize);

struct PipelineConfig {
  int width = 640, height = 480;  ///< G-buffer / output size (camera colour resolution)
  Technique technique = Technique::Dlpv;
  LpvKnobs lpv;
  ValKnobs val;
  std::optional<LpvGrid> fixedGrid;  ///< overrides fitting the volume to the virtual objects (tests)
};

struct CameraView {
  capture::Intrinsics intrinsics;
  capture::Pose T_world_camera;
  double nearPlane = 0.05, farPlane = 20.0;
};

class LightingPipeline {
 public:
  /// Needs a current GL 4.5 context.
  LightingPipeline(const PipelineConfig& config, const std::vector<VirtualObject>& objects);

  /// The real mesh in the lighting world (empty = no real geometry). Every call counts as a change.
  void setRealMesh(const std::vector<MeshVertex>& vertices, const std::vector<uint32_t>& indices);
  /// Where object i sits in the lighting world.
  void setObjectTransform(size_t i, const cv::Matx44d& T_world_object);
  /// Kinect-VAL: the real-surface VALs (lighting world) of the next runs; the virtual ones come from the RSMs.
  void setRealVals(std::vector<Val> vals) {
    realVals_ = std::move(vals);
    ++realValsVersion_;
  }

  /// What Kinect-VAL did in the last run.
  struct ValStats {
    size_t realVals = 0, virtualVals = 0, receivers = 0;
    size_t shadowedVals = 0;  ///< real VALs dimmed because the object shadows them
    bool bruteForce = false;
  };
  const ValStats& valStats() const { return valStats_; }
  /// The VALs of the last run (real ones dimmed where the object shadows them, then the virtual ones).
  const std::vector<Val>& vals() const { return vals_; }
  /// Per sparse point (objects in order; brute force: per visible virtual pixel) E and S of the last run.
  void downloadValSums(std::vector<cv::Vec3f>& E, std::vector<cv::Vec3f>& S) const;
  /// The sparse points' VPL pairs of the last run (objects in order), after occlusion.
  std::vector<SparseVpl> downloadSparseVpls() const { return valGpu_ ? valGpu_->downloadVpls() : std::vector<SparseVpl>(); }
  /// Object i's sparse points (model frame).
  const SparsePoints& sparsePoints(size_t i) const { return valObjects_.at(i).points; }

  /// Renders the G-buffer, RSMs and volumes and shades every pixel. Stages timed on profiler
  /// ("gbuffer", "rsm", "lpv.inject", "lpv.propagate", "shade"). lights: at most kMaxLights.
  /// Only what the inputs require runs: the G-buffer when the camera, the real mesh or an object moved;
  /// RSMs and volumes when the lights, the real mesh or an object changed; Kinect-VAL when those, the real
  /// VALs, the camera or the ambient changed; the shading when anything did. The results of a skipped
  /// stage are the last run's, which equal what it would compute again.
  void run(const CameraView& camera, const std::vector<SceneLight>& lights, const cv::Vec3d& ambientRadiance,
           gl::Profiler* profiler);
  /// Stages the last run skipped because their inputs had not changed: of "gbuffer", "rsm", "lpv", "val",
  /// "shade".
  const std::vector<std::string>& skippedStages() const { return skipped_; }
  /// The next run computes every stage.
  void invalidate() { cache_.reset(); }

  /// RGBA32F: rgb = delta (real) or radiance (virtual), a = 1 on virtual pixels (compositor input).
  const gl::Texture& shade() const { return shade_; }
  /// GPU memory of the textures this pipeline holds (G-buffer, RSMs, shadow arrays, volumes, Kinect-VAL
  /// targets), bytes; meshes and small buffers not counted.
  size_t gpuBytes() const;
  /// CV_32FC4 downloads of the shading result and of its debug irradiance (E_delta / E_indirect, W/m^2).
  cv::Mat downloadShade() const;
  cv::Mat downloadIrradiance() const;
  /// G-buffer channels (CV_32FC4): 0 position, 1 normal, 2 albedo (a = virtual).
  cv::Mat downloadGBuffer(int channel) const;
  /// The grid of the last run (nullopt when no virtual object was placed and no fixed grid is set).
  const std::optional<LpvGrid>& grid() const { return grid_; }
  /// Accumulated volumes of the last run: "delta", "rho" (indirect, lights the virtual object), and for
  /// lpv-diff "rho_full", "mu_full"; before propagation, the injected direct lobes "delta_direct",
  /// "rho_direct", "mu_direct".
  LpvVolumeCpu downloadVolume(const std::string& name) const;
  /// The last light's RSMs (rho = real + virtual, mu = real only).
  RsmTexels downloadRsm(bool rho) const;

 private:
  struct Volume {
    gl::Texture r, g, b;
    gl::Framebuffer fb;
  };
  struct Rsm {
    gl::Texture position, normal, flux, direct, depth;
    gl::Framebuffer fb;
  };
  Volume makeVolume(int res) const;
  Rsm makeRsm(int size) const;
  void drawScene(const gl::Program& program, bool includeVirtual, const cv::Matx44d& viewProj) const;
  void renderRsm(Rsm& rsm, const SceneLight& light, const LightView& view, bool includeVirtual);
  void runVal(const CameraView& camera, const cv::Vec3d& ambientRadiance, gl::Profiler* profiler);
  size_t shadowRealVals(std::vector<Val>& vals, const cv::Vec3d& ambientRadiance) const;
  void valBruteForce(const CameraView& camera, gl::Profiler* profiler);
  void inject(Volume& target, const Rsm& source, const Rsm* other, float sign, unsigned mode, const SceneLight& light);
  void propagate(Volume& volume, bool clampNegative, const Volume* late);
  void add(const Volume& src, Volume& dst);
  const Volume* volume(const std::string& name) const;

  PipelineConfig config_;
  std::vector<GpuMesh> objectMeshes_;
  std::vector<cv::Matx44d> objectTransforms_;
  std::vector<cv::Vec3f> objectBoundsMin_, objectBoundsMax_;
  GpuMesh realMesh_;
  std::optional<LpvGrid> grid_;

  gl::Program gbufferProgram_, rsmProgram_, injectProgram_, propagateProgram_, addProgram_, shadeProgram_;
  gl::Texture gPosition_, gNormal_, gAlbedo_, gDepth_, shade_, irradiance_;
  gl::Framebuffer gbufferFb_, shadeFb_;
  gl::Texture shadowArray_;
  Rsm rsmRho_, rsmMu_;
  int volumeRes_ = 0;
  Volume delta_, rho_, rhoFull_, muFull_, scratchA_, scratchB_;
  Volume deltaDirect_, rhoDirect_, muDirect_;  ///< direct lobes, joined lpv.directSteps before the end
  gl::VertexArray emptyVao_;

  // Kinect-VAL
  struct ValObject {
    SparsePoints points;       ///< model frame
    gl::Buffer weights;        ///< per vertex: 8 neighbour indices + 8 weights (64 B)
    Material material;
  };
  std::vector<ValObject> valObjects_;
  std::optional<ValGpu> valGpu_;
  std::vector<Val> realVals_;
  std::vector<Val> rsmVals_;   ///< virtual VALs of the last run, all lights
  std::vector<Val> vals_;      ///< everything the last run gathered
  struct ShadowMaps {
    SceneLight light;
    LightView view;
    cv::Mat rho, mu;  ///< RSM world positions with and without the virtual objects (CPU copies)
  };
  std::vector<ShadowMaps> shadowMaps_;
  ValStats valStats_;
  // What the last run computed from (stage skipping).
  uint64_t realMeshVersion_ = 0, realValsVersion_ = 0;
  struct RunInputs {
    std::vector<double> camera, objects, lights, ambient;
    uint64_t realMesh = 0, realVals = 0;
  };
  std::optional<RunInputs> cache_;
  std::vector<LightView> views_;  ///< the last RSM run's light views
  std::vector<std::string> skipped_;
  gl::Program valMeshProgram_;
  gl::Texture valRadiance_, valIrradiance_, shadowMuArray_;
  gl::Framebuffer valFb_;
};

}  // namespace mrgi::lighting
