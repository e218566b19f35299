// The mrgi command line: every subcommand's flags on one CLI11 app, parsed and run by run() (main.cpp calls
// it; the flag fuzzer parses random argv through the same commands).
#include <cstdio>
#include <exception>
#include <map>
#include <opencv2/core.hpp>
#include <string>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "app/run.h"
#include "capture/checks.h"
#include "capture/image_io.h"
#include "capture/memory.h"
#include "runtime/threads.h"

namespace mrgi::app {

std::map<CLI::App*, Action> addCommands(CLI::App& app) {
  app.require_subcommand(1);
  app.set_version_flag("--version", "mrgi 0.1.0");
  std::map<CLI::App*, Action> actions;
  auto add = [&](const char* name, const char* help, Action (*fn)(CLI::App&)) {
    CLI::App* sub = app.add_subcommand(name, help);
    actions[sub] = fn(*sub);
  };
  add("live",
      "Interactive AR demo: depth sensor (or --source recording) in a window with technique, knobs, debug views, "
      "timings",
      addLive);
  add("record", "Record the depth sensor (and fisheye camera) into a crash-safe session; Ctrl-C keeps every frame",
      addRecord);
  add("info", "Print one JSON object describing a session, TUM sequence, .oni file or device", addInfo);
  add("replay", "Replay a recording headless (or in a window) and write composited frames + summary.json", addReplay);
  add("synth",
      "Generate a synthetic tabletop session with ground truth (AprilTag, walls, a box, a light; or outdoors under an "
      "HDR environment)",
      addSynth);
  add("track",
      "Track the camera through a recording: its pose per frame, by the marker where seen, RGB-D odometry and "
      "relocalisation between (JSON lines with --json)",
      addTrack);
  add("lights",
      "Estimate distant lights from a calibrated fisheye image or an equirectangular probe (solid-angle-weighted "
      "median cut)",
      addLights);
  add("calibrate-fisheye", "Calibrate a fisheye camera from checkerboard images (OpenCV fisheye model)",
      addCalibrateFisheye);
  add("import-visp", "Convert a ViSP RGB-D AprilTag sequence (PNG + NPZ depth) into an mrgi session", addImportVisp);
  add("insert",
      "Place a virtual object relative to the marker (optionally snapped onto the table plane) and save it into a "
      "scene file",
      addInsert);
  add("room",
      "Build the model of the real room from a recording (its depth fused at each frame's tracked camera pose, the "
      "trajectory optimised) and save it",
      addRoom);
  add("room-lights",
      "Lights from a room model as seen from a point: a few point lights and an SH remainder; the map as PNG",
      addRoomLights);
  add("reference", "Path-trace the ground truth of one frame (rho, mu, delta EXR and the reference composite)",
      addReference);
  add("bench",
      "Measure speed against accuracy of every technique's knobs against the path-traced reference; JSON, CSV, HTML, "
      "presets",
      addBench);
  add("compare",
      "Compare a replay's composites with a synthetic session's reference composites: the object's brightness, "
      "relative L1 and brightest side, and its shadow's darkening energy, per frame",
      addCompare);
  add("track-pixels",
      "Measure tracking in pixels on a ViSP RGB-D AprilTag sequence: the tags placed from frame 0 and drawn with "
      "each way of tracking, its tags painted out after frame 0, Open3D's odometry beside ours",
      addTrackPixels);
  checkEveryValue(app);
  return actions;
}

namespace {
/// Every message ends as one printable line of bounded length: a library may quote a whole file.
std::string oneLine(const std::string& message) { return capture::excerpt(message, 600); }
}  // namespace

int run(int argc, char** argv) {
  runtime::configureProcess(argv);
  capture::keepFrameMemory();
  CLI::App app{
      "mrgi: a mixed-reality compositor for RGB-D footage (differential rendering with real-time global illumination)"};
  const std::map<CLI::App*, Action> actions = addCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help / --version
    if (argc > 1 && argv[1][0] != '-') {
      bool known = false;
      std::vector<std::string> names;
      for (const auto* sub : app.get_subcommands({}))
        known |= sub->get_name() == argv[1], names.push_back(sub->get_name());
      if (!known) {
        std::fprintf(stderr, "mrgi: unknown subcommand '%s'%s (see mrgi --help)\n", oneLine(argv[1]).c_str(),
                     capture::didYouMean(argv[1], names).c_str());
        return 2;
      }
    }
    // A flag the subcommand does not have: the one it most likely meant.
    if (dynamic_cast<const CLI::ExtrasError*>(&e))
      for (const auto* sub : app.get_subcommands({}))
        if (sub->parsed())
          for (const std::string& extra : sub->remaining()) {
            if (extra.rfind("--", 0) != 0) continue;
            std::vector<std::string> flags;
            for (const CLI::Option* opt : sub->get_options())
              for (const std::string& n : opt->get_lnames()) flags.push_back("--" + n);
            const std::string hint = capture::didYouMean(extra.substr(0, extra.find('=')), flags);
            if (hint.empty()) continue;
            std::fprintf(stderr, "mrgi: %s: unknown flag%s (see mrgi %s --help)\n", oneLine(extra).c_str(),
                         hint.c_str(), sub->get_name().c_str());
            return 2;
          }
    // One line on stderr naming the problem.
    std::fprintf(stderr, "mrgi: %s (see mrgi --help)\n", oneLine(e.what()).c_str());
    return 2;
  }
  capture::quietOpenCv();
  try {
    for (const auto& [sub, action] : actions)
      if (sub->parsed()) return action();
  } catch (const FlagError& e) {
    std::fprintf(stderr, "mrgi: %s (see mrgi --help)\n", oneLine(e.what()).c_str());
    return 2;
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "mrgi: OpenCV: %s\n", oneLine(e.err).c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrgi: %s\n", oneLine(e.what()).c_str());
    return 1;
  }
  return 1;
}

}  // namespace mrgi::app
