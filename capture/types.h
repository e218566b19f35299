#pragma once
/// Frame types produced by every capture source. Units: metres, seconds, pixels.
/// Camera frame: OpenCV (x right, y down, z forward). Poses T_a_b map points from frame b to frame a.
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace mrgi::capture {

/// Pinhole intrinsics of an image of width x height pixels (pixel centres at integer coordinates).
struct Intrinsics {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  /// Positive size, finite positive focal lengths, finite principal point.
  bool valid() const {
    return width > 0 && height > 0 && std::isfinite(fx) && std::isfinite(fy) && fx > 0 && fy > 0 && std::isfinite(cx) &&
           std::isfinite(cy);
  }
  bool operator==(const Intrinsics&) const = default;
};

/// Rigid transform as a 4x4 row-major matrix, translation in metres.
using Pose = cv::Matx44d;
inline Pose identityPose() { return Pose::eye(); }
/// The rotation block of a pose.
inline cv::Matx33d rotationOf(const Pose& T) { return T.get_minor<3, 3>(0, 0); }
/// The translation column of a pose.
inline cv::Vec3d translationOf(const Pose& T) { return {T(0, 3), T(1, 3), T(2, 3)}; }
/// The pose with rotation R and translation t.
inline Pose makePose(const cv::Matx33d& R, const cv::Vec3d& t) {
  return {R(0, 0), R(0, 1), R(0, 2), t[0], R(1, 0), R(1, 1), R(1, 2), t[1],
          R(2, 0), R(2, 1), R(2, 2), t[2], 0,       0,       0,       1};
}
/// The inverse of a rigid transform.
inline Pose inversePose(const Pose& T) {
  const cv::Matx33d Rt = rotationOf(T).t();
  return makePose(Rt, -(Rt * translationOf(T)));
}
/// T_world_camera of a camera at eye looking at target, OpenCV camera frame (x right, y down, z forward),
/// image x along forward x `up` (so that image down is away from `up`; another axis when looking nearly
/// straight along it).
inline Pose lookAtPose(const cv::Vec3d& eye, const cv::Vec3d& target, const cv::Vec3d& up = {0, 1, 0}) {
  const cv::Vec3d z = cv::normalize(target - eye);
  const cv::Vec3d other = std::abs(up[0]) < 0.9 ? cv::Vec3d(1, 0, 0) : cv::Vec3d(0, 1, 0);
  const cv::Vec3d ref = std::abs(z.dot(up)) < 0.9 ? up : other;
  const cv::Vec3d x = cv::normalize(z.cross(ref));
  const cv::Vec3d y = z.cross(x);
  return makePose(cv::Matx33d(x[0], y[0], z[0], x[1], y[1], z[1], x[2], y[2], z[2]), eye);
}
/// T applied to a point (rotation and translation).
inline cv::Vec3d transformPoint(const Pose& T, const cv::Vec3d& p) { return rotationOf(T) * p + translationOf(T); }

/// Calibration of a fisheye camera in OpenCV's fisheye (equidistant / Kannala-Brandt) model.
struct FisheyeCalibration {
  int width = 0, height = 0;
  cv::Matx33d K = cv::Matx33d::eye();
  cv::Vec4d D{0, 0, 0, 0};  ///< k1..k4 of theta_d = theta (1 + k1 theta^2 + k2 theta^4 + ...)
  std::string model = "equidistant";
  /// Pose of the fisheye camera in the world (y up), if known (fixed rig); identity otherwise.
  std::optional<Pose> T_world_fisheye;
};

struct RgbdFrame {
  cv::Mat colour;  ///< CV_8UC3, RGB channel order, sRGB-encoded
  cv::Mat depth;   ///< CV_32FC1, metres along the optical axis, 0 = no measurement (never NaN/negative)
  Intrinsics colourIntrinsics;
  Intrinsics depthIntrinsics;
  /// Depth camera -> colour camera. When depthRegistered, depth is already resampled into the colour
  /// camera (same size, same intrinsics) and this is the identity.
  Pose T_colour_depth = identityPose();
  bool depthRegistered = true;
  /// Relative exposure of the colour image: linear radiance = decoded value / exposure (1 unless the
  /// recording says otherwise: frames.jsonl's "colour_exposure").
  double exposure = 1.0;
};

struct FisheyeFrame {
  cv::Mat image;          ///< CV_8UC3 RGB sRGB-encoded, or CV_32FC3 linear radiance (HDR)
  double exposure = 1.0;  ///< relative exposure (seconds when the device reports it); linear = value / exposure
  FisheyeCalibration calibration;
};

/// A light of the ground truth (manifest "ground_truth.lights", or a frame's own when the lights move).
struct GroundTruthLight {
  enum class Type { Point, Spot, Directional };
  Type type = Type::Point;
  cv::Vec3d position{0, 0, 0};    ///< point/spot, world, metres
  cv::Vec3d direction{0, 0, -1};  ///< spot axis / directional travel direction (into the scene), unit
  cv::Vec3d intensity{0, 0, 0};   ///< point/spot: W/sr per channel
  cv::Vec3d irradiance{0, 0, 0};  ///< directional: W/m^2 at normal incidence
  double spotHalfAngleDeg = 45;
  double radius = 0;  ///< emitter radius (metres) the generator rendered, 0 = a delta light
};

struct Frame {
  int64_t index = 0;       ///< 0-based position in the source
  double timestamp = 0.0;  ///< seconds, strictly increasing within a source
  std::optional<RgbdFrame> rgbd;
  std::optional<FisheyeFrame> fisheye;
  std::optional<Pose> groundTruthT_world_camera;  ///< colour camera pose, when the source knows it
  /// This frame's lights (world frame), when the session's lights move (a frame's "lights" in frames.jsonl);
  /// otherwise the manifest's ground-truth lights hold for every frame.
  std::optional<std::vector<GroundTruthLight>> groundTruthLights;
};

/// What a source can tell before reading frames.
struct SourceInfo {
  std::string uri;
  std::string kind;                   ///< "session", "tum", "open3d", "openni2", "v4l2"
  std::optional<int64_t> frameCount;  ///< unknown for live devices
  Intrinsics colourIntrinsics, depthIntrinsics;
  bool hasRgbd = false;
  bool hasFisheye = false;
  bool hasGroundTruth = false;
  double fps = 0;  ///< nominal frame rate: a recording's median frame interval, a device's mode (0 = unknown)
  /// Set when the intrinsics are a default rather than the recording's own: one line for the user.
  std::string calibrationNote;
};

/// The frame rates a recording may have (Hz): outside them its timestamps say nothing usable about its pace.
constexpr double kMinFrameRate = 0.1, kMaxFrameRate = 1000.0;
/// 1 / the median interval of increasing timestamps (seconds); 0 (unknown) with fewer than two or when that
/// rate lies outside [kMinFrameRate, kMaxFrameRate].
double medianRate(const std::vector<double>& timestamps);

}  // namespace mrgi::capture
