#include "gl/profiler.h"

#include <algorithm>
#include <stdexcept>

namespace mrgi::gl {
namespace {
QueryHandle timestampNow() {
  GLuint id = 0;
  glCreateQueries(GL_TIMESTAMP, 1, &id);
  glQueryCounter(id, GL_TIMESTAMP);
  return QueryHandle(id);
}
}  // namespace

Profiler::Scope::Scope(Profiler& p, std::string name, bool gpu) : profiler_(p), index_(p.pending_.size()) {
  if (gpu && p.finish_) glFinish();
  Pending entry{std::move(name), gpu, std::chrono::steady_clock::now(), {}, {}, {}};
  if (gpu) entry.begin = timestampNow();
  p.pending_.push_back(std::move(entry));
}

Profiler::Scope::~Scope() {
  Pending& e = profiler_.pending_[index_];
  if (e.gpu) e.end = timestampNow();
  if (e.gpu && profiler_.finish_) glFinish();
  e.cpuEnd = std::chrono::steady_clock::now();
}

std::map<std::string, StageTime> Profiler::times(const std::vector<Pending>& stages) {
  std::map<std::string, StageTime> out;
  for (const Pending& e : stages) {
    StageTime& t = out[e.name];
    t.cpuMs += std::chrono::duration<double, std::milli>(e.cpuEnd - e.cpuBegin).count();
    if (e.gpu && e.begin && e.end) {
      GLuint64 b = 0, en = 0;
      glGetQueryObjectui64v(e.begin.id(), GL_QUERY_RESULT, &b);
      glGetQueryObjectui64v(e.end.id(), GL_QUERY_RESULT, &en);
      t.gpuMs += en > b ? static_cast<double>(en - b) * 1e-6 : 0.0;
    }
  }
  return out;
}

std::map<std::string, StageTime> Profiler::resolve() {
  if (std::any_of(pending_.begin(), pending_.end(), [](const Pending& e) { return e.gpu; })) countSynchronousReadback();
  std::map<std::string, StageTime> out = times(pending_);
  pending_.clear();
  return out;
}

void Profiler::adopt(Profiler& other) {
  for (const Pending& e : other.pending_)
    if (e.gpu) throw std::logic_error("Profiler::adopt: stage " + e.name + " has GPU timestamps of another frame loop");
  for (Pending& e : other.pending_) pending_.push_back(std::move(e));
  other.pending_.clear();
}

uint64_t Profiler::endFrame() {
  ended_.emplace_back(frames_, std::move(pending_));
  pending_.clear();
  return frames_++;
}

std::vector<Profiler::FrameTimes> Profiler::collect(bool wait) {
  const auto arrived = [](const Pending& e) {
    if (!e.gpu || !e.begin || !e.end) return true;
    GLuint64 available = 0;
    glGetQueryObjectui64v(e.end.id(), GL_QUERY_RESULT_AVAILABLE, &available);
    if (available) glGetQueryObjectui64v(e.begin.id(), GL_QUERY_RESULT_AVAILABLE, &available);
    return available != 0;
  };
  std::vector<FrameTimes> out;
  size_t done = 0;
  for (; done < ended_.size(); ++done) {
    const auto& [frame, stages] = ended_[done];
    const bool ready = std::all_of(stages.begin(), stages.end(), arrived);
    if (!ready && !wait) break;  // timestamps arrive in order: later frames are not ready either
    if (!ready) countSynchronousReadback();
    std::vector<std::string> order;
    for (const Pending& p : stages)
      if (std::find(order.begin(), order.end(), p.name) == order.end()) order.push_back(p.name);
    out.push_back({frame, times(stages), std::move(order)});
  }
  ended_.erase(ended_.begin(), ended_.begin() + static_cast<std::ptrdiff_t>(done));
  return out;
}

}  // namespace mrgi::gl
