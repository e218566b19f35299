#pragma once
/// Dense RGB-D odometry: the rigid motion that carries one RGB-D frame (the source) onto another (the target:
/// the previous frame, or the room model seen from a predicted pose), by Gauss-Newton steps over a coarse-to-fine
/// pyramid. The intensity and hybrid steps are ours: they sample the target between pixels (bilinear), where
/// Open3D's (t::pipelines::odometry::ComputeOdometryResult{Intensity,Hybrid}, kept behind
/// OdometryOptions::subpixel) take the nearest pixel and cannot settle closer than half a pixel of the level. The
/// point-to-plane step is Open3D's (projective association, Huber weights, one 6x6 solve). The pyramid is made
/// here with OpenCV, since Debian's Open3D build implements neither the grey conversion nor the bilateral filter
/// on the CPU that its own multi-scale driver calls (shared/notes/anchors.md).
///
/// Camera frames are OpenCV's (x right, y down, z forward), depth in metres.
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "capture/types.h"

namespace mrgi::reconstruction {

/// What the steps minimise: the point-to-plane distance (KinectFusion), the intensity difference
/// (Steinbrücker et al. 2011), or both (Park et al. 2017: the robust default on textured scenes; point to
/// plane alone slides along a flat, texture-less view).
enum class OdometryMethod { PointToPlane, Intensity, Hybrid };
const char* toString(OdometryMethod m);

struct OdometryOptions {
  OdometryMethod method = OdometryMethod::Hybrid;
  /// Gauss-Newton steps per pyramid level, coarse to fine; the number of entries is the number of levels.
  std::vector<int> iterations{10, 6, 4};
  /// The finest level's width: a wider frame is halved until it fits (640x480 is tracked at 320x240).
  int maxWidth = 320;
  double minDepthM = 0.1, maxDepthM = 4.0;
  /// Associations whose depths differ by more than this are outliers (metres, at the finest level; doubled
  /// per coarser level); the Huber thresholds of the depth (metres) and intensity ([0, 1]) residuals.
  float depthOutlierM = 0.07f, depthHuberM = 0.05f, intensityHuber = 0.1f;
  /// The intensity residual's scale against the depth residual's in the hybrid (Open3D's hybrid step weighs
  /// the two alike; its legacy odometry weighs depth 30 times more): intensities are multiplied by it (and
  /// the Huber threshold with them), which weighs the intensity term by its square.
  float intensityWeight = 0.5f;
  /// An intensity residual larger than this (the intensities' own [0, 1] scale) after a level has converged is not
  /// misalignment but a change of the source's appearance since the target (a hand, a screen, a marker painted
  /// out): those pixels are left out of the level's second solve. 0: off.
  float intensityOutlier = 0.15f;
  /// ... when they are at least this share of the pixels the two frames share (fewer: noise and edges of an
  /// unchanged view, and the level stands; on the unchanged ViSP frames this keeps the hybrid solve at 21 ms a
  /// frame where solving every level twice took 34).
  double intensityOutlierMinShare = 0.03;
  /// Normalise each frame's intensity to a fixed mean and spread over its pixels with depth (for a camera
  /// whose exposure changes unreported). Off: the frame's own exposure is divided out, and a view whose
  /// content changes does not shift its intensities.
  bool normaliseIntensity = false;
  /// The intensity and hybrid steps sample the target between pixels (bilinear), so that they converge below a
  /// pixel of the level; false: Open3D's own steps, which take the nearest pixel (their parity and the measure of
  /// the difference).
  bool subpixel = true;
  /// A step that moves the view by less than this share of the level's pixel (its rotation in radians plus its
  /// translation in metres, over the pixel's angle) ends the level early. With the sub-pixel steps a level converges
  /// in a few steps: on the ViSP desk (tags painted out after the first frame) 0.005-0.1 of a pixel draw the tags
  /// alike (0.59-0.64 px RMS) in 16 to 9 steps a frame, 0.3 in 6 but 0.83 px.
  double convergedPixels = 0.1;
  /// Translation the view cannot hold stays as `init` had it. The inliers' surface normals hold a direction
  /// d in proportion to d^T (mean n n^T) d: a wall and the ceiling hold none along the line where they meet,
  /// one wall none in its own plane, and there depth noise and the intensity term slide the pose freely. The
  /// solved motion's translation (from init, in the target's frame) along every eigenvector of the mean
  /// n n^T (plus the intensity edges' g g^T) whose eigenvalue is below this is taken back out (Zhang et al.
  /// 2016's solution remapping); 0: off. With an intensity term only: point to plane alone is how a frame
  /// is aligned with the room model, whose noise-free surface's small structures (the box's sides) hold at
  /// the finest level what the coarse normals call weak (tabletop-pt against its room: ATE 4.1 -> 5.7 mm
  /// with it).
  double weakDirection = 0.02;
  /// With the sub-pixel intensity or hybrid steps: the coarsest level is solved from `init` and also from `init`
  /// turned in place (steps that rotate about the target camera's centre alone, then the full steps), and the one
  /// whose robust cost there is lower carries on to the finer levels. A camera that stops stepping back and starts
  /// to turn has its turn in neither the last pose nor a constant-velocity prediction, and from those the full
  /// steps can trade the missed rotation for a translation (tabletop-scan's frame 13 against 12: 78 mm off). The
  /// turned start is kept only where its cost is lower by 3 % or more (the same basin's costs differ by less). The
  /// second start costs a coarse level's solve (a sixteenth of the pixels).
  bool turnInPlace = true;
};

/// A frame prepared for odometry: per pyramid level (finest first) its depth, intensity and their gradients,
/// and its vertex and normal maps; NaN where there is no depth. Cheap to copy (shares its images).
class OdometryFrame {
 public:
  OdometryFrame();
  ~OdometryFrame();
  OdometryFrame(const OdometryFrame&);
  OdometryFrame& operator=(const OdometryFrame&);
  /// `depth` (CV_32F metres, 0 or NaN = none, or CV_16U millimetres) and `colour` (CV_8UC3 RGB or CV_8UC1
  /// grey, sRGB-encoded, taken at `exposure`; or CV_32FC1 linear luminance at exposure 1, as a room model's
  /// rendering has it; may be empty for point-to-plane) on the same pixel grid with intrinsics `k`.
  OdometryFrame(const cv::Mat& depth, const cv::Mat& colour, const capture::Intrinsics& k,
                const OdometryOptions& options = {}, double exposure = 1.0);
  int levels() const;
  const capture::Intrinsics& intrinsics(int level) const;
  /// CV_32F metres (NaN = none) / CV_32F intensity / CV_32FC3 camera frame (NaN = none), at `level`.
  const cv::Mat& depth(int level) const;
  const cv::Mat& intensity(int level) const;
  const cv::Mat& vertices(int level) const;
  const cv::Mat& normals(int level) const;
  /// Pixels with depth at the finest level.
  size_t validPixels() const;
  /// The memory the frame's images hold (bytes; each buffer once): a tracker keeps dozens of frames as keyframes.
  size_t bytes() const;
  bool hasIntensity() const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
  friend struct OdometrySolver;
};

struct OdometryResult {
  capture::Pose T_target_source = capture::identityPose();
  /// At the finest level, of the last step: inliers over the source's pixels, and the root mean square of
  /// the inliers' point-to-plane (or depth) residuals in metres (0 for intensity alone).
  double fitness = 0;
  double inlierRmse = 0;
  /// The view the two frames share: the source's pixels that land on a target pixel with depth, over the
  /// source's pixels. A turning camera loses overlap while its alignment stays right: the alignment's quality
  /// is the fitness within the overlap (inlierShare()).
  double overlap = 0;
  /// The inliers' residuals each scaled to 1 m range (divided by the square of the point's depth in metres
  /// where it lies beyond 1 m), their root mean square: a depth sensor's axial noise grows with the square
  /// of the range, so a view of far walls and one of a near table are held to one measure.
  double rangeRmse = 0;
  int steps = 0;
  /// Translation directions held back to init's (OdometryOptions::weakDirection): 0 where the view holds
  /// all three.
  int weakDirections = 0;
  /// The coarsest level's solve from init turned in place was kept (OdometryOptions::turnInPlace).
  bool turnedInPlace = false;
  /// False when a level had no inlier at all (frames that do not overlap): the pose is then `init`.
  bool solved = false;
  /// Inliers over the overlapping pixels (0 without overlap).
  double inlierShare() const { return overlap > 0 ? fitness / overlap : 0.0; }
};

/// Whether an alignment can be trusted on its own (the tracker's gate; the offline trajectory's edges keep
/// their fitness gate, reconstruction/pose_graph.h, which on tabletop-scan this gate would loosen, admitting 17
/// weaker edges: optimised ATE 2.70 -> 3.30 mm):
/// the views share at least `minOverlap` of the source's pixels, at least `minInlierShare` of the shared
/// pixels are inliers (the alignment's quality, not how far the camera turned), and the inliers' RMSE scaled
/// to 1 m range is at most `maxRangeRmseM` (a far wall's residual held to what its range lets the sensor
/// measure). By fitness alone a camera turning 12 degrees a frame past walls 2-3 m away was refused on its
/// second step: a fifth of each view leaves the frame and the walls' residual is twice the table's.
struct OdometryGate {
  double minOverlap = 0.3;
  double minInlierShare = 0.5;
  double maxRangeRmseM = 0.015;
  bool passes(const OdometryResult& r) const {
    return r.solved && r.overlap >= minOverlap && r.inlierShare() >= minInlierShare && r.rangeRmse <= maxRangeRmseM;
  }
};

/// The motion that carries `source` onto `target`, starting from `init` (target from source). Both frames
/// need the same pyramid (same size, intrinsics and levels); throws std::invalid_argument otherwise.
OdometryResult estimateOdometry(const OdometryFrame& source, const OdometryFrame& target,
                                const capture::Pose& init = capture::identityPose(),
                                const OdometryOptions& options = {});

}  // namespace mrgi::reconstruction
