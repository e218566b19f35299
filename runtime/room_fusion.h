#pragma once
// Fusing a recording into the room model (mrgi room, bench --room): every frame's filtered depth at its
// camera pose (runtime/pose_source.h) into a RoomModel in the marker frame. Frames without a trusted pose
// (lost, or the marker's held pose) are refused, never fused at a guess.
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "capture/frame_source.h"
#include "reconstruction/pose_graph.h"
#include "reconstruction/room_model.h"
#include "runtime/frame_pipeline.h"
#include "runtime/session_setup.h"

namespace mrgi::runtime {

struct RoomFusion {
  reconstruction::RoomModel model;
  int64_t frames = 0, posed = 0;
  /// Frames refused for their pose: lost, or held (the marker's last pose kept while unseen).
  int64_t lost = 0, held = 0;
  std::vector<double> fuseMs;     ///< per integrated-or-refused frame with a pose
  std::vector<double> surfaceMs;  ///< the same frames: depth filter and normals + fusion
  nlohmann::json perFrame =
      nlohmann::json::array();  ///< frame, integrated, refused, overlap, inconsistent, new_blocks, fuse_ms
  /// Each measured frame's camera-to-world pose as it was fused (nullopt: refused for its pose).
  std::vector<std::optional<capture::Pose>> poses;
  /// The optimised trajectory's facts (edges, pruned, how far frames moved), when it was optimised; else null.
  nlohmann::json trajectory;
  /// When it was optimised: each measured frame's pose as the tracker gave it before (nullopt: lost or held).
  std::vector<std::optional<capture::Pose>> trackerPoses;
  /// Frames read whose colour has more than kClippedShare of its pixels at the sensor's white (a sunlit patch, a
  /// lamp, a window), and the largest share of any frame: there the room's radiance reads lower than it is.
  int64_t clippedFrames = 0;
  double mostClipped = 0;
  static constexpr double kClippedShare = 0.02;
  /// One line for the user when frames clipped ("" when none did).
  std::string clippingNote(const std::string& path) const;
  /// Median of fuseMs (0 without any).
  double medianFuseMs() const;
  /// Median of surfaceMs: a frame's whole real-surface cost (filter, normals, fusion, appearance).
  double medianSurfaceMs() const;
};

struct RoomFusionOptions {
  PoseMode pose = PoseMode::Tracked;
  capture::OpenOptions open;  ///< a folder's calibration and depth scale
  reconstruction::RoomOptions room;
  int64_t limit = -1;  ///< frames read (< 0: all)
  int every = 1;       ///< every `every`-th frame is integrated
  /// With odometry or tracked poses, every `trackEvery` fused frames (0: never) the room's surface becomes
  /// what the next frames are aligned with (frame-to-model).
  int trackEvery = 0;
  /// With odometry or tracked poses: the whole trajectory optimised before anything is fused (a pose graph of
  /// odometry, loop-closure and marker edges: reconstruction/pose_graph.h), the recording read twice. Not
  /// with trackEvery (frame-to-model against the room fused so far needs the poses as the frames come).
  bool optimise = true;
  reconstruction::TrajectoryOptions trajectory;
};

/// Fuses the recording at `path` (opened with capture::open; opened again for an optimised trajectory).
/// `onFrame` (optional) sees each frame's line as it is decided.
RoomFusion fuseRoom(
    const std::string& path, const RoomFusionOptions& options,
    const std::function<void(const nlohmann::json& line, const reconstruction::RoomModel& model)>& onFrame = {});

/// Whether a scene resolved as `setup` is lit by the room of a recording fused whole before its first frame
/// (fuseWholeRecording): its lights come from the room, no saved room is given (`roomGiven`), and the room is
/// fused by default, neither asked for as the frames come (--fuse-room) nor left to each frame's own depth.
bool fusesRecordingFirst(const LightingSetup& setup, const RoomOptions& rooms, bool roomGiven);

/// The room a recording shows, fused from all its frames before any is lit: what a scene that leaves its lights to
/// the room ("lights": "auto" without lights listed, or "room") is lit by in replay, in insert's preview and in the
/// live window playing a recording, so the three light the same frame alike and frame 0 is lit by the whole room,
/// not by what frame 0 alone saw. `onFrame` as fuseRoom's. Throws naming the recording when no surface could be
/// fused; `fused` (optional) receives the fusion's facts.
std::shared_ptr<const reconstruction::RoomMesh> fuseWholeRecording(
    const std::string& path, PoseMode pose, const capture::OpenOptions& open, RoomFusion* fused = nullptr,
    const std::function<void(const nlohmann::json& line, const reconstruction::RoomModel& model)>& onFrame = {});

/// Writes a fused room as mrgi room does (room.ply, room_appearance.npy, room.json naming `session`); the
/// mesh is returned (empty, and nothing written, when the room has no surface).
reconstruction::RoomMesh saveRoomModel(const std::string& dir, const reconstruction::RoomModel& room,
                                       const std::string& session);

}  // namespace mrgi::runtime
