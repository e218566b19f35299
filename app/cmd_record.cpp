// mrgi record: frames from the depth sensor (and the fisheye camera with its calibration) into the
// crash-safe session format. Every frame is complete on disk before the next is read, so Ctrl-C, a lost
// device or a power cut leave a session that replays up to its last frame.
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <thread>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "capture/error.h"
#include "capture/live_source.h"
#include "capture/session.h"
#include "runtime/output.h"

using nlohmann::json;

namespace mrgi::app {
namespace {

struct RecordOptions {
  capture::LiveSourceOptions in;
  std::string out;
  int64_t frames = 0;
  double rate = 0;  ///< --source: frames per second to read at (0 = as fast as possible)
};

int runRecord(const RecordOptions& o) {
  capture::LiveSource live(o.in);
  InterruptGuard guard;
  ProgressBar bar("record");
  std::optional<capture::SessionWriter> writer;
  const double period = live.recording() && o.rate > 0 ? 1.0 / o.rate : 0.0;
  std::string stopped = "end of source";
  int64_t fisheyeFrames = 0;
  while (o.frames == 0 || (writer ? writer->framesWritten() : 0) < o.frames) {
    if (InterruptGuard::interrupted()) {
      stopped = "interrupted";
      break;
    }
    const auto t0 = std::chrono::steady_clock::now();
    std::optional<capture::Frame> frame;
    try {
      frame = live.next();
    } catch (const capture::CaptureError& e) {
      if (!writer) throw;
      // The device went away: what was recorded stays complete.
      std::fprintf(stderr, "mrgi: %s; keeping the %lld frames recorded\n", e.what(),
                   static_cast<long long>(writer->framesWritten()));
      stopped = "device lost";
      break;
    }
    if (!frame) break;
    if (!frame->rgbd) continue;
    if (!writer) {
      capture::SessionManifest m = capture::manifestFor(live, *frame);
      if (!m.fisheye) m.fisheye = live.fisheyeCalibration();  // nullopt without a fisheye camera
      writer.emplace(o.out, m);                               // refuses a folder that holds anything
    }
    fisheyeFrames += frame->fisheye ? 1 : 0;
    writer->append(*frame);
    if (o.frames > 0) bar(static_cast<double>(writer->framesWritten()) / static_cast<double>(o.frames));
    if (period > 0) {
      const double spent = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (spent < period) std::this_thread::sleep_for(std::chrono::duration<double>(period - spent));
    }
  }
  if (!writer) throw capture::CaptureError(live.name(), "delivered no RGB-D frame; nothing recorded");
  const json summary = {{"session", o.out},
                        {"source", live.name()},
                        {"frames", writer->framesWritten()},
                        {"fisheye_frames", fisheyeFrames},
                        {"stopped", stopped}};
  std::printf("%s\n", summary.dump().c_str());
  return stopped == "interrupted" ? 130 : 0;
}

}  // namespace

Action addRecord(CLI::App& app) {
  auto o = std::make_shared<RecordOptions>();
  app.add_option("--out", o->out, "new session folder (must not exist or be empty)")->required();
  app.add_option("--device", o->in.device, "depth sensor URI")->capture_default_str();
  app.add_option("--fisheye", o->in.fisheye, "V4L2 fisheye camera recorded alongside (e.g. /dev/video0)");
  app.add_option("--fisheye-calibration", o->in.fisheyeCalibration, "its calibration (YAML), stored in the manifest");
  app.add_option("--fisheye-every", o->in.fisheyeEvery, "a fisheye frame every N depth frames")
      ->check(numberIn(1, 1e6));
  app.add_option("--source", o->in.source, "re-record a session, TUM sequence or .oni file instead of the sensor");
  app.add_option("--frames", o->frames, "stop after N frames (0 = until Ctrl-C or the end)")->check(numberIn(0, 1e9));
  app.add_option("--rate", o->rate, "--source: read N frames per second, as a sensor would deliver them (0 = at once)")
      ->check(numberIn(0, 1000));
  return [o] { return runRecord(*o); };
}

}  // namespace mrgi::app
