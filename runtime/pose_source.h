#pragma once
// Where each frame's camera pose comes from: one seam for every command that places a camera (replay, live,
// insert, room, reference, bench, track). The world is the marker frame wherever a marker anchors it.
//
//   marker        the tracked AprilTag alone (smoothed, held briefly, then lost)
//   ground-truth  the session's own poses (synthetic sessions)
//   odometry      the marker anchors the world on the first frame it is seen, and is never used again:
//                 dense RGB-D odometry carries the pose from there (what it drifts is what it measures)
//   tracked       odometry between marker sightings; a sighting corrects the pose a little per frame (no
//                 jump of the object), or places it outright after a loss; a lost frame is relocalised
//                 against keyframes (ORB features and depth, PnP RANSAC) or by the marker
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/types.h"
#include "gl/profiler.h"
#include "reconstruction/odometry.h"
#include "reconstruction/room_model.h"

namespace mrgi::runtime {

enum class PoseMode { Marker, GroundTruth, Odometry, Tracked };
/// "marker", "ground-truth", "odometry", "tracked": the one spelling of the modes (CLI, JSON).
const std::vector<std::string>& poseModeNames();
const char* toString(PoseMode m);
/// Throws InputError naming `flag` for a name that is not a mode.
PoseMode poseModeFromName(const std::string& name, const std::string& flag = "--pose");
/// --pose's help text, the same in every command.
std::string poseModeHelp();

/// How one frame was posed.
enum class PosedBy { None, Marker, GroundTruth, Odometry, Relocalised, FirstFrame };
const char* toString(PosedBy b);

struct CameraPose {
  /// Camera to world (the marker frame); nullopt when the frame is lost: nothing is drawn at it and nothing
  /// is fused from it.
  std::optional<capture::Pose> T_world_camera;
  PosedBy by = PosedBy::None;
  /// The marker's own state this frame ("tracked", "held", "lost"; "-" when the mode does not look for it).
  std::string marker = "-";
  /// Odometry's quality of this frame when it ran: inliers over pixels with depth, the share of those pixels
  /// the two views have in common, and the inliers' point-to-plane RMSE (metres; scaled to 1 m range:
  /// rangeRmse, reconstruction::OdometryResult); negative when it did not run.
  double fitness = -1, overlap = -1, inlierRmse = -1, rangeRmse = -1;
  void setQuality(const reconstruction::OdometryResult& r) {
    fitness = r.fitness, overlap = r.overlap, inlierRmse = r.inlierRmse, rangeRmse = r.rangeRmse;
  }
  /// What odometry aligned the frame with: "model" (the room seen from the predicted pose), "keyframe" or
  /// "previous" (the frame before); empty when it did not place the frame.
  std::string against;
  /// The camera-to-world pose the marker alone gives this frame, when its tag was seen (unsmoothed): what an
  /// offline optimisation of the trajectory weighs against odometry (reconstruction/pose_graph.h).
  std::optional<capture::Pose> markerT_world_camera;
  /// Marker correction applied to the odometry pose this frame (metres, degrees), when the tag was seen.
  double correctionM = 0, correctionDeg = 0;
  /// The marker placed the pose outright because odometry had slid (TrackingOptions::markerOverrideM); the
  /// correction is then how far it had slid.
  bool markerReset = false;
  bool tracked() const { return T_world_camera.has_value(); }
  /// The marker's last pose kept while its tag is briefly unseen (marker mode): drawn, never fused.
  bool held() const { return by == PosedBy::Marker && marker == "held"; }
  /// "tracked" or "lost".
  const char* status() const { return tracked() ? "tracked" : "lost"; }
  /// The per-frame facts for summaries: status, by, marker, fitness, rmse.
  nlohmann::json facts() const;
};

/// The marker a source carries (its manifest's, or the defaults).
struct MarkerSpec {
  std::string family = "tag36h11";
  double size = 0.16;
  int id = -1;  ///< < 0: the first tag found
};

struct TrackingOptions {
  reconstruction::OdometryOptions odometry;
  /// The quality gate. A frame's odometry is not trusted, and the frame is lost, when `gate` refuses it
  /// (reconstruction::OdometryGate). Past the first frames the gate follows the sensor: a frame is also lost
  /// below `fitnessRatio` times the median inlier share, or above `rmseRatio` times the median range-scaled
  /// RMSE, of the last `qualityWindow` trusted frames (a real sensor's residual is several times a synthetic
  /// one's; a wrong alignment stands out against either).
  reconstruction::OdometryGate gate;
  double fitnessRatio = 0.8, rmseRatio = 1.6;
  int qualityWindow = 15;
  /// A new keyframe is taken when the frame's fitness against the current one (inliers over all its pixels)
  /// drops below this (the view has moved on) or it lies farther than keyframeDistanceM / keyframeAngleDeg
  /// from it.
  double keyframeFitness = 0.8;
  double keyframeDistanceM = 0.15, keyframeAngleDeg = 15.0;
  int maxKeyframes = 64;
  /// The marker's pull on a tracked pose (tracked mode): each sighting moves the pose this fraction of the
  /// way to the marker's, at most maxCorrectionM and maxCorrectionDeg a frame, so a drifted pose is brought
  /// back over a few frames instead of jumping the object. A sighting after a loss places the pose outright.
  double markerGain = 0.1;
  double maxCorrectionM = 0.004, maxCorrectionDeg = 0.4;
  /// A sighting whose disagreement with the tracked pose grew by more than this since the last frame (which
  /// saw the marker too) is not drift (which gathers over the frames the tag is away) but this frame's
  /// alignment having slid and still passed the gate (a near-planar view, a fast step): the marker places
  /// the pose outright, as after a loss.
  double markerOverrideM = 0.03, markerOverrideDeg = 3.0;
  /// ORB relocalisation: at least this many PnP inliers, then confirmed by dense odometry against the keyframe.
  int relocaliseMinInliers = 25;
  /// What a frame is aligned with the room model by (PoseSource::useModel): point to plane, as KinectFusion
  /// does. The room's fused radiance is blurred over its 2 cm voxels: with the intensity term (hybrid) the
  /// poses came out 10 mm off on tabletop-synth, against 1.9 mm by depth alone.
  reconstruction::OdometryMethod modelMethod = reconstruction::OdometryMethod::PointToPlane;
  /// A recording without a marker: when its first frame shows no marker, the world is founded there (z up
  /// along the dominant plane under the view's centre: reconstruction::worldOnDominantPlane) instead of
  /// waiting for a marker. With `firstFrameT_world_camera` (a saved scene's world) the first frame is placed
  /// there and the marker is not looked for: the world is not the marker frame.
  bool worldFromFirstFrame = false;
  std::optional<capture::Pose> firstFrameT_world_camera;
};

class PoseSource {
 public:
  virtual ~PoseSource() = default;
  virtual PoseMode mode() const = 0;
  /// The pose of the next frame (frames in order; depth registered to colour, in metres or millimetres).
  /// `profiler` gets the stages it ran ("marker", "odometry", "relocalise").
  virtual CameraPose locate(const capture::Frame& frame, gl::Profiler& profiler) = 0;
  /// The first frame's pose when the world was founded on it (TrackingOptions::worldFromFirstFrame), else
  /// nullopt: what a saved scene records to place its objects again.
  virtual std::optional<capture::Pose> foundedWorld() const { return std::nullopt; }
  /// The room model in the world (a saved room): odometry then aligns each frame with the room as seen from
  /// the predicted pose first (frame-to-model), the keyframes after. Null: keyframes only.
  virtual void useModel(std::shared_ptr<const reconstruction::RoomMesh> room) {}
};

/// `T_world_marker`: the session's ground truth, which ground-truth poses need (they are given in its
/// world; the lighting world is the marker frame).
std::unique_ptr<PoseSource> makePoseSource(PoseMode mode, const MarkerSpec& marker,
                                           const std::optional<capture::Pose>& T_world_marker,
                                           const TrackingOptions& options = {});

/// Poses decided beforehand (a trajectory optimised offline): the n-th frame located gets the n-th pose, a
/// frame past the last is lost. `mode` is what it reports as its mode.
std::unique_ptr<PoseSource> makeGivenPoseSource(PoseMode mode, std::vector<CameraPose> poses);

}  // namespace mrgi::runtime
