#pragma once
/// Splatting indirect illumination (shared/papers/001; algorithms.md §2 and §5) as a technique module: per
/// light, the texels of RSM^rho and RSM^mu become pixel lights, importance-sampled by hierarchical warping on
/// the GPU, and each sampled light is splatted over its significant region only (the splat box of I_low) in
/// a deferred pass over the G-buffer.
/// Outputs: on real pixels the change the objects make to the bounce light, the splats of RSM^rho's lights
/// minus RSM^mu's at the same texels with the same weights (sampled where the two differ, so that identical
/// texels cancel and with no object the delta is exactly 0), glossy objects' lobes included (their focused
/// reflections: caustics on the table); on the object, the bounce real surfaces send it (RSM^rho's real
/// texels). The ambient the objects hide from real surfaces, and what they reflect of it, are the shading
/// pass's (lighting/object_shadow.h): an object's texel carries the lights' bounce alone. Reference math:
/// splat.h.
#include <utility>
#include <vector>

#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/techniques/splatting/splat.h"
#include "lighting/techniques/technique.h"

namespace mrgi::lighting {

struct SplattingKnobs {
  int vpls = 0;       ///< sampled pixel lights per run (over all lights)
  double iLow = 0;    ///< I_low of a light: this x lum|Phi| / (pi s^2), s the region's side
  double widen = 0;   ///< metres: a glossy lobe widens within this distance of its light
  int farLevels = 0;  ///< far-field levels (splat.h splatFar): each reaches 4x further with 1/16 of the samples
};
const std::vector<KnobBinding<SplattingKnobs>>& splattingKnobTable();

class SplattingTechnique final : public Technique {
 public:
  bool accountsForReflectedLight() const override { return true; }  // the objects' RSM texels as splatted lights
  explicit SplattingTechnique(const TechniqueSetup& setup);

  std::string name() const override { return "splatting"; }
  unsigned inputs() const override { return kInputCamera | kInputGeometry | kInputLights | kInputAmbient; }
  /// The pixel lights carry the ambient's bounce and occlusion: a new ambient samples them again.
  unsigned lightInputs() const override { return kInputAmbient; }
  void beginLights(const FrameResources& frame, gl::Profiler* profiler) override;
  void light(const FrameResources& frame, size_t index, gl::Profiler* profiler) override;
  void update(const FrameResources& frame, gl::Profiler* profiler) override;
  TechniqueOutputs outputs() const override { return out_.outputs(real_, virtual_); }
  /// splat_vpls: the sampled lights over the last light's RSM (their texels); splat_overdraw: splats per pixel.
  std::vector<std::string> debugViews() const override { return {"splat_vpls", "splat_overdraw"}; }
  cv::Mat debugImage(const std::string& view, const DebugContext& context, nlohmann::json& info) const override;
  nlohmann::json stats() const override;
  size_t gpuBytes() const override;

  const SplattingKnobs& knobs() const { return knobs_; }
  /// The last run's pixel lights (GPU download): the delta's records (3 per sample) and the object's (1 per sample).
  std::vector<splat::PixelLight> downloadLights(bool delta) const;
  /// This run's sampled lights in record order: each one's first sample index and sample count (a delta
  /// light's records start at 3 x its first sample, an object light's at its first sample).
  const std::vector<std::pair<int, int>>& sampledLights() const { return sampled_; }
  /// I_low of a light of flux luminance 1 (the knob over pi s^2).
  float iLowScale() const { return iLowScale_; }
  /// The last light's level-0 importance (delta or object), padded side x side (GPU download).
  cv::Mat downloadImportance(bool delta) const;
  /// The reach of a texel's occlusion in its RSM (splat::rsmOcclusion), metres: the region's side / 8.
  float occlusionRadius() const { return aoRadius_; }

 private:
  void sampleLight(const FrameResources& frame, size_t index, bool delta, int count, int firstSample, int firstRecord);

  SplattingKnobs knobs_;
  bool real_ = false, virtual_ = false;

  gl::Program importanceProgram_, reduceProgram_, sampleProgram_, splatProgram_;
  int padded_ = 0, levels_ = 0;
  std::pair<int, int> lastSamples_{0, 0};  ///< the last light's first sample index and sample count
  float ambientShare_ = 0;                 ///< each sampled light's share of the ambient's bounce
  float aoRadius_ = 0;                     ///< the last light's occlusion reach (occlusionRadius())
  std::vector<int> levelOffsets_;
  gl::Buffer deltaPyramid_, objectPyramid_, deltaLights_, objectLights_;
  std::vector<int> budget_;                   ///< samples per light this run
  std::vector<std::pair<int, int>> sampled_;  ///< this run's lights with samples: first sample index, count
  int deltaRecords_ = 0, objectRecords_ = 0, samplesSoFar_ = 0;
  float iLowScale_ = 0;
  IrradianceTargets out_;
  gl::VertexArray emptyVao_;
  cv::Mat lastVpls_;  ///< debug: sample count per texel of the last light
};

}  // namespace mrgi::lighting
