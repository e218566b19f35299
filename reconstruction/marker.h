#pragma once
/// AprilTag marker detection (libapriltag), pose, depth-plane refinement, One-Euro smoothing and loss
/// handling.
///
/// Tag frame (shared/notes/algorithms.md §0): origin at the tag centre, z out of the tag (towards a viewer
/// in front of it), x along the tag's first edge (corner 0 -> corner 1, corners as libapriltag orders
/// them: counter-clockwise in the image starting bottom-left of the upright tag), y = z x x (up).
/// Camera frame: OpenCV (x right, y down, z forward). Tag size = edge of the black border square.
#include <array>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/core/quaternion.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/types.h"

namespace mrgi::reconstruction {

struct TagDetection {
  int id = -1;
  std::array<cv::Point2d, 4> corners;  ///< pixels, libapriltag order
  cv::Point2d centre;
  int hamming = 0;            ///< corrected bit errors
  double decisionMargin = 0;  ///< libapriltag's quality measure (higher is better)
};

struct DetectorOptions {
  std::string family = "tag36h11";
  float decimate = 1.0f;  ///< quad detection on a decimated image (faster, less precise); 1 = full res
  float blurSigma = 0.0f;
  int threads = 1;
  int maxHamming = 1;  ///< reject detections that needed more bit corrections
  double minDecisionMargin = 20.0;
};

/// libapriltag detector for one family. Throws std::invalid_argument for an unknown family.
class TagDetector {
 public:
  explicit TagDetector(const DetectorOptions& options = {});
  ~TagDetector();
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;
  /// Detections in an 8-bit grey or RGB image, sorted by id.
  std::vector<TagDetection> detect(const cv::Mat& image) const;
  /// Detections inside `roi` only, in the image's pixels, at the cost of the region's area. The region is
  /// clipped to the image and grown to whole 4-pixel tiles of the image, where libapriltag's adaptive
  /// threshold works, so a tag well inside it (tagWellInside) is found with the same corners as on the
  /// whole image.
  std::vector<TagDetection> detect(const cv::Mat& image, cv::Rect roi) const;
  const DetectorOptions& options() const { return options_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  DetectorOptions options_;
};

/// The region detect(image, roi) searches for a tag last seen at `corners`: their bounding box grown by
/// `grow` times its larger side on every side.
cv::Rect tagSearchRegion(const std::array<cv::Point2d, 4>& corners, double grow);
/// A detection in a region lies well inside it: its corners at least `margin` pixels from the region's edges
/// (a tag cut by the region's edge may be found with wrong corners, or not at all).
bool tagWellInside(const TagDetection& d, const cv::Rect& roi, double margin);

/// The four corners of a tag of edge `size` in the tag frame, in libapriltag corner order.
std::array<cv::Point3d, 4> tagCornersInTagFrame(double size);

struct TagPose {
  capture::Pose T_camera_tag = capture::identityPose();
  double reprojectionRms = 0;  ///< pixels, of the chosen solution
  double alternativeRms = 0;   ///< pixels, of IPPE's other (mirror) solution; inf if none
  bool ambiguous = false;      ///< the two solutions explain the corners about equally well
  bool depthRefined = false;
};

struct PoseOptions {
  /// Solutions whose reprojection errors are within this ratio count as ambiguous; the choice then
  /// falls to the depth plane, then to the previous pose, then to the lower error.
  double ambiguityRatio = 0.5;
};

/// Pose of one tag from its corners: IPPE square (both solutions), ambiguity resolution, LM refinement.
/// `previous` (camera-from-tag of the last frame) and `planeNormal` (camera-frame normal of the tag's
/// support plane facing the camera) disambiguate. Nullopt only for degenerate corners.
std::optional<TagPose> estimateTagPose(const TagDetection& detection, double tagSize, const capture::Intrinsics& k,
                                       const PoseOptions& options = {}, const capture::Pose* previous = nullptr,
                                       const cv::Vec3d* planeNormal = nullptr);

/// Least-squares plane through the valid depth samples inside the tag quad (one outlier-rejection
/// round); nullopt with fewer than minSamples inliers. Returns (unit normal facing the camera, point).
std::optional<std::pair<cv::Vec3d, cv::Vec3d>> fitTagPlane(const TagDetection& detection, const cv::Mat& depth,
                                                           const capture::Intrinsics& k, int minSamples = 30);

/// Re-seats a pose on the measured depth plane: rotates the tag z onto the plane normal (smallest
/// rotation) and moves the centre along its viewing ray onto the plane. Keeps the pose when the plane
/// disagrees with it by more than maxAngleDeg.
TagPose refinePoseWithDepth(const TagPose& pose, const std::pair<cv::Vec3d, cv::Vec3d>& plane,
                            double maxAngleDeg = 25.0, double maxShiftMetres = 1e30);

/// The agreement measureTagPose asks of the depth plane before re-seating a pose on it: a sensor whose
/// depth on the tag is biased (printed black and white fool some sensors by centimetres and degrees) must
/// not pull a good image pose away; a noisy image pose (small tag in the image) gets corrected. The limits
/// grow with the image pose's own uncertainty: its distance from the tag's apparent size is uncertain by
/// dz = z sqrt(2) cornerNoisePx / side (side: the tag's mean side in pixels), and where 3 dz exceeds
/// maxShiftMetres both limits are scaled by 3 dz / maxShiftMetres (a 25-pixel tag at 0.9 m: dz = 10 mm,
/// limits 31 mm and 3.1 degrees; the real ViSP sequence, whose sensor's depth on the printed tag is biased,
/// keeps the base limits).
struct DepthGate {
  double maxAngleDeg = 2.5;       ///< between the pose's tag normal and the plane's
  double maxShiftMetres = 0.025;  ///< of the tag centre along its viewing ray
  double cornerNoisePx = 0.2;
};
/// The gate's limits for one detection at distance `z` (metres): {angle in degrees, shift in metres}.
std::pair<double, double> depthGateLimits(const DepthGate& gate, const TagDetection& detection, double z);

/// One frame's measurement of a tag: estimateTagPose, disambiguated and re-seated by the depth plane under
/// the tag when `depth` (registered to the colour image, metres) is given, holds enough samples there and
/// agrees with the image pose within `gate`.
std::optional<TagPose> measureTagPose(const TagDetection& detection, double tagSize, const capture::Intrinsics& k,
                                      const cv::Mat& depth = cv::Mat(), const capture::Pose* previous = nullptr,
                                      const DepthGate& gate = {});

/// One-Euro filter (Casiez et al. 2012) of a vector signal: low cutoff when slow (no jitter), high when
/// fast (no lag). Cutoffs in Hz, time in seconds.
class OneEuroFilter {
 public:
  OneEuroFilter(double minCutoff = 1.0, double beta = 0.5, double derivativeCutoff = 1.0)
      : minCutoff_(minCutoff), beta_(beta), dCutoff_(derivativeCutoff) {}
  std::vector<double> filter(double t, const std::vector<double>& x);
  void reset() { initialised_ = false; }

 private:
  double minCutoff_, beta_, dCutoff_;
  bool initialised_ = false;
  double tPrev_ = 0;
  std::vector<double> xPrev_, dxPrev_;
};

/// Pose smoothing: One-Euro on translation (metres) and on the rotation quaternion (hemisphere-aligned,
/// renormalised).
class PoseSmoother {
 public:
  PoseSmoother(double minCutoff = 1.0, double beta = 20.0, double derivativeCutoff = 1.0)
      : translation_(minCutoff, beta, derivativeCutoff), rotation_(minCutoff, beta, derivativeCutoff) {}
  capture::Pose filter(double t, const capture::Pose& T);
  void reset() { translation_.reset(), rotation_.reset(), havePrev_ = false; }

 private:
  OneEuroFilter translation_, rotation_;
  bool havePrev_ = false;
  cv::Quatd qPrev_;
};

enum class TrackStatus { Tracked, Held, Lost };
const char* toString(TrackStatus s);

struct TrackerOptions {
  double holdSeconds = 0.5;  ///< keep the last pose this long after the tag disappears, then "lost"
  bool smooth = true;
  /// One-Euro: Hz at rest; Hz added per m/s (or quaternion units/s). Measured on the bundled orbits and a
  /// static camera (README): beta 100 with a 10 Hz speed estimate keeps the moving error within 1.5-2 mm
  /// of the raw poses while cutting static jitter 5x; the old 20 / 1 Hz lagged by 14-20 mm.
  double minCutoff = 1.0, beta = 100.0;
  double derivativeCutoff = 10.0;  ///< One-Euro: Hz of the speed estimate (higher: motion seen sooner)
};

/// Per-tag temporal state: smoothing while tracked, hold then loss when unseen; smoothing restarts after
/// a loss (no blending across gaps).
class MarkerTrack {
 public:
  explicit MarkerTrack(const TrackerOptions& options = {})
      : options_(options), smoother_(options.minCutoff, options.beta, options.derivativeCutoff) {}
  /// Feed the measurement of this frame (nullopt when the tag was not detected).
  TrackStatus update(double t, const std::optional<capture::Pose>& measured);
  const std::optional<capture::Pose>& pose() const { return pose_; }  ///< last output (held while held)
  const capture::Pose* lastMeasured() const { return lastMeasured_ ? &*lastMeasured_ : nullptr; }

 private:
  TrackerOptions options_;
  PoseSmoother smoother_;
  std::optional<capture::Pose> pose_, lastMeasured_;
  double lastSeen_ = 0;
  TrackStatus status_ = TrackStatus::Lost;
};

/// Alternative light mode: a point light (a lamp) carrying its own AprilTag, with a set intensity.
struct TaggedPointLight {
  int tagId = 1;
  cv::Vec3d offset{0, 0, 0};     ///< light centre in the tag frame, metres
  cv::Vec3d intensity{1, 1, 1};  ///< RGB radiant intensity, W/sr
};

/// The light's position in the camera frame given the pose of its tag.
cv::Vec3d taggedLightPosition(const TaggedPointLight& light, const capture::Pose& T_camera_tag);

/// Rotation angle (degrees) between two rotations and translation distance (metres) between two poses.
double rotationErrorDeg(const capture::Pose& a, const capture::Pose& b);
double translationError(const capture::Pose& a, const capture::Pose& b);

}  // namespace mrgi::reconstruction
