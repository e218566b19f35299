#include "runtime/read_ahead.h"

#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>
#include <utility>

#include "runtime/frame_pipeline.h"

namespace mrgi::runtime {
namespace {

/// One thread, kept for the process's life, that reads and prepares the frames read ahead, one after the other.
/// What a thread keeps between its tasks stays warm from frame to frame: the guided filter's scratch images, and
/// the OpenMP team Open3D's odometry and fusion start from it (an OpenMP team belongs to the thread that starts
/// it and goes with that thread: a thread a frame started and ended a team a frame, and faulted in its memory).
class PrepareThread {
 public:
  PrepareThread() : thread_([this] { loop(); }) {}
  /// Runs `task` on the thread and returns when it is done (its exception rethrown here).
  template <typename T>
  T run(std::function<T()> task) {
    // The queued job owns the task: its shared state outlives the moment get() below returns, while the thread
    // may still be inside the task's call.
    auto job = std::make_shared<std::packaged_task<T()>>(std::move(task));
    std::future<T> done = job->get_future();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      jobs_.emplace_back([job] { (*job)(); });
    }
    wake_.notify_one();
    return done.get();
  }

 private:
  [[noreturn]] void loop() {
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return !jobs_.empty(); });
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      job();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> jobs_;
  std::thread thread_;  // last: started once the members it reads exist
};

/// Never destroyed: the process's exit ends the thread, which may be waiting on a device that no longer answers
/// (joining it there could hang the exit).
PrepareThread& prepareThread() {
  static PrepareThread* thread = new PrepareThread;
  return *thread;
}

}  // namespace

std::future<FrameAhead> readAhead(std::function<std::optional<capture::Frame>()> next, FramePipeline* pipeline) {
  // std::async's future waits for its task when dropped, so nothing the task refers to can go first; the task
  // itself runs on the prepare thread.
  return std::async(std::launch::async, [next = std::move(next), pipeline] {
    return prepareThread().run<FrameAhead>([&] {
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
  });
}

}  // namespace mrgi::runtime
