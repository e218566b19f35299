#include "runtime/read_ahead.h"

#include <utility>

#include "runtime/frame_pipeline.h"

namespace mrgi::runtime {

std::future<FrameAhead> readAhead(std::function<std::optional<capture::Frame>()> next, FramePipeline* pipeline) {
  return std::async(std::launch::async, [next = std::move(next), pipeline] {
    FrameAhead a;
    a.frame = next();
    a.in = std::chrono::steady_clock::now();
    if (a.frame && a.frame->rgbd && pipeline) {
      a.arrived = *a.frame;  // shares the images: registration replaces the depth, never writes into it
      a.stages = std::make_unique<gl::Profiler>();
      a.prepared = pipeline->prepare(*a.frame, *a.stages);
    }
    return a;
  });
}

}  // namespace mrgi::runtime
