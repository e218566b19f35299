// mrgi replay: the flags of a recording's replay (runtime/replay.h).
#include <memory>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "capture/checks.h"
#include "runtime/replay.h"

namespace mrgi::app {

Action addReplay(CLI::App& app) {
  auto o = std::make_shared<ReplayOptions>();
  o->scene.presets = MRGI_DEFAULT_PRESETS;
  app.add_option("SESSION", o->source, "session directory, TUM directory, Open3D RGB-D folder or .oni file")
      ->required();
  app.add_option("--out", o->out, "output folder for frame_NNNN.png and summary.json")->required();
  app.add_option("--frames", o->frames, "replay at most N frames (0 = all)")->check(numberIn(0, 1e9));
  app.add_option("--gl", o->gl, "GL backend: osmesa (headless, default), egl (headless GPU), window")
      ->check(CLI::IsMember({"osmesa", "egl", "window"}));
  app.add_option("--scene", o->scene.scene,
                 "scene file (JSON): virtual objects relative to the marker, lights, technique");
  app.add_option("--technique", o->scene.technique, "lighting technique, overrides the scene file's")
      ->check(techniqueValidator());
  app.add_option("--preset", o->scene.preset, "technique and knobs from a measured preset (overrides the scene file's)")
      ->check(CLI::IsMember({"fast", "balanced", "accurate"}));
  app.add_option("--presets", o->scene.presets, "presets file written by mrgi bench --presets")->capture_default_str();
  app.add_flag("--dump-delta", o->dumpDelta,
               "also write delta_NNNN.exr (linear RGB added to real pixels) and mask_NNNN.png (255 = virtual)");
  app.add_flag("--debug", o->debug,
               "also write debug_NNNN_*.png: delta (red = negative), G-buffer albedo/normal/mask, "
               "RSM flux/normal of the last light, each technique's own views, the fisheye frame with its "
               "median-cut lights; with --room the fused room seen from the camera (radiance, albedo) "
               "and, lit from the room, its environment at the object with its lights");
  addPoseOption(app, o->pose);
  addFolderCalibration(app, o->open);
  allowEmpty(
      app.add_option("--mp4", o->mp4, "video of the composites inside --out (\"\" = none)")->capture_default_str());
  addRoomFlags(app, o->rooms, "at the end");
  app.add_option("--fps", o->fps, "video frame rate (default: the recording's)")
      ->check(numberIn(capture::kMinFrameRate, capture::kMaxFrameRate));
  app.add_flag("--recompute-all", o->recomputeAll,
               "run every stage on every frame (default: skip stages whose inputs did not change)");
  app.add_flag("--sequential", o->sequential,
               "work on each frame in the loop, one stage after another (default: the next frame's CPU "
               "half, marker to real mesh, runs on a worker while GL works on this one; the same composites)");
  app.add_flag("--finish-stages", o->finishStages,
               "wait for the GPU at the end of each stage, so each stage's GPU time is its own (a profiling aid: "
               "the frames take longer; the same composites)");
  app.add_option("--mesh-stride", o->meshStride, "real-scene mesh over every N-th depth pixel")->check(numberIn(1, 16));
  app.add_flag("-v,--verbose", o->verbose,
               "one line per frame with each stage's time in the pipeline's order (summary.json holds them too)");
  return [o] {
    // A bad room stops before anything is written.
    o->room = openRoom(o->rooms, !o->scene.scene.empty());
    return replay(*o);
  };
}

}  // namespace mrgi::app
