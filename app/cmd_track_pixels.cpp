// mrgi track-pixels: tracking measured in pixels on a real ViSP RGB-D AprilTag sequence
// (evaluation/tag_pixels.h): the tags' centres placed from the first frame and drawn with each way of tracking
// the camera, against where every later frame shows them; with the tags painted out after the first frame, and
// Open3D's legacy RGB-D odometry through the same harness beside ours.
#include <cstdio>
#include <memory>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "evaluation/tag_pixels.h"

namespace mrgi::app {

namespace {

struct TrackPixelsOptions {
  std::string input;
  int frames = 0;
  int markerId = 3;
  bool json = false;
};

int trackPixels(const TrackPixelsOptions& o) {
  const evaluation::TagPixelTable table = evaluation::tagPixelTable(o.input, o.frames, o.markerId);
  if (o.json) {
    std::printf("%s\n", evaluation::tagPixelJson(table).dump().c_str());
    return 0;
  }
  const size_t frames = table.frames;
  std::printf(
      "%s, frames 0-%zu: the tags' centres placed from frame 0, drawn in frames 1-%zu\n\n"
      "| poses | RMS (px) | 95th percentile (px) | max (px) | frames tracked | ms a frame |\n"
      "|---|---|---|---|---|---|\n",
      o.input.c_str(), frames - 1, frames - 1);
  for (const auto& r : table.rows)
    std::printf("| %s | %.2f | %.2f | %.2f | %d of %d | %.0f |\n", r.poses.c_str(), r.error.rmsPx, r.error.p95Px,
                r.error.maxPx, r.error.tracked, r.error.frames, r.msPerFrame);
  return 0;
}

}  // namespace

Action addTrackPixels(CLI::App& app) {
  auto o = std::make_shared<TrackPixelsOptions>();
  app.add_option("DIR", o->input, "ViSP RGB-D AprilTag sequence folder (e.g. ../shared/data/rgbd-visp-apriltag)")
      ->required();
  app.add_option("--frames", o->frames, "the first N frames (default: all)")->check(numberIn(2, 1e6));
  app.add_option("--tag-id", o->markerId, "the tag that anchors the world on frame 0 (default 3)")
      ->check(numberIn(0, 1e6));
  app.add_flag("--json", o->json, "print one JSON object (each row's measures and its per-frame RMS)");
  return [o] { return trackPixels(*o); };
}

}  // namespace mrgi::app
