// mrgi bench: the flags of the speed/accuracy measurement of the lighting techniques' knobs (evaluation/bench_run.h).
#include <filesystem>
#include <memory>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "capture/error.h"
#include "evaluation/bench.h"
#include "evaluation/bench_run.h"
#include "runtime/output.h"

namespace fs = std::filesystem;

namespace mrgi::app {

Action addBench(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  app.add_option("--technique", o->technique, "technique to sweep (default: all; bruteforce: required)")
      ->check(techniqueValidator());
  app.add_option(
         "--against", o->against,
         "reference (path tracer, default) or bruteforce (a technique's sparse method vs its per-pixel brute force)")
      ->check(CLI::IsMember({"reference", "bruteforce"}));
  app.add_option("--json", o->json, "write one record per configuration (JSON)");
  app.add_option("--csv", o->csv, "write the records as CSV");
  app.add_option("--html", o->html, "write a self-contained HTML report (SVG plots, images)");
  app.add_option(
      "--gallery", o->gallery,
      "write DIR/SESSION.png per session: the crop around the objects, composite and real-pixel delta, of every "
      "technique's defaults beside the reference's");
  app.add_option("--presets", o->presets, "write the fast/balanced/accurate presets chosen from the front (JSON)");
  CLI::Option* sessions = app.add_option(
      "--session", o->sessions,
      "sessions to measure on, their first frames (repeat the flag; default: the bundled recordings/tabletop-synth, "
      "tabletop-pt and tabletop-hdr, found from the current folder or the checkout holding this executable)");
  app.add_option("--scene", o->scene,
                 "scene file for every session: objects, lights, the knobs the sweep starts from (default: each "
                 "session's reference scene, else recordings/scenes/tabletop.json)");
  app.add_option("--frames", o->frames, "consecutive frames per configuration (flicker; times exclude the first)")
      ->check(numberIn(1, 1000));
  app.add_option("--ref-frames", o->refFrames, "frames with a path-traced reference, spread over --frames")
      ->check(numberIn(1, 100));
  app.add_option("--ref-spp", o->refSpp, "reference samples per pixel")->check(numberIn(1, 1 << 16));
  app.add_option(
         "--ref-focus-spp", o->refFocusSpp,
         "reference samples per pixel in the box around the objects grown by three radii, where their shadow and "
         "bounce fall (0 = 16 x --ref-spp)")
      ->check(numberIn(0, 1 << 20));
  app.add_option("--ref-bounces", o->refBounces, "reference bounces")->check(numberIn(0, 64));
  app.add_flag("--quick", o->quick, "fewer knob values (small sessions, tests)");
  app.add_flag(
      "--room", o->room,
      "also light each configuration from the session's fused room model (mrgi room over all its frames) and report "
      "its whole-pipeline error beside the per-frame one");
  app.add_option("--tracking-pixels", o->trackingPixels,
                 "also measure tracking in pixels on this real ViSP tag sequence, ours beside Open3D's odometry (as "
                 "mrgi track-pixels; e.g. ../shared/data/rgbd-visp-apriltag)");
  addPoseOption(app, o->pose)
      ->description(
          "camera pose per frame: ground-truth (default here: the bench ranks techniques, not tracking; needs a "
          "synthetic "
          "session), marker, odometry or tracked");
  app.add_option("--model", o->model, "bruteforce: virtual object, resting on the marker plane at its centre");
  app.add_option("--scale", o->scale, "model scale (the bundled unit sphere: its radius in metres)")
      ->check(numberIn(1e-3, 10.0));
  app.add_option("--occlusion", o->occlusion, "sparse runs with disc occlusion off, on or both")
      ->check(CLI::IsMember({"off", "on", "both"}));
  app.add_option("--vals", o->valCounts, "VAL counts to sweep (e.g. 1024,16384,262144)")->delimiter(',');
  app.add_option("--sparse", o->sparseCounts, "sparse point counts to sweep (e.g. 256,4096,16384)")->delimiter(',');
  app.add_option("--k-cache", o->kCache, "bruteforce: the technique's k_cache knob (VALs per shared-memory tile)")
      ->check(numberIn(1, 1 << 20));
  app.add_option("--repeats", o->repeats, "timing repeats (best is kept)")->check(numberIn(1, 1000));
  app.add_option("--gl", o->gl, "GL backend: osmesa (default), egl")->check(CLI::IsMember({"osmesa", "egl"}));
  return [o, sessions] {
    if (sessions->count() == 0)
      for (std::string& s : o->sessions) s = bundledPath(s);
    // Nothing the user has is replaced: each file named here is new or an earlier output of mrgi bench.
    checkReplaceable(o->json, "--json", "mrgi bench");
    checkReplaceable(o->csv, "--csv", "mrgi bench", evaluation::kCsvSignature);
    checkReplaceable(o->html, "--html", "mrgi bench");
    checkReplaceable(o->presets, "--presets", "mrgi bench");
    if (!o->gallery.empty()) {
      std::error_code ec;
      if (fs::exists(o->gallery, ec) && !fs::is_directory(o->gallery, ec))
        throw capture::CaptureError(o->gallery, "exists and is not a folder (--gallery)");
      fs::create_directories(o->gallery, ec);
      if (ec) throw capture::CaptureError(o->gallery, "cannot create the folder (--gallery): " + ec.message());
      for (const std::string& s : o->sessions)
        checkReplaceable((fs::path(o->gallery) / (fs::path(s).filename().string() + ".png")).string(), "--gallery",
                         "mrgi bench");
    }
    return runBench(*o);
  };
}

}  // namespace mrgi::app
