#pragma once
/// DLPV (Delta Light Propagation Volumes, shared/papers; algorithms.md §3) as a technique module: per light
/// the RSM texels where RSM^rho and RSM^mu differ are injected into a delta volume (+rho, -mu, and the direct
/// light the object now intercepts, negative), propagated, and read back as the real pixels' E_delta; the
/// virtual object's bounce light comes from a regular volume of RSM^rho. Variant knob "naive_difference"
/// (alias "lpv-diff"): two full volumes V^rho and V^mu, differenced at read-out. Reference math: lpv.h.
#include <optional>

#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/techniques/dlpv/lpv.h"
#include "lighting/techniques/technique.h"

namespace mrgi::lighting {

struct DlpvKnobs {
  int resolution = 0;            ///< cells per axis
  int steps = 0;                 ///< propagation steps
  double damping = 0;            ///< directional damping of lateral/backward propagation, [0, 1] (0 = off)
  int directSteps = 0;           ///< steps the direct (shadow) delta propagates (joins that many before the end)
  bool naiveDifference = false;  ///< two volumes differenced instead of delta injection
};
const std::vector<KnobBinding<DlpvKnobs>>& dlpvKnobTable();

class DlpvTechnique final : public Technique {
 public:
  explicit DlpvTechnique(const TechniqueSetup& setup);

  std::string name() const override { return "dlpv"; }
  unsigned inputs() const override { return kInputCamera | kInputGeometry | kInputLights; }
  /// The objects' shadow of every light but a sharp distant one (the sun): the volume covers the region around
  /// the objects in cells of centimetres, where a low sun throws a sharp shadow past the region's edge; that
  /// shadow the shading pass draws from the shadow maps.
  bool accountsForDirectShadow(const SceneLight& light) const override { return !sharpDistant(light); }
  /// A directional light no wider than this (radians; the sun's is 0.0047) casts shadows sharp enough that a volume
  /// of centimetre cells cannot draw them.
  static constexpr double kSharpAngularRadius = 0.02;
  /// A directional light no wider than kSharpAngularRadius.
  static bool sharpDistant(const SceneLight& light);
  bool accountsForReflectedLight() const override { return true; }  // the objects' RSMs injected into the volume
  void beginLights(const FrameResources& frame, gl::Profiler* profiler) override;
  void light(const FrameResources& frame, size_t index, gl::Profiler* profiler) override;
  void endLights(const FrameResources& frame, gl::Profiler* profiler) override;
  void update(const FrameResources& frame, gl::Profiler* profiler) override;
  TechniqueOutputs outputs() const override;
  std::vector<std::string> debugViews() const override { return {"dlpv_slices"}; }
  cv::Mat debugImage(const std::string& view, const DebugContext& context, nlohmann::json& info) const override;
  size_t gpuBytes() const override;

  const DlpvKnobs& knobs() const { return knobs_; }
  /// The grid of the last light stage (nullopt before one ran).
  const std::optional<LpvGrid>& grid() const { return grid_; }
  /// Accumulated volumes of the last run: "delta", "rho" (indirect, lights the virtual object), and for the
  /// naive difference "rho_full", "mu_full"; before propagation, the injected direct lobes "delta_direct",
  /// "rho_direct", "mu_direct". An empty volume when the run did not compute it.
  LpvVolumeCpu downloadVolume(const std::string& name) const;

 private:
  struct Volume {
    gl::Texture r, g, b;
    gl::Framebuffer fb;
  };
  Volume makeVolume(int res) const;
  void inject(Volume& target, const Rsm& source, const Rsm* other, float sign, unsigned mode, const SceneLight& light,
              int rsmSize);
  void propagate(Volume& volume, bool clampNegative, const Volume* late);
  void add(const Volume& src, Volume& dst);
  const Volume* volume(const std::string& name) const;

  DlpvKnobs knobs_;
  bool real_ = false, virtual_ = false;
  std::optional<LpvGrid> grid_;
  gl::Program injectProgram_, propagateProgram_, addProgram_, readoutProgram_;
  int volumeRes_ = 0;
  Volume delta_, rho_, rhoFull_, muFull_, scratchA_, scratchB_;
  Volume deltaDirect_, rhoDirect_, muDirect_;  ///< direct lobes, joined directSteps before the end
  IrradianceTargets out_;
  gl::VertexArray emptyVao_;
};

}  // namespace mrgi::lighting
