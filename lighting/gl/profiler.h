#pragma once
/// Per-pass GPU timings with timestamp queries (GL_TIMESTAMP, so scopes may nest), plus CPU wall time,
/// collected under stable names ("gbuffer", "rsm", "dlpv.propagate", ...).
#include <chrono>
#include <map>
#include <string>
#include <vector>

#include "gl/objects.h"

namespace mrgi::gl {

struct StageTime {
  double gpuMs = 0.0;  ///< GPU time between the scope's begin and end timestamps (0 for CPU-only stages)
  double cpuMs = 0.0;  ///< CPU wall time of the scope
};

class Profiler {
 public:
  /// finishEachStage: every GPU scope waits for the GPU at its begin and end (glFinish), so its CPU wall
  /// time is the stage's own work. On a software rasteriser (llvmpipe) timestamps of compute dispatches and
  /// draws are taken when its deferred queue reaches them, and a stage's timestamps can bracket an earlier
  /// stage's work; benchmarks that attribute time to stages turn this on. It serialises CPU and GPU.
  explicit Profiler(bool finishEachStage = false) : finish_(finishEachStage) {}

  class Scope {
   public:
    Scope(Profiler& p, std::string name, bool gpu);
    ~Scope();
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    Profiler& profiler_;
    size_t index_;
  };

  /// Times a stage on the GPU and the CPU; the result is available after resolve().
  Scope gpu(std::string name) { return Scope(*this, std::move(name), true); }
  /// Times a CPU-only stage.
  Scope cpu(std::string name) { return Scope(*this, std::move(name), false); }

  /// Waits for this frame's queries and returns the stage times (summed over repeated names), then
  /// starts a new frame. The map is ordered by name. Waiting is a synchronous readback.
  std::map<std::string, StageTime> resolve();

  /// The frame loop's way, which never waits for the GPU: ends this frame (its number is returned, from 0)
  /// and keeps its stages until their timestamps have arrived; collect() hands over the ended frames whose
  /// timestamps all have, oldest first (typically the previous frame's, a frame late), or with wait = true
  /// every ended frame (at the end of a run: a synchronous readback).
  struct FrameTimes {
    uint64_t frame = 0;
    std::map<std::string, StageTime> stages;
    std::vector<std::string> order;  ///< the stages' names in the order they first began (adopted ones last)
  };
  uint64_t endFrame();
  /// Moves the stages another profiler timed into this frame: the CPU stages of work done for it on another
  /// thread (which times them with a profiler of its own; a GPU stage there is a logic error).
  void adopt(Profiler& other);
  std::vector<FrameTimes> collect(bool wait);

 private:
  struct Pending {
    std::string name;
    bool gpu;
    std::chrono::steady_clock::time_point cpuBegin, cpuEnd;
    QueryHandle begin, end;
  };
  static std::map<std::string, StageTime> times(const std::vector<Pending>& stages);
  std::vector<Pending> pending_;
  std::vector<std::pair<uint64_t, std::vector<Pending>>> ended_;  ///< frames waiting for their timestamps
  uint64_t frames_ = 0;
  bool finish_ = false;
};

}  // namespace mrgi::gl
