#pragma once
// A frame loop's next frame, read (and prepared) on a worker thread while the loop renders the current one.
#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <optional>

#include "capture/types.h"
#include "gl/profiler.h"
#include "runtime/frame_data.h"

namespace mrgi::runtime {

class FramePipeline;

/// A frame read ahead of a frame loop on a worker thread, and prepared there when a pipeline was given.
struct FrameAhead {
  std::optional<capture::Frame> frame;       ///< nullopt at the end of the source
  std::optional<capture::Frame> arrived;     ///< as read, before preparing registered its depth (shares the images)
  std::chrono::steady_clock::time_point in;  ///< when it was read and decoded
  std::optional<PreparedFrame> prepared;     ///< FramePipeline::prepare's result
  std::unique_ptr<gl::Profiler> stages;      ///< the CPU stages of preparing it (gl::Profiler::adopt)
};
/// Reads the next frame with `next` on a worker thread and, with `pipeline`, prepares it there (the caller
/// prepares nothing else with that pipeline until the result is taken). A read error surfaces at get().
std::future<FrameAhead> readAhead(std::function<std::optional<capture::Frame>()> next, FramePipeline* pipeline);

}  // namespace mrgi::runtime
