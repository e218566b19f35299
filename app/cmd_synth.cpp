// mrgi synth: the flags of a synthetic tabletop session with ground truth (evaluation/synth.h writes it).
#include <cstdio>
#include <memory>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "capture/checks.h"
#include "evaluation/synth.h"
#include "runtime/output.h"

namespace mrgi::app {

Action addSynth(CLI::App& app) {
  auto o = std::make_shared<SynthOptions>();
  auto exposure = std::make_shared<std::string>("1");
  app.add_option("--out", o->out, "new session directory (must not exist or be empty)")->required();
  app.add_option("--frames", o->frames, "number of frames along the camera orbit")->check(numberIn(1, 100000));
  app.add_option("--environment", o->environment,
                 "outdoors under this HDR environment (equirectangular EXR) instead of the room");
  app.add_option("--environment-scale", o->environmentScale,
                 "multiplies the environment (default: a white upward surface reads 0.6)")
      ->check(numberIn(0, 1e6));
  app.add_flag("--static-camera", o->staticCamera,
               "keep the camera at the orbit's first pose (only the sensor noise changes)");
  app.add_option("--width", o->width, "image width")->check(numberIn(16, 8192));
  app.add_option("--height", o->height, "image height")->check(numberIn(12, 8192));
  app.add_option("--seed", o->seed, "noise seed (output is deterministic for a seed)");
  app.add_option("--tag-id", o->tagId, "tag36h11 id of the marker on the table")->check(numberIn(0, 586));
  app.add_option("--tag-size", o->tagSize, "marker black-square edge in metres")->check(numberAbove(0, 10));
  app.add_option("--render", o->render, "pathtrace (global illumination, default) or raycast (direct light + ambient)")
      ->check(CLI::IsMember({"pathtrace", "raycast"}));
  app.add_option("--spp", o->spp, "path-traced samples per pixel")->check(numberIn(1, 1 << 16));
  app.add_option("--reference-focus-spp", o->referenceFocusSpp,
                 "with --scene: the reference delta from its own two renders, this many samples per pixel around the "
                 "objects (--reference-focus-radii), --spp elsewhere, written as half floats (0 = the composite's "
                 "render minus the "
                 "frame's)")
      ->check(numberIn(0, 1 << 20));
  app.add_option("--reference-focus-radii", o->referenceFocusRadii,
                 "with --reference-focus-spp: how far around the objects the focus reaches, in radii of their bounding "
                 "sphere (default 3)")
      ->check(numberIn(0, 100));
  app.add_option("--bounces", o->bounces, "path-traced bounces")->check(numberIn(0, 64));
  app.add_option("--scene", o->scene,
                 "also write each frame's reference composite with this scene's objects (reference/)");
  app.add_option("--scan", o->scan,
                 "append N look-around frames (walls, ceiling, the lamp; no marker in view, no reference)")
      ->check(numberIn(0, 100000));
  app.add_option("--scan-jpeg", o->scanJpegQuality,
                 "store the look-around's colour as JPEG at this quality (1-100; 0 = PNG, lossless as the orbit's)")
      ->check(numberIn(0, 100));
  app.add_flag("--window-sun", o->windowSun,
               "a window in the right wall and the sun through it onto the table, beside the lamp (a distant light "
               "the cameras never see: only its sunlit patches and shadows)");
  app.add_flag("--move-light", o->moveLight,
               "the lamp moves a third of the way round the table over the orbit (each frame records its lights)");
  app.add_flag("--move-box", o->moveBox,
               "the box moves to the front of the table a third of the way through (a room that changes: carving)");
  app.add_option("--exposure", *exposure,
                 "auto (at most 1 % of pixels clip; recorded per frame) or a relative exposure")
      ->check(numberList(1, capture::kMinExposure, capture::kMaxExposure, {"auto"}));
  app.add_option("--fisheye-every", o->fisheyeEvery, "store a fisheye HDR frame every N frames (0 = no fisheye)")
      ->check(numberIn(0, 1e6));
  return [o, exposure] {
    o->exposure.reset();
    if (*exposure != "auto") o->exposure = parseNumbers(*exposure)[0];  // checked by the flag's validator
    ProgressBar bar("synth");
    o->progress = [&bar](double fraction) { bar(fraction); };
    const int frames = writeSynthSession(*o);
    std::printf("wrote %d frames to %s\n", frames, o->out.c_str());
    return 0;
  };
}

}  // namespace mrgi::app
