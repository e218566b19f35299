#pragma once
// Tracking measured where the user sees it: in pixels. A ViSP RGB-D AprilTag sequence (a board of tags on a desk,
// its tags detected in every frame and the board's pose per frame, apriltag_data.json) places the tags' centres
// once, from the first frame (its detected centres on the board's plane), and draws them with a trajectory's
// poses in every later frame; the error is how far they land from where the frame itself shows them. With the
// tags painted out of every frame after the first (only where the depth lies on the board, so what stands in
// front keeps its colour), nothing but the desk's own texture and shape can carry the pose: a marker-less
// recording. Open3D's legacy RGB-D odometry (frame to frame, its defaults) runs through the same harness as the
// peer.
#include <array>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/types.h"
#include "runtime/pose_source.h"

namespace mrgi::evaluation {

struct TagSequence {
  std::string path;
  std::vector<capture::Frame> frames;  ///< colour and registered depth (metres), in order
  capture::Intrinsics intrinsics;
  double tagSize = 0;
  /// Per frame, each detected tag's four corners (pixels x, y, the detector's order; the file stores them as
  /// row, column).
  std::vector<std::map<int, std::array<cv::Point2d, 4>>> corners;
  /// Per frame, the board's pose (camera from board; its plane is z = 0), from all its tags at once.
  std::vector<capture::Pose> T_camera_board;
};

/// Reads a ViSP RGB-D AprilTag folder (color_image_NNNN.png, depth_image_NNNN.npz, cam.json,
/// apriltag_data.json's tag_size, grid and detections), at most `maxFrames` frames (0: all with images).
/// Throws capture::CaptureError naming the file for anything missing or malformed.
TagSequence loadTagSequence(const std::string& dir, int maxFrames = 0);

/// The projective centre of a tag: where its quad's diagonals cross.
cv::Point2d tagCentre(const std::array<cv::Point2d, 4>& corners);

/// Paints every tag of the board out of frame `i` (i.e. its colour): each tag's quad with its white border
/// (the quads of every tag the sequence ever detected, carried by the board's pose into this frame, and the
/// board's grid filled out with the tags never detected), filled with the board's own colour, only where the
/// depth lies within 3 cm of the board's plane (the sensor's offset from it removed) or is missing. Returns the
/// pixels painted.
int paintTagsOut(TagSequence& seq, size_t i);
/// The same with the board's tag quads (board frame, metres) computed once for the sequence (boardTagQuads).
int paintTagsOut(TagSequence& seq, size_t i, const std::vector<std::array<cv::Vec3d, 4>>& quads);
/// Every tag's quad on the board (board frame, metres): each detected tag's corners from every frame that saw it,
/// averaged, and the board's grid filled out with the tags never detected.
std::vector<std::array<cv::Vec3d, 4>> boardTagQuads(const TagSequence& seq);

struct TagPixelError {
  int frames = 0;   ///< frames after the first with at least one tag detected
  int tracked = 0;  ///< of those, the frames with a pose
  int samples = 0;  ///< tag centres compared
  double rmsPx = 0, p95Px = 0, maxPx = 0;
  std::vector<double> frameRmsPx;  ///< per frame after the first (-1: lost or no tag)
};

/// `T_world_camera[i]` (nullopt: lost) for every frame of `seq`, in any one world: the tags' centres of frame 0,
/// on the board's plane there, drawn in each later frame against that frame's detected centres.
TagPixelError tagPixelError(const TagSequence& seq, const std::vector<std::optional<capture::Pose>>& T_world_camera);

/// Open3D's legacy RGB-D odometry (pipelines::odometry::ComputeRGBDOdometry, its default options and
/// pyramid), frame to frame from the first, chained: `hybrid` its hybrid Jacobian, else its colour term. A
/// frame it fails on keeps the previous motion's pose (identity step).
std::vector<std::optional<capture::Pose>> open3dTrajectory(const TagSequence& seq, bool hybrid);

/// The product's own poses of every frame of `seq`, in order, by `mode` (the marker: the sequence's tag of
/// `markerId`, which anchors the world on the first frame it is seen). `fuseRefresh` > 0: each posed frame is fused
/// into a room as it comes and the frames are aligned with its surface first (frame to model, as replay
/// --fuse-room --track-room does), the surface taken anew every `fuseRefresh` fused frames.
std::vector<std::optional<capture::Pose>> trackedTrajectory(const TagSequence& seq, runtime::PoseMode mode,
                                                            int markerId = 3,
                                                            const runtime::TrackingOptions& options = {},
                                                            int fuseRefresh = 0);

/// The board's own poses (camera to board): what the harness gives when the poses are exact up to the board's
/// detection (its floor).
std::vector<std::optional<capture::Pose>> boardTrajectory(const TagSequence& seq);

/// One way of tracking measured by the harness.
struct TagPixelRow {
  std::string poses;  ///< what placed the camera, on which frames (tags in view, painted out after frame 0, ...)
  TagPixelError error;
  double msPerFrame = 0;  ///< its wall time over the sequence's frames (in memory), per frame
};

/// The harness's table on a ViSP tag sequence: the sequence's folder, its frames read, a row per way of tracking.
struct TagPixelTable {
  std::string sequence;
  size_t frames = 0;
  std::vector<TagPixelRow> rows;
};

/// The harness's table on a ViSP tag sequence (its first `frames` frames, 0: all; the world anchored by tag
/// `markerId`): the board's own poses (the floor); ours (--pose odometry, the same at the frame's full width,
/// --pose tracked, --pose odometry against the room as it is fused) and Open3D's colour and hybrid terms with the
/// tags painted out after frame 0; ours and Open3D's with every frame painted (no marker: the world founded on
/// frame 0); ours tracked and Open3D's hybrid with the tags in view.
TagPixelTable tagPixelTable(const std::string& dir, int frames = 0, int markerId = 3);

/// {"sequence", "frames", "rows": [{poses, rms_px, p95_px, max_px, frames, tracked, ms_per_frame, frame_rms_px}]}
nlohmann::json tagPixelJson(const TagPixelTable& table);

}  // namespace mrgi::evaluation
