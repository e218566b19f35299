#include "runtime/source.h"

#include <cstdio>
#include <mutex>
#include <set>

#include "capture/session.h"

namespace mrgi::runtime {

std::unique_ptr<capture::FrameSource> openSource(const std::string& uri, const capture::OpenOptions& options) {
  auto source = capture::open(uri, options);
  if (!source->info().calibrationNote.empty()) sayNoteOnce(source->info().calibrationNote);
  return source;
}

void sayNoteOnce(const std::string& note) {
  static std::mutex mutex;
  static std::set<std::string> said;
  const std::lock_guard<std::mutex> lock(mutex);
  if (said.insert(note).second) std::fprintf(stderr, "note: %s\n", note.c_str());
}

std::optional<capture::Pose> groundTruthT_world_marker(const capture::FrameSource& source) {
  if (const capture::SessionManifest* manifest = source.sessionManifest()) return manifest->truth.T_world_marker;
  if (source.info().hasGroundTruth) return capture::identityPose();
  return std::nullopt;
}

}  // namespace mrgi::runtime
