#pragma once
/// Kinect-VAL (LightSkin, shared/papers/000; algorithms.md §4) as a technique module for the virtual object:
/// real-surface area lights (the frame's real VALs, dimmed where the object now shadows them) and the
/// object's own lit RSM texels light it through sparse shading points, interpolated per vertex and
/// evaluated per pixel (diffuse + glossy). It hands out the object's indirect radiance; it has no real-pixel
/// output (the shading pass adds the object's direct shadow there). Reference math: val.h; GPU: val_gpu.h.
#include <optional>

#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/techniques/kinect_val/val.h"
#include "lighting/techniques/kinect_val/val_gpu.h"
#include "lighting/techniques/technique.h"

namespace mrgi::lighting {

struct KinectValKnobs {
  int sparsePoints = 0;     ///< sparse shading points per object
  int kCache = 0;           ///< VALs per shared-memory tile of the gather
  bool occlusion = false;   ///< disc-occluder approximation (§3.3)
  int stride = 0;           ///< RGB-D pixel stride of the real VALs
  int rsmStride = 0;        ///< RSM texel stride of the virtual VALs
  bool fusion = false;      ///< fuse real VALs over frames in a world-space surfel map
  double voxel = 0;         ///< surfel voxel, metres
  double decay = 0;         ///< confidence a surfel keeps per frame that should have seen it but did not
  bool bruteForce = false;  ///< reference: every VAL gathered at every visible virtual pixel (no occlusion)
};
const std::vector<KnobBinding<KinectValKnobs>>& kinectValKnobTable();

class KinectValTechnique final : public Technique {
 public:
  explicit KinectValTechnique(const TechniqueSetup& setup);

  std::string name() const override { return "kinect-val"; }
  unsigned inputs() const override { return kInputCamera | kInputGeometry | kInputLights | kInputAmbient | kInputOwn; }
  std::unique_ptr<TechniqueInputBuilder> inputBuilder() const override;
  void beginLights(const FrameResources& frame, gl::Profiler* profiler) override;
  void light(const FrameResources& frame, size_t index, gl::Profiler* profiler) override;
  void update(const FrameResources& frame, gl::Profiler* profiler) override;
  TechniqueOutputs outputs() const override;
  std::vector<std::string> debugViews() const override { return {"val_irradiance", "val_sparse_points"}; }
  cv::Mat debugImage(const std::string& view, const DebugContext& context, nlohmann::json& info) const override;
  nlohmann::json stats() const override;
  size_t gpuBytes() const override;

  const KinectValKnobs& knobs() const { return knobs_; }
  /// What the last run did.
  struct Stats {
    size_t realVals = 0, virtualVals = 0, receivers = 0;
    size_t shadowedVals = 0;  ///< real VALs dimmed because the object shadows them
    bool bruteForce = false;
  };
  /// (The virtual and dimmed counts are read back from the GPU.)
  Stats valStats() const;
  /// The VALs of the last run as gathered (real ones dimmed where the object shadows them, then the virtual
  /// ones), read back from the GPU where they were built.
  std::vector<Val> downloadVals() const { return gpu_.downloadVals(); }
  /// Per sparse point (objects in order; brute force: per visible virtual pixel) E and S of the last run.
  void downloadValSums(std::vector<cv::Vec3f>& E, std::vector<cv::Vec3f>& S) const;
  /// The sparse points' VPL pairs of the last run (objects in order), after occlusion.
  std::vector<SparseVpl> downloadSparseVpls() const { return gpu_.downloadVpls(); }
  /// Object i's sparse points (model frame).
  const SparsePoints& sparsePoints(size_t i) const { return objects_.at(i).points; }
  /// The bounce irradiance E (rgb, W/m^2) on the object's visible pixels.
  const gl::Texture& irradiance() const { return irradiance_; }

 private:
  void bruteForce(const FrameResources& frame, gl::Profiler* profiler);

  KinectValKnobs knobs_;
  struct Object {
    SparsePoints points;  ///< model frame
    gl::Buffer weights;   ///< per vertex: 8 neighbour indices + 8 weights (64 B)
    Material material;
  };
  std::vector<Object> objects_;
  ValGpu gpu_;
  /// The frame's versions (geometry, lights, ambient, own inputs) the assembled VAL set was built from: the
  /// camera alone moving (a static room, static objects and lights) leaves the set as it is.
  std::optional<std::array<uint64_t, 4>> assembled_;
  gl::Program meshProgram_;
  gl::Texture radiance_, irradiance_;
  gl::Framebuffer fb_;
  Stats stats_;                          ///< what the CPU knows of the last run (the GPU holds the VAL counts)
  std::vector<cv::Matx44d> transforms_;  ///< object placements of the last run
  /// The facts of a run (counts now; the irradiance and flicker, which need the sums on the CPU, when stats()
  /// is first asked after the run: nothing is read back on a run nobody asks about).
  nlohmann::json runStats_ = nlohmann::json::object();
  uint64_t runs_ = 0;
  mutable uint64_t statsRun_ = 0;
  mutable nlohmann::json irradianceStats_ = nlohmann::json::object();
  mutable std::vector<cv::Vec3f> prevE_;  ///< the sparse points' irradiance when stats() was last asked (flicker)
};

}  // namespace mrgi::lighting
