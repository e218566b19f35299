// mrgi track-pixels: tracking measured in pixels on a real ViSP RGB-D AprilTag sequence
// (evaluation/tag_pixels.h): the tags' centres placed from the first frame and drawn with each way of tracking
// the camera, against where every later frame shows them; with the tags painted out after the first frame, and
// Open3D's legacy RGB-D odometry through the same harness beside ours.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "evaluation/tag_pixels.h"
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

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
  const TagSequence inView = evaluation::loadTagSequence(o.input, o.frames);
  TagSequence painted = inView;
  for (capture::Frame& f : painted.frames) f.rgbd->colour = f.rgbd->colour.clone();  // its own pixels to paint
  for (size_t i = 1; i < painted.frames.size(); ++i) evaluation::paintTagsOut(painted, i);
  if (getenv("DBGPAINT")) {
    cv::Mat bgr;
    cv::cvtColor(painted.frames[std::atoi(getenv("DBGPAINT"))].rgbd->colour, bgr, cv::COLOR_RGB2BGR);
    cv::imwrite("/tmp/painted.png", bgr);
  }
  struct Row {
    const char* name;
    const TagSequence* seq;
    std::vector<std::optional<capture::Pose>> poses;
  };
  std::vector<Row> rows;
  rows.push_back({"the board's own poses (the harness's floor)", &inView, evaluation::boardTrajectory(inView)});
  rows.push_back({"ours, --pose odometry, tags painted out", &painted,
                  evaluation::trackedTrajectory(painted, runtime::PoseMode::Odometry, o.markerId)});
  rows.push_back({"ours, --pose tracked, tags painted out", &painted,
                  evaluation::trackedTrajectory(painted, runtime::PoseMode::Tracked, o.markerId)});
  rows.push_back({"Open3D colour term, tags painted out", &painted, evaluation::open3dTrajectory(painted, false)});
  rows.push_back({"Open3D hybrid term, tags painted out", &painted, evaluation::open3dTrajectory(painted, true)});
  rows.push_back({"ours, --pose tracked, tags in view", &inView,
                  evaluation::trackedTrajectory(inView, runtime::PoseMode::Tracked, o.markerId)});
  rows.push_back({"Open3D hybrid term, tags in view", &inView, evaluation::open3dTrajectory(inView, true)});
  nlohmann::json j = {{"sequence", o.input}, {"frames", inView.frames.size()}, {"rows", nlohmann::json::array()}};
  if (!o.json)
    std::printf("%s, frames 0-%zu: the tags' centres placed from frame 0, drawn in frames 1-%zu\n\n"
                "| poses | RMS (px) | 95th percentile (px) | max (px) | frames tracked |\n|---|---|---|---|---|\n",
                o.input.c_str(), inView.frames.size() - 1, inView.frames.size() - 1);
  for (const Row& r : rows) {
    const evaluation::TagPixelError e = evaluation::tagPixelError(*r.seq, r.poses);
    if (o.json) {
      j["rows"].push_back({{"poses", r.name},
                           {"rms_px", e.rmsPx},
                           {"p95_px", e.p95Px},
                           {"max_px", e.maxPx},
                           {"frames", e.frames},
                           {"tracked", e.tracked},
                           {"frame_rms_px", e.frameRmsPx}});
    } else {
      std::printf("| %s | %.2f | %.2f | %.2f | %d of %d |\n", r.name, e.rmsPx, e.p95Px, e.maxPx, e.tracked, e.frames);
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
