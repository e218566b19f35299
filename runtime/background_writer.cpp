#include "runtime/background_writer.h"

#include <algorithm>
#include <chrono>

namespace mrgi::runtime {

namespace {
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

BackgroundWriter::BackgroundWriter(size_t capacity) : capacity_(std::max<size_t>(1, capacity)) {
  worker_ = std::thread([this] { run(); });
}

BackgroundWriter::~BackgroundWriter() {
  {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [this] { return (queue_.empty() && !running_) || error_; });
    stop_ = true;
  }
  changed_.notify_all();
  worker_.join();
}

void BackgroundWriter::rethrow() {
  if (error_) std::rethrow_exception(error_);
}

void BackgroundWriter::push(std::function<void()> write) {
  const auto t0 = std::chrono::steady_clock::now();
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [this] { return queue_.size() < capacity_ || error_; });
  blocked_ += since(t0);
  rethrow();
  queue_.push_back(std::move(write));
  peak_ = std::max(peak_, queue_.size());
  lock.unlock();
  changed_.notify_all();
}

void BackgroundWriter::finish() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [this] { return (queue_.empty() && !running_) || error_; });
  rethrow();
}

size_t BackgroundWriter::peakQueued() const {
  std::lock_guard lock(mutex_);
  return peak_;
}

double BackgroundWriter::blockedSeconds() const {
  std::lock_guard lock(mutex_);
  return blocked_;
}

double BackgroundWriter::busySeconds() const {
  std::lock_guard lock(mutex_);
  return busy_;
}

void BackgroundWriter::run() {
  for (;;) {
    std::function<void()> write;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [this] { return !queue_.empty() || stop_; });
      if (queue_.empty()) return;  // stop_ and nothing left
      write = std::move(queue_.front());
      queue_.pop_front();
      running_ = true;
    }
    changed_.notify_all();  // a slot is free
    const auto t0 = std::chrono::steady_clock::now();
    std::exception_ptr error;
    try {
      write();
    } catch (...) {
      error = std::current_exception();
    }
    {
      std::lock_guard lock(mutex_);
      busy_ += since(t0);
      running_ = false;
      if (error && !error_) {
        error_ = error;
        queue_.clear();  // nothing after a failed write: the output would have a gap
      }
    }
    changed_.notify_all();
  }
}

}  // namespace mrgi::runtime
