// mrgi reference: the flags of one frame's path-traced ground truth (evaluation/reference_frame.h).
#include <memory>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "evaluation/reference_frame.h"

namespace mrgi::app {

Action addReference(CLI::App& app) {
  auto o = std::make_shared<ReferenceOptions>();
  app.add_option("SESSION", o->source, "session directory, TUM directory or .oni file")->required();
  app.add_option("--scene", o->scene, "scene file (JSON): virtual objects, lights")->required();
  app.add_option("--out", o->out, "output folder for rho.exr, mu.exr, delta.exr, mask.png, composite.png")->required();
  app.add_option("--frame", o->frame, "frame index K (0-based)")->check(numberIn(0, 1e9));
  app.add_option("--spp", o->spp, "samples per pixel")->check(numberIn(1, 1 << 20));
  app.add_option("--bounces", o->bounces, "indirect bounces after the first surface")->check(numberIn(0, 64));
  app.add_option("--seed", o->seed, "random seed (the images depend on it alone)");
  app.add_option("--threads", o->threads, "worker threads (0 = all)")->check(numberIn(0, 1024));
  addPoseOption(app, o->pose);
  app.add_option("--mesh-stride", o->meshStride, "real-scene mesh over every N-th depth pixel")->check(numberIn(1, 16));
  return [o] { return renderReferenceFrame(*o); };
}

}  // namespace mrgi::app
