#include "gl/profiler.h"

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

std::map<std::string, StageTime> Profiler::resolve() {
  std::map<std::string, StageTime> out;
  for (Pending& e : pending_) {
    StageTime& t = out[e.name];
    t.cpuMs += std::chrono::duration<double, std::milli>(e.cpuEnd - e.cpuBegin).count();
    if (e.gpu && e.begin && e.end) {
      GLuint64 b = 0, en = 0;
      glGetQueryObjectui64v(e.begin.id(), GL_QUERY_RESULT, &b);
      glGetQueryObjectui64v(e.end.id(), GL_QUERY_RESULT, &en);
      t.gpuMs += en > b ? static_cast<double>(en - b) * 1e-6 : 0.0;
    }
  }
  pending_.clear();
  return out;
}

}  // namespace mrgi::gl
