// mrgi: inserts virtual objects into live or recorded RGB-D footage with consistent lighting.
#include <csignal>
#include <cstdio>
#include <exception>
#include <map>
#include <string>

#include <opencv2/core.hpp>

#include "app/commands.h"
#include "capture/image_io.h"
#include "capture/memory.h"

int main(int argc, char** argv) {
  mrgi::capture::keepFrameMemory();
  CLI::App app{"mrgi: a mixed-reality compositor for RGB-D footage (differential rendering with real-time global illumination)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "mrgi 0.1.0");
  std::map<CLI::App*, mrgi::app::Action> actions;
  auto add = [&](const char* name, const char* help, mrgi::app::Action (*fn)(CLI::App&)) {
    CLI::App* sub = app.add_subcommand(name, help);
    actions[sub] = fn(*sub);
  };
  add("live", "Interactive AR demo: depth sensor (or --source recording) in a window with technique, knobs, debug views, timings",
      mrgi::app::addLive);
  add("record", "Record the depth sensor (and fisheye camera) into a crash-safe session; Ctrl-C keeps every frame",
      mrgi::app::addRecord);
  add("info", "Print one JSON object describing a session, TUM sequence, .oni file or device", mrgi::app::addInfo);
  add("replay", "Replay a recording headless (or in a window) and write composited frames + summary.json",
      mrgi::app::addReplay);
  add("synth", "Generate a synthetic tabletop session with ground truth (AprilTag, walls, a box, a light; or outdoors under an HDR environment)",
      mrgi::app::addSynth);
  add("track", "Track an AprilTag marker: camera-from-tag pose per frame (JSON lines with --json)",
      mrgi::app::addTrack);
  add("lights", "Estimate distant lights from a calibrated fisheye image (solid-angle-weighted median cut)",
      mrgi::app::addLights);
  add("calibrate-fisheye", "Calibrate a fisheye camera from checkerboard images (OpenCV fisheye model)",
      mrgi::app::addCalibrateFisheye);
  add("import-visp", "Convert a ViSP RGB-D AprilTag sequence (PNG + NPZ depth) into an mrgi session",
      mrgi::app::addImportVisp);
  add("insert", "Place a virtual object relative to the marker (optionally snapped onto the table plane) and save it into a scene file",
      mrgi::app::addInsert);
  add("room", "Build the model of the real room from a recording (depth fused over every frame's marker pose) and save it",
      mrgi::app::addRoom);
  add("room-lights", "Lights from a room model as seen from a point: a few point lights and an SH remainder; the map as PNG",
      mrgi::app::addRoomLights);
  add("reference", "Path-trace the ground truth of one frame (rho, mu, delta EXR and the reference composite)",
      mrgi::app::addReference);
  add("bench", "Measure speed against accuracy of every technique's knobs against the path-traced reference; JSON, CSV, HTML, presets",
      mrgi::app::addBench);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help / --version
    if (argc > 1 && argv[1][0] != '-') {
      bool known = false;
      for (const auto* sub : app.get_subcommands({})) known |= sub->get_name() == argv[1];
      if (!known) {
        std::fprintf(stderr, "mrgi: unknown subcommand '%s' (see mrgi --help)\n", argv[1]);
        return 2;
      }
    }
    // One line on stderr naming the problem.
    std::fprintf(stderr, "mrgi: %s (see mrgi --help)\n", e.what());
    return 2;
  }
  mrgi::capture::quietOpenCv();
  try {
    for (const auto& [sub, action] : actions)
      if (sub->parsed()) return action();
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "mrgi: OpenCV: %s\n", e.err.c_str());
    return 1;
  } catch (const std::exception& e) {
    std::string msg = e.what();
    for (char& c : msg)
      if (c == '\n') c = ' ';
    std::fprintf(stderr, "mrgi: %s\n", msg.c_str());
    return 1;
  }
  return 1;
}
