// mrgi track-pixels: tracking measured in pixels on a real ViSP RGB-D AprilTag sequence
// (evaluation/tag_pixels.h): the tags' centres placed from the first frame and drawn with each way of tracking
// the camera, against where every later frame shows them; with the tags painted out after the first frame, and
// Open3D's legacy RGB-D odometry through the same harness beside ours.
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>

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
  using evaluation::TagSequence;
  using Trajectory = std::vector<std::optional<capture::Pose>>;
  const TagSequence inView = evaluation::loadTagSequence(o.input, o.frames);
  TagSequence painted = inView;
  for (capture::Frame& f : painted.frames) f.rgbd->colour = f.rgbd->colour.clone();  // its own pixels to paint
  for (size_t i = 1; i < painted.frames.size(); ++i) evaluation::paintTagsOut(painted, i);
  // Every frame painted, the first included: a recording without a marker (the world founded on its first frame).
  TagSequence bare = painted;
  bare.frames[0].rgbd->colour = bare.frames[0].rgbd->colour.clone();
  evaluation::paintTagsOut(bare, 0);
  runtime::TrackingOptions founded;
  founded.worldFromFirstFrame = true;
  runtime::TrackingOptions fine;
  fine.odometry.maxWidth = inView.intrinsics.width;
  struct Row {
    std::string name;
    const TagSequence* seq;
    std::function<Trajectory()> run;
  };
  const auto ours = [&](const TagSequence& s, runtime::PoseMode mode, const runtime::TrackingOptions& to) {
    return [&s, mode, to, id = o.markerId] { return evaluation::trackedTrajectory(s, mode, id, to); };
  };
  const std::string full = "its finest level at " + std::to_string(inView.intrinsics.width) + " px";
  const std::vector<Row> rows = {
      {"the board's own poses (the harness's floor)", &inView, [&] { return evaluation::boardTrajectory(inView); }},
      {"ours, --pose odometry, tags painted out", &painted, ours(painted, runtime::PoseMode::Odometry, {})},
      {"ours, --pose odometry, tags painted out, " + full, &painted, ours(painted, runtime::PoseMode::Odometry, fine)},
      {"ours, --pose tracked, tags painted out", &painted, ours(painted, runtime::PoseMode::Tracked, {})},
      {"Open3D colour term, tags painted out", &painted, [&] { return evaluation::open3dTrajectory(painted, false); }},
      {"Open3D hybrid term, tags painted out", &painted, [&] { return evaluation::open3dTrajectory(painted, true); }},
      {"ours, --pose odometry, every frame painted (no marker)", &bare,
       ours(bare, runtime::PoseMode::Odometry, founded)},
      {"Open3D colour term, every frame painted", &bare, [&] { return evaluation::open3dTrajectory(bare, false); }},
      {"Open3D hybrid term, every frame painted", &bare, [&] { return evaluation::open3dTrajectory(bare, true); }},
      {"ours, --pose tracked, tags in view", &inView, ours(inView, runtime::PoseMode::Tracked, {})},
      {"Open3D hybrid term, tags in view", &inView, [&] { return evaluation::open3dTrajectory(inView, true); }},
  };
  nlohmann::json j = {{"sequence", o.input}, {"frames", inView.frames.size()}, {"rows", nlohmann::json::array()}};
  if (!o.json)
    std::printf(
        "%s, frames 0-%zu: the tags' centres placed from frame 0, drawn in frames 1-%zu\n\n"
        "| poses | RMS (px) | 95th percentile (px) | max (px) | frames tracked | ms a frame |\n"
        "|---|---|---|---|---|---|\n",
        o.input.c_str(), inView.frames.size() - 1, inView.frames.size() - 1);
  for (const Row& r : rows) {
    const auto start = std::chrono::steady_clock::now();
    const Trajectory poses = r.run();
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() /
                      static_cast<double>(r.seq->frames.size());
    const evaluation::TagPixelError e = evaluation::tagPixelError(*r.seq, poses);
    if (o.json) {
      j["rows"].push_back({{"poses", r.name},
                           {"rms_px", e.rmsPx},
                           {"p95_px", e.p95Px},
                           {"max_px", e.maxPx},
                           {"frames", e.frames},
                           {"tracked", e.tracked},
                           {"ms_per_frame", ms},
                           {"frame_rms_px", e.frameRmsPx}});
    } else {
      std::printf("| %s | %.2f | %.2f | %.2f | %d of %d | %.0f |\n", r.name.c_str(), e.rmsPx, e.p95Px, e.maxPx,
                  e.tracked, e.frames, ms);
    }
  }
  if (o.json) std::printf("%s\n", j.dump().c_str());
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
