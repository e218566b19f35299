#pragma once
/// The one interface every lighting technique implements (lighting/techniques/*/, listed by the registry). A technique
/// reads the frame's shared resources (lighting/frame/frame.h), declares which of their versions its results
/// depend on, and hands out GPU textures the shared shading pass adds: a real-pixel delta and/or the
/// virtual object's indirect light. It never draws the direct light, shadows or ambient (the shading pass
/// does), and nothing outside its folder names it except the registry (lighting/techniques/registry.cpp).
///
/// Per run the pipeline calls, only when the technique's declared inputs changed:
///   beginLights()  -> light(i) for each light, right after the frame rendered light i's RSMs -> endLights()
///   (only when the RSMs were re-rendered, i.e. lights or geometry changed), then update().
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "gl/objects.h"
#include "gl/profiler.h"
#include "lighting/frame/frame.h"
#include "lighting/knobs.h"

namespace mrgi::lighting {

/// What a technique is asked to provide.
enum class Role { Real, Virtual };

/// Outputs, RGBA32F textures of the output size, or of the frame's reduced view (FrameResources::techniqueView,
/// the frame knob render_scale: per-pixel work over a quarter or a sixteenth of the pixels), which the shading
/// pass upsamples joint-bilaterally (lighting/upsample.h); nullptr = none (the shading pass reads zero).
struct TechniqueOutputs {
  /// Real pixels: rgb = E_delta (W/m^2), the irradiance the virtual objects add (or remove) on real surfaces.
  const gl::Texture* realDelta = nullptr;
  /// Virtual pixels: rgb = indirect irradiance (W/m^2), shaded with the albedo like the direct light.
  const gl::Texture* virtualIrradiance = nullptr;
  /// Virtual pixels: rgb = indirect radiance added as it is (W/m^2/sr; glossy reflection).
  const gl::Texture* virtualRadiance = nullptr;
};

/// The two irradiance outputs a read-out pass writes (RGBA32F, the size it is given, nearest filtering), as one
/// framebuffer: colour attachment 0 the real-pixel delta, 1 the object's indirect irradiance.
struct IrradianceTargets {
  gl::Texture realDelta, virtualIrradiance;
  gl::Framebuffer fb;
  IrradianceTargets(int width, int height)
      : realDelta(GL_TEXTURE_2D, GL_RGBA32F, width, height),
        virtualIrradiance(GL_TEXTURE_2D, GL_RGBA32F, width, height) {
    realDelta.setFilter(GL_NEAREST, GL_NEAREST);
    virtualIrradiance.setFilter(GL_NEAREST, GL_NEAREST);
    fb.attachColour(0, realDelta);
    fb.attachColour(1, virtualIrradiance);
    fb.finalise(2);
  }
  /// The outputs of a technique serving these roles.
  TechniqueOutputs outputs(bool real, bool virtualObject) const {
    TechniqueOutputs o;
    if (real) o.realDelta = &realDelta;
    if (virtualObject) o.virtualIrradiance = &virtualIrradiance;
    return o;
  }
  size_t bytes() const { return realDelta.bytes() + virtualIrradiance.bytes(); }
};

/// What a debug view may draw on.
struct DebugContext {
  cv::Mat composite;  ///< RGB8, the frame's composite
  capture::Intrinsics intrinsics;
  std::optional<capture::Pose> T_world_camera;
};

/// How a technique is built: its knob values (complete), the roles it serves in this pipeline, the frame.
struct TechniqueSetup {
  KnobValues knobs;
  bool real = false, virtualObject = false;
  const FrameResources* frame = nullptr;
  /// Progress of a long precompute (what, fraction 0..1); may be empty (PipelineConfig::progress).
  std::function<void(const std::string& what, double fraction)> progress;
  /// Where precomputed data may be kept between runs; empty: nowhere (PipelineConfig::cacheDir).
  std::string cacheDir;
};

class Technique {
 public:
  virtual ~Technique() = default;

  /// Registry name ("dlpv").
  virtual std::string name() const = 0;
  /// The frame inputs update() depends on (FrameInput bits). Per-light work always depends on lights and
  /// geometry.
  virtual unsigned inputs() const = 0;
  /// Further inputs its per-light work (beginLights, light, endLights) depends on: a change reruns the
  /// lights' pass (RSMs included), as a change of lights or geometry does.
  virtual unsigned lightInputs() const { return 0; }
  /// What builds the technique's own input from each frame or a room (lighting/frame/technique_input.h), read
  /// back from FrameResources::techniqueInput(name()); nullptr: it needs none.
  virtual std::unique_ptr<TechniqueInputBuilder> inputBuilder() const { return nullptr; }
  /// Whether the real-pixel delta already contains the objects' direct shadow from `light` on real surfaces
  /// (otherwise the shading pass adds it from the shadow maps).
  virtual bool accountsForDirectShadow(const SceneLight& light) const {
    (void)light;
    return false;
  }
  /// Whether the real-pixel delta already contains the lights the objects reflect onto real surfaces
  /// (otherwise the shading pass adds it: lighting::reflectedLight).
  virtual bool accountsForReflectedLight() const { return false; }

  virtual void beginLights(const FrameResources& frame, gl::Profiler* profiler) {}
  virtual void light(const FrameResources& frame, size_t index, gl::Profiler* profiler) {}
  virtual void endLights(const FrameResources& frame, gl::Profiler* profiler) {}
  /// Computes the outputs from the frame (its G-buffer is current).
  virtual void update(const FrameResources& frame, gl::Profiler* profiler) = 0;
  virtual TechniqueOutputs outputs() const = 0;

  /// Debug views ("dlpv_slices") and their images (RGB8; empty when there is nothing to show). `info`
  /// receives the scales the image used.
  virtual std::vector<std::string> debugViews() const { return {}; }
  virtual cv::Mat debugImage(const std::string& view, const DebugContext& context, nlohmann::json& info) const {
    return {};
  }
  /// Per-frame facts for summary.json (counts, flicker, ...), after update().
  virtual nlohmann::json stats() const { return nlohmann::json::object(); }
  /// GPU memory of the textures and buffers it holds, bytes.
  virtual size_t gpuBytes() const = 0;
};

}  // namespace mrgi::lighting
