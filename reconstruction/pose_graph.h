#pragma once
/// A recording's whole trajectory optimised offline (mrgi room, bench --room): a pose graph with one node per
/// posed frame and one for the world (the marker frame, held fixed); edges from dense RGB-D odometry between
/// each frame and the few posed frames before it, loop closures with older frames its initial pose lies
/// near, and one edge per marker sighting. Open3D builds and solves it (pipelines::registration::PoseGraph,
/// GlobalOptimization: Levenberg-Marquardt, with Choi et al.'s line process weighing and pruning the loop
/// closures, which may be wrong); odometry's information matrices are Open3D's too
/// (t::pipelines::registration::GetInformationMatrix over the frames' vertices).
///
/// What it corrects that a frame-by-frame tracker cannot: each marker sighting counts once for the whole
/// trajectory, before and after it, instead of pulling the next frames a bounded step (so a first sighting
/// that is off is averaged with the later ones), and loop closures tie a trajectory that comes back to
/// where it was.
#include <memory>
#include <optional>
#include <vector>

#include "capture/types.h"
#include "reconstruction/odometry.h"

namespace mrgi::reconstruction {

struct TrajectoryOptions {
  OdometryOptions odometry;
  /// Each frame is aligned with this many posed frames before it (the first is its odometry edge).
  int window = 3;
  /// Every `loopEvery`-th posed frame is kept as a loop-closure candidate for the frames after the window,
  /// tried when the initial poses lie within loopDistanceM and loopAngleDeg of each other (at most
  /// maxLoopsPerFrame each, nearest first).
  int loopEvery = 4;
  double loopDistanceM = 0.4, loopAngleDeg = 40;
  int maxLoopsPerFrame = 2;
  /// An alignment becomes an edge at this fitness or more and this inlier RMSE or less.
  double minFitness = 0.5, maxRmseM = 0.015;
  /// The spread of one odometry edge (its information matrix is Open3D's, scaled so that its translation
  /// part is 1 / sigma^2) and of one marker sighting (rotation, translation). Measured on the bundled
  /// sessions: odometry's error per frame 0.6-1.0 mm, the marker's 2.4-3.9 mm with the tag fully in view
  /// (tens of millimetres half hidden).
  double odometrySigmaM = 0.001;
  double markerSigmaM = 0.01, markerSigmaDeg = 1.0;
  /// The finest pyramid level whose vertices the information matrices are computed from (1: 160 x 120 for a
  /// 640 x 480 frame tracked at 320 x 240).
  int informationLevel = 1;
  /// Correspondences within this distance count in an edge's information matrix.
  double informationDistanceM = 0.02;
};

/// One frame of the trajectory.
struct TrajectoryFrame {
  /// Its initial camera-to-world pose (the tracker's); nullopt: not posed (lost), left out of the graph.
  std::optional<capture::Pose> T_world_camera;
  /// The camera-to-world pose its marker sighting gives, when the tag was seen.
  std::optional<capture::Pose> markerT_world_camera;
};

struct TrajectoryResult {
  /// Per frame added: the optimised pose, nullopt where the frame was not posed.
  std::vector<std::optional<capture::Pose>> T_world_camera;
  int odometryEdges = 0, loopEdges = 0, markerEdges = 0;
  /// Loop closures the optimisation pruned (line process below Open3D's threshold).
  int prunedEdges = 0;
  /// Alignments tried and refused by the quality gate.
  int refusedAlignments = 0;
  /// How far the optimisation moved the frames from their initial poses (mean and largest, metres).
  double meanShiftM = 0, maxShiftM = 0;
};

/// Builds the graph frame by frame (the frames' pyramids are kept only as long as a later frame may be
/// aligned with them: the window, and every loopEvery-th frame), then optimises it.
class TrajectoryOptimiser {
 public:
  explicit TrajectoryOptimiser(const TrajectoryOptions& options = {});
  ~TrajectoryOptimiser();
  TrajectoryOptimiser(const TrajectoryOptimiser&) = delete;
  TrajectoryOptimiser& operator=(const TrajectoryOptimiser&) = delete;
  /// The next frame: its odometry pyramid (OdometryFrame, made with options().odometry) and its poses.
  void add(const OdometryFrame& frame, const TrajectoryFrame& poses);
  /// Optimises the graph built so far. With no marker sighting, the first posed frame is held instead of the
  /// world (the trajectory keeps its anchor).
  TrajectoryResult optimise() const;
  const TrajectoryOptions& options() const { return o_; }

 private:
  struct Impl;
  TrajectoryOptions o_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mrgi::reconstruction
