#pragma once
/// Opening a recording or device for a command: capture::open, and the one line a user needs when the
/// source falls back to a default (a folder without its camera's calibration), said once per source.
#include <memory>
#include <optional>
#include <string>

#include "capture/frame_source.h"

namespace mrgi::runtime {

std::unique_ptr<capture::FrameSource> openSource(const std::string& uri, const capture::OpenOptions& options = {});

/// Says `note` on stderr as one "note: ..." line, once per process (the same note again is not repeated).
void sayNoteOnce(const std::string& note);

/// Where the source's ground-truth poses place the lighting world (the marker frame): a session's manifest
/// says (ground_truth.T_world_marker); a folder without a manifest whose frames carry poses (a TUM
/// groundtruth.txt, an Open3D trajectory.log) has its poses' own world as the world; else none.
std::optional<capture::Pose> groundTruthT_world_marker(const capture::FrameSource& source);

}  // namespace mrgi::runtime
