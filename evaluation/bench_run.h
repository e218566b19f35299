#pragma once
// The bench's harness (`mrgi bench`): per session, its frames, the path-traced references of the inputs the
// pipeline sees and the session's own true references; every configuration of the sweep measured against them
// (evaluation/bench.h: the configurations, presets and report), or one technique's sparse method against its
// brute force. Progress and results are printed on stdout as they come.
#include <string>
#include <vector>

#include "runtime/pose_source.h"

namespace mrgi::evaluation {

struct BenchOptions {
  std::string technique;  ///< empty: all (reference mode)
  std::string against = "reference";
  std::string json, csv, html, presets;
  std::string gallery;  ///< folder: per session, every technique's crop around the objects beside the reference's
  std::string scene;    ///< empty: per session, the scene of its true references, else recordings/scenes/tabletop.json
  int frames = 4;
  int refFrames = 2;
  int refSpp = 64;
  int refFocusSpp = 0;  ///< samples per pixel near the objects (groundtruth::virtualFocus); 0: 16 x refSpp
  int refBounces = 3;
  bool quick = false;
  bool room = false;  ///< also light from each session's fused room model, side by side
  /// A ViSP RGB-D tag sequence: the tracking table in pixels on its real frames, ours beside Open3D's odometry
  /// (evaluation/tag_pixels.h), in the JSON ("tracking_pixels") and the report. Empty: none.
  std::string trackingPixels;
  runtime::PoseMode pose = runtime::PoseMode::GroundTruth;
  std::vector<std::string> sessions{"recordings/tabletop-synth", "recordings/tabletop-pt", "recordings/tabletop-hdr"};
  // --against bruteforce: on the first session's first frame
  std::string model = "recordings/models/sphere.ply";
  std::vector<int> valCounts{1024, 4096, 16384, 65536};
  std::vector<int> sparseCounts{256, 1024, 4096};
  int kCache = 128;
  int repeats = 3;
  double scale = 0.06;
  std::string occlusion = "both";
  std::string gl = "osmesa";
};

/// Runs the bench: against the path-traced reference (the sweep, its records, report, presets and gallery as
/// the options name them) or, with against = "bruteforce", the technique's sparse method against its brute
/// force on the first session's first frame. Returns the process exit code; throws for bad input.
int runBench(const BenchOptions& o);

}  // namespace mrgi::evaluation
