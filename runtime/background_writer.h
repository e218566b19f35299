#pragma once
/// Output writes (PNG/EXR encoding, video frames) on one worker thread, in the order they were pushed, so
/// that encoding frame n overlaps the work on frame n + 1. At most `capacity` writes wait: push() blocks
/// while the queue is full, so a slow disk slows the frame loop instead of growing memory. A write that
/// throws stops the worker; its error is rethrown by the next push() or by finish(), and the writes queued
/// after it are dropped (what was written before it stays complete: each write is atomic on its own).
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace mrgi::runtime {

class BackgroundWriter {
 public:
  explicit BackgroundWriter(size_t capacity = 4);
  /// Finishes the queued writes; an error is not rethrown here (call finish() to see it).
  ~BackgroundWriter();
  BackgroundWriter(const BackgroundWriter&) = delete;
  BackgroundWriter& operator=(const BackgroundWriter&) = delete;

  /// Queues a write (it owns what it writes: copy images into it). Blocks while `capacity` writes wait;
  /// rethrows an earlier write's error.
  void push(std::function<void()> write);
  /// Waits until every queued write is done; rethrows the first error. The writer stays usable.
  void finish();
  /// The most writes that were waiting at once, and the seconds push() spent blocked on a full queue.
  size_t peakQueued() const;
  double blockedSeconds() const;
  /// Seconds the worker spent in writes.
  double busySeconds() const;

 private:
  void run();
  void rethrow();

  const size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::function<void()>> queue_;
  bool running_ = false;  ///< the worker is in a write
  bool stop_ = false;
  std::exception_ptr error_;
  size_t peak_ = 0;
  double blocked_ = 0, busy_ = 0;
  std::thread worker_;
};

}  // namespace mrgi::runtime
