#pragma once
// `mrgi reference`: the path-traced ground truth of one frame, rendered from the same inputs the real-time
// techniques see (measured real mesh and albedo, the scene's objects and lights): rho, mu, their delta, the mask
// and the reference composite, with reference.json.
#include <cstdint>
#include <string>

#include "runtime/pose_source.h"

namespace mrgi::evaluation {

struct ReferenceOptions {
  /// The recording, the scene file, the output folder.
  std::string source, scene, out;
  int frame = 0;
  int spp = 64;
  int bounces = 3;
  uint64_t seed = 1;
  int threads = 0;
  runtime::PoseMode pose = runtime::PoseMode::Tracked;
  int meshStride = 2;
};
/// Renders frame `frame` and writes it into `out`; returns 0. Throws when the frame is missing or has no pose.
int renderReferenceFrame(const ReferenceOptions& o);

}  // namespace mrgi::evaluation
