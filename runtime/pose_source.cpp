#include "runtime/pose_source.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/error.h"
#include "reconstruction/depth.h"
#include "reconstruction/marker.h"
#include "reconstruction/plane.h"
#include "reconstruction/room_view.h"

namespace mrgi::runtime {

namespace {
struct ModeName {
  PoseMode mode;
  const char* name;
};
constexpr ModeName kModes[] = {{PoseMode::Marker, "marker"},
                               {PoseMode::GroundTruth, "ground-truth"},
                               {PoseMode::Odometry, "odometry"},
                               {PoseMode::Tracked, "tracked"}};
}  // namespace

const std::vector<std::string>& poseModeNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& m : kModes) n.emplace_back(m.name);
    return n;
  }();
  return names;
}

const char* toString(PoseMode m) {
  for (const auto& x : kModes)
    if (x.mode == m) return x.name;
  return "?";
}

PoseMode poseModeFromName(const std::string& name, const std::string& flag) {
  for (const auto& x : kModes)
    if (name == x.name) return x.mode;
  throw capture::InputError(flag, "'" + name + "' is not a pose source (marker, ground-truth, odometry or tracked)");
}

std::string poseModeHelp() {
  return "camera pose per frame: tracked (default: the marker where seen, RGB-D odometry between, relocalised when "
         "lost), marker (the tag alone), odometry (the marker anchors the first frame only) or ground-truth (the "
         "session's)";
}

const char* toString(PosedBy b) {
  switch (b) {
    case PosedBy::None:
      return "none";
    case PosedBy::Marker:
      return "marker";
    case PosedBy::GroundTruth:
      return "ground-truth";
    case PosedBy::Odometry:
      return "odometry";
    case PosedBy::Relocalised:
      return "relocalised";
    case PosedBy::FirstFrame:
      return "first-frame";
  }
  return "?";
}

nlohmann::json CameraPose::facts() const {
  nlohmann::json j = {
      {"status", status()}, {"by", tracked() ? nlohmann::json(toString(by)) : nlohmann::json()}, {"marker", marker}};
  if (fitness >= 0) j["fitness"] = fitness, j["overlap"] = overlap, j["inlier_rmse_m"] = inlierRmse;
  if (!against.empty()) j["against"] = against;
  if (correctionM > 0 || correctionDeg > 0) j["correction_m"] = correctionM, j["correction_deg"] = correctionDeg;
  if (markerReset) j["marker_reset"] = true;
  return j;
}

namespace {

/// The AprilTag measurement of a frame: the wanted tag's camera-from-marker pose, searched around where it
/// was last seen first (the tag's box grown by its size on every side), the whole image when not found well
/// inside that region.
class MarkerMeasurement {
 public:
  explicit MarkerMeasurement(const MarkerSpec& m) : spec_(m) {
    reconstruction::DetectorOptions dopt;
    dopt.family = m.family;
    detector_.emplace(dopt);
  }
  /// T_camera_marker of this frame, unsmoothed; nullopt when the tag is not seen.
  std::optional<capture::Pose> measure(const capture::RgbdFrame& rgbd, const capture::Pose* previous) {
    std::optional<capture::Pose> measured;
    const auto pick = [&](const std::vector<reconstruction::TagDetection>& found, const cv::Rect* region) {
      for (const auto& d : found) {
        if (spec_.id >= 0 && d.id != spec_.id) continue;
        if (region && !reconstruction::tagWellInside(d, *region, 4.0)) continue;
        const auto pose = reconstruction::measureTagPose(d, spec_.size, rgbd.colourIntrinsics, rgbd.depth, previous);
        if (pose) {
          measured = pose->T_camera_tag;
          lastCorners_ = d.corners;
          return true;
        }
      }
      return false;
    };
    bool found = false;
    if (lastCorners_) {
      const cv::Rect region =
          reconstruction::tagSearchRegion(*lastCorners_, 1.0) & cv::Rect(0, 0, rgbd.colour.cols, rgbd.colour.rows);
      found = pick(detector_->detect(rgbd.colour, region), &region);
    }
    if (!found) found = pick(detector_->detect(rgbd.colour), nullptr);
    if (!found) lastCorners_.reset();
    return measured;
  }

 private:
  MarkerSpec spec_;
  std::optional<reconstruction::TagDetector> detector_;
  std::optional<std::array<cv::Point2d, 4>> lastCorners_;
};

/// marker: the tag alone, smoothed, held for a moment when it is not seen, then lost.
class MarkerPoses : public PoseSource {
 public:
  explicit MarkerPoses(const MarkerSpec& m) : measurement_(m) {}
  PoseMode mode() const override { return PoseMode::Marker; }
  CameraPose locate(const capture::Frame& frame, gl::Profiler& profiler) override {
    auto s = profiler.cpu("marker");
    const auto measured = measurement_.measure(*frame.rgbd, track_.lastMeasured());
    const auto status = track_.update(frame.timestamp, measured);
    CameraPose out;
    out.marker = reconstruction::toString(status);
    if (measured) out.markerT_world_camera = capture::inversePose(*measured);
    if (status != reconstruction::TrackStatus::Lost && track_.pose()) {
      out.T_world_camera = capture::inversePose(*track_.pose());
      out.by = PosedBy::Marker;
    }
    return out;
  }

 private:
  MarkerMeasurement measurement_;
  reconstruction::MarkerTrack track_;
};

/// ground-truth: the session's camera poses in the marker frame; a frame without one falls back to the marker.
class GroundTruthPoses : public PoseSource {
 public:
  GroundTruthPoses(const MarkerSpec& m, const capture::Pose& T_world_marker)
      : marker_(m), T_marker_world_(capture::inversePose(T_world_marker)) {}
  PoseMode mode() const override { return PoseMode::GroundTruth; }
  CameraPose locate(const capture::Frame& frame, gl::Profiler& profiler) override {
    if (!frame.groundTruthT_world_camera) return marker_.locate(frame, profiler);
    CameraPose out;
    out.T_world_camera = T_marker_world_ * *frame.groundTruthT_world_camera;
    out.by = PosedBy::GroundTruth;
    return out;
  }

 private:
  MarkerPoses marker_;
  capture::Pose T_marker_world_;
};

/// The rotation vector and translation of a pose (its log, up to the coupling of the two, which a small
/// correction may ignore), and back.
void splitPose(const capture::Pose& T, cv::Vec3d& w, cv::Vec3d& t) {
  cv::Mat rv;
  cv::Rodrigues(cv::Mat(capture::rotationOf(T)), rv);
  w = cv::Vec3d(rv.at<double>(0), rv.at<double>(1), rv.at<double>(2));
  t = capture::translationOf(T);
}
capture::Pose joinPose(const cv::Vec3d& w, const cv::Vec3d& t) {
  cv::Mat R;
  cv::Rodrigues(cv::Mat(w), R);
  return capture::makePose(cv::Matx33d(R), t);
}

/// The nearest rigid transform (its rotation's polar factor): products of poses drift off the rotations, and
/// a correction carried by a keyframe each frame would compound it.
capture::Pose rigid(const capture::Pose& T) {
  cv::Mat w, u, vt;
  cv::SVD::compute(cv::Mat(capture::rotationOf(T)), w, u, vt);
  cv::Mat R = u * vt;
  if (cv::determinant(R) < 0) {
    u.col(2) *= -1;
    R = u * vt;
  }
  return capture::makePose(cv::Matx33d(R), capture::translationOf(T));
}

/// odometry and tracked: dense RGB-D odometry against keyframes, anchored by the marker.
class OdometryPoses : public PoseSource {
 public:
  OdometryPoses(PoseMode mode, const MarkerSpec& m, const TrackingOptions& o) : mode_(mode), measurement_(m), o_(o) {}
  PoseMode mode() const override { return mode_; }
  std::optional<capture::Pose> foundedWorld() const override { return founded_; }
  void useModel(std::shared_ptr<const reconstruction::RoomMesh> room) override {
    model_ = room && !room->positions.empty() ? std::move(room) : nullptr;
    modelRays_ = model_ ? std::make_shared<reconstruction::MeshRays>(model_->positions, model_->indices) : nullptr;
  }

  CameraPose locate(const capture::Frame& frame, gl::Profiler& profiler) override {
    const capture::RgbdFrame& rgbd = *frame.rgbd;
    CameraPose out;
    // The marker: every frame when it tracks; until it has anchored the world when it only anchors.
    std::optional<capture::Pose> marker;
    if (!o_.firstFrameT_world_camera && !founded_ && (mode_ == PoseMode::Tracked || !anchored_)) {
      auto s = profiler.cpu("marker");
      marker = measurement_.measure(rgbd, lastMarker_ ? &*lastMarker_ : nullptr);
      lastMarker_ = marker;
      out.marker = marker ? "tracked" : "lost";
      if (marker) out.markerT_world_camera = capture::inversePose(*marker);
    }
    std::optional<reconstruction::OdometryFrame> odo;
    {
      auto s = profiler.cpu("odometry");
      odo.emplace(rgbd.depth, rgbd.colour, rgbd.colourIntrinsics, o_.odometry, rgbd.exposure);
    }
    if (!anchored_) {
      const bool first = !sawFrame_;
      sawFrame_ = true;
      if (marker) {
        out.T_world_camera = capture::inversePose(*marker);
        out.by = PosedBy::Marker;
      } else if (first && o_.firstFrameT_world_camera) {
        out.T_world_camera = *o_.firstFrameT_world_camera;
        out.by = PosedBy::FirstFrame;
      } else if (first && o_.worldFromFirstFrame) {
        auto s = profiler.cpu("world");
        cv::Mat depth = rgbd.depth;
        const cv::Mat positions = reconstruction::backProject(depth, rgbd.colourIntrinsics);
        if (const auto T_camera_world = reconstruction::worldOnDominantPlane(
                positions, reconstruction::computeNormals(positions), rgbd.colourIntrinsics)) {
          out.T_world_camera = capture::inversePose(*T_camera_world);
          out.by = PosedBy::FirstFrame;
        }
      }
      if (!out.T_world_camera) return out;  // no world yet: nothing can be placed
      anchored_ = true;
      if (out.by == PosedBy::FirstFrame) founded_ = out.T_world_camera;
      accept(*odo, rgbd, out, true);
      return out;
    }
    std::optional<capture::Pose> pose;
    if (!lost_) {
      auto s = profiler.cpu("odometry");
      pose = track(*odo, out);
      if (pose) out.by = PosedBy::Odometry;
    }
    if (!pose && !(mode_ == PoseMode::Tracked && marker)) {
      auto s = profiler.cpu("relocalise");
      pose = relocalise(*odo, rgbd, out);
      if (pose) out.by = PosedBy::Relocalised;
    }
    bool newKeyframe = false;
    if (mode_ == PoseMode::Tracked && marker && !founded_) {
      const capture::Pose M = capture::inversePose(*marker);
      cv::Vec3d w, t;  // the marker's pose from the tracked one
      if (pose) splitPose(capture::inversePose(*pose) * M, w, t);
      const double angleDeg = cv::norm(w) * 180.0 / CV_PI, dist = cv::norm(t);
      // Drift gathers over the frames the tag is away and the pull takes it back a bounded step a frame; a
      // disagreement that grew by more than the override since the last frame the marker saw is this frame's
      // alignment having slid: the marker places the camera outright.
      if (pose && markerGap_ &&
          (dist - markerGap_->first > o_.markerOverrideM || angleDeg - markerGap_->second > o_.markerOverrideDeg)) {
        pose.reset();
        out.correctionM = dist, out.correctionDeg = angleDeg, out.markerReset = true;
      }
      if (pose) {
        // A complementary filter: the pose moves towards the marker's by a bounded step (no jump).
        double gainW = o_.markerGain, gainT = o_.markerGain;
        if (angleDeg * gainW > o_.maxCorrectionDeg) gainW = o_.maxCorrectionDeg / angleDeg;
        if (dist * gainT > o_.maxCorrectionM) gainT = o_.maxCorrectionM / dist;
        const capture::Pose corrected = *pose * joinPose(w * gainW, t * gainT);
        // The keyframe the pose was tracked from moves with it (world frame), or the next frame's odometry
        // would undo the correction.
        Keyframe& kf = keyframes_[current_];
        kf.T_world_camera = rigid(corrected * capture::inversePose(*pose) * kf.T_world_camera);
        pose = corrected;
        out.correctionM = dist * gainT;
        out.correctionDeg = angleDeg * gainW;
        markerGap_ = {dist - out.correctionM, angleDeg - out.correctionDeg};
      } else {
        pose = M;  // after a loss, or where odometry failed or slid, the marker places the camera outright
        markerGap_ = {0.0, 0.0};
        newKeyframe = true;
      }
      out.by = PosedBy::Marker;
    }
    if (!pose || out.by != PosedBy::Marker) markerGap_.reset();
    if (!pose) {
      lost_ = true;
      velocity_.reset();
      return out;
    }
    out.T_world_camera = rigid(*pose);
    accept(*odo, rgbd, out, newKeyframe || out.by == PosedBy::Relocalised);
    return out;
  }

 private:
  struct Keyframe {
    reconstruction::OdometryFrame frame;
    capture::Pose T_world_camera;
    std::vector<cv::Point3f> points;  ///< ORB keypoints with depth, camera frame
    cv::Mat descriptors;              ///< their ORB descriptors, one row each
  };

  /// The quality gate: absolute limits, and against the recent trusted frames' medians.
  bool trusted(const reconstruction::OdometryResult& r) const {
    if (!o_.gate.passes(r)) return false;
    if (recentShare_.size() < 3) return true;
    const auto median = [](std::deque<double> v) {
      std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
      return v[v.size() / 2];
    };
    return r.inlierShare() >= o_.fitnessRatio * median(recentShare_) &&
           r.rangeRmse <= o_.rmseRatio * median(recentRangeRmse_);
  }

  /// Odometry against the current keyframe, then against the previous frame; the pose when one is trusted.
  std::optional<capture::Pose> track(const reconstruction::OdometryFrame& odo, CameraPose& out) {
    // The prediction: the last frame's motion again (a steady orbit), else no motion (a camera that stopped).
    const capture::Pose predicted = velocity_ ? lastPose_ * *velocity_ : lastPose_;
    const auto attempt = [&](const reconstruction::OdometryFrame& target,
                             const capture::Pose& T_world_target) -> std::optional<capture::Pose> {
      const capture::Pose T_target_world = capture::inversePose(T_world_target);
      auto r = reconstruction::estimateOdometry(odo, target, T_target_world * predicted, o_.odometry);
      if (velocity_ && !trusted(r))
        r = reconstruction::estimateOdometry(odo, target, T_target_world * lastPose_, o_.odometry);
      if (!r.solved) return std::nullopt;
      out.setQuality(r);
      lastFitness_ = r.fitness;
      if (!trusted(r)) return std::nullopt;
      return T_world_target * r.T_target_source;
    };
    // The room as seen from the prediction, rendered at the pyramid's finest level.
    if (model_) {
      const capture::Intrinsics& k0 = odo.intrinsics(0);
      const reconstruction::RoomView view =
          reconstruction::renderRoomView(*model_, *modelRays_, predicted, k0, o_.odometry.maxDepthM);
      reconstruction::OdometryOptions mo = o_.odometry;
      mo.maxWidth = k0.width;
      mo.method = o_.modelMethod;
      const reconstruction::OdometryFrame target(view.depth, view.luminance, k0, mo);
      const auto r = reconstruction::estimateOdometry(odo, target, capture::identityPose(), mo);
      if (r.solved && trusted(r)) {
        out.setQuality(r);
        out.against = "model";
        return predicted * r.T_target_source;
      }
    }
    keyframeFailed_ = false;
    out.against = "keyframe";
    if (auto p = attempt(keyframes_[current_].frame, keyframes_[current_].T_world_camera)) return p;
    keyframeFailed_ = true;  // the view has left the keyframe: the frame becomes one if the previous frame places it
    out.against = "previous";
    if (previous_)
      if (auto p = attempt(*previous_, lastPose_)) return p;
    out.against.clear();
    return std::nullopt;
  }

  /// ORB matches against the keyframes (newest first), PnP RANSAC, confirmed by dense odometry.
  std::optional<capture::Pose> relocalise(const reconstruction::OdometryFrame& odo, const capture::RgbdFrame& rgbd,
                                          CameraPose& out) {
    std::vector<cv::KeyPoint> kps;
    cv::Mat desc;
    orbOf(rgbd.colour, kps, desc);
    if (desc.empty()) return std::nullopt;
    const capture::Intrinsics& k = rgbd.colourIntrinsics;
    const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
    cv::BFMatcher matcher(cv::NORM_HAMMING, true);
    for (size_t n = keyframes_.size(); n-- > 0;) {
      const Keyframe& kf = keyframes_[n];
      if (kf.descriptors.empty()) continue;
      std::vector<cv::DMatch> matches;
      matcher.match(kf.descriptors, desc, matches);
      if (static_cast<int>(matches.size()) < o_.relocaliseMinInliers) continue;
      std::vector<cv::Point3f> object;
      std::vector<cv::Point2f> image;
      for (const auto& m : matches) {
        object.push_back(kf.points[static_cast<size_t>(m.queryIdx)]);
        image.push_back(kps[static_cast<size_t>(m.trainIdx)].pt);
      }
      cv::Mat rvec, tvec;
      std::vector<int> inliers;
      if (!cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 200, 3.0f, 0.99, inliers,
                              cv::SOLVEPNP_EPNP) ||
          static_cast<int>(inliers.size()) < o_.relocaliseMinInliers)
        continue;
      const capture::Pose T_camera_kf = joinPose(cv::Vec3d(rvec), cv::Vec3d(tvec));
      const auto r = reconstruction::estimateOdometry(odo, kf.frame, capture::inversePose(T_camera_kf), o_.odometry);
      if (!trusted(r)) continue;
      out.setQuality(r);
      current_ = n;
      return kf.T_world_camera * r.T_target_source;
    }
    return std::nullopt;
  }

  void orbOf(const cv::Mat& colour, std::vector<cv::KeyPoint>& kps, cv::Mat& desc) {
    if (!orb_) orb_ = cv::ORB::create(1000);
    cv::Mat grey;
    cv::cvtColor(colour, grey, cv::COLOR_RGB2GRAY);
    orb_->detectAndCompute(grey, cv::noArray(), kps, desc);
  }

  /// A posed frame: the next frame's prediction, and a keyframe when the view has moved on.
  void accept(const reconstruction::OdometryFrame& odo, const capture::RgbdFrame& rgbd, const CameraPose& out,
              bool force) {
    // The motion since the last frame, when it was posed too (the next frame's prediction).
    if (!lost_ && previous_)
      velocity_ = rigid(capture::inversePose(lastPose_) * *out.T_world_camera);
    else
      velocity_.reset();
    lost_ = false;
    lastPose_ = *out.T_world_camera;
    if (out.fitness >= 0) {
      recentShare_.push_back(out.overlap > 0 ? out.fitness / out.overlap : 0.0);
      recentRangeRmse_.push_back(out.rangeRmse);
      while (static_cast<int>(recentShare_.size()) > o_.qualityWindow)
        recentShare_.pop_front(), recentRangeRmse_.pop_front();
    }
    previous_ = odo;
    bool add = force || keyframes_.empty() || keyframeFailed_;
    keyframeFailed_ = false;
    if (!add) {
      const capture::Pose& kf = keyframes_[current_].T_world_camera;
      add = lastFitness_ < o_.keyframeFitness ||
            reconstruction::translationError(kf, lastPose_) > o_.keyframeDistanceM ||
            reconstruction::rotationErrorDeg(kf, lastPose_) > o_.keyframeAngleDeg;
    }
    if (!add) return;
    Keyframe kf{odo, lastPose_, {}, {}};
    std::vector<cv::KeyPoint> kps;
    cv::Mat desc;
    orbOf(rgbd.colour, kps, desc);
    const capture::Intrinsics& k = rgbd.colourIntrinsics;
    for (size_t i = 0; i < kps.size(); ++i) {
      const int x = cvRound(kps[i].pt.x), y = cvRound(kps[i].pt.y);
      if (x < 0 || y < 0 || x >= rgbd.depth.cols || y >= rgbd.depth.rows) continue;
      const float z = rgbd.depth.at<float>(y, x);
      if (!(z > 0.f && z < 1e30f)) continue;
      kf.points.emplace_back(static_cast<float>((kps[i].pt.x - k.cx) / k.fx * z),
                             static_cast<float>((kps[i].pt.y - k.cy) / k.fy * z), z);
      kf.descriptors.push_back(desc.row(static_cast<int>(i)));
    }
    if (static_cast<int>(keyframes_.size()) >= o_.maxKeyframes) keyframes_.erase(keyframes_.begin());
    keyframes_.push_back(std::move(kf));
    current_ = keyframes_.size() - 1;
    lastFitness_ = 1.0;
  }

  PoseMode mode_;
  MarkerMeasurement measurement_;
  TrackingOptions o_;
  bool anchored_ = false, lost_ = false, sawFrame_ = false;
  std::optional<capture::Pose> founded_;  ///< the first frame's pose in a world founded on it
  capture::Pose lastPose_ = capture::identityPose();
  std::optional<capture::Pose>
      velocity_;  ///< the last frame's motion (camera frame), when two posed frames follow each other
  std::optional<capture::Pose> lastMarker_;  ///< T_camera_marker of the last frame, for the tag's ambiguity
  std::optional<reconstruction::OdometryFrame> previous_;
  std::vector<Keyframe> keyframes_;
  size_t current_ = 0;
  double lastFitness_ = 1.0;
  /// How far the marker's pose lay from the tracked one after its correction (metres, degrees), when the last
  /// frame saw the marker.
  std::optional<std::pair<double, double>> markerGap_;
  /// Inlier shares and range-scaled RMSEs of the last trusted frames (TrackingOptions::qualityWindow).
  std::deque<double> recentShare_, recentRangeRmse_;
  bool keyframeFailed_ = false;
  cv::Ptr<cv::ORB> orb_;
  std::shared_ptr<const reconstruction::RoomMesh> model_;
  std::shared_ptr<reconstruction::MeshRays> modelRays_;
};

/// Poses decided beforehand, in the order the frames come.
class GivenPoses : public PoseSource {
 public:
  GivenPoses(PoseMode mode, std::vector<CameraPose> poses) : mode_(mode), poses_(std::move(poses)) {}
  PoseMode mode() const override { return mode_; }
  CameraPose locate(const capture::Frame&, gl::Profiler&) override {
    return next_ < poses_.size() ? poses_[next_++] : CameraPose{};
  }

 private:
  PoseMode mode_;
  std::vector<CameraPose> poses_;
  size_t next_ = 0;
};

}  // namespace

std::unique_ptr<PoseSource> makeGivenPoseSource(PoseMode mode, std::vector<CameraPose> poses) {
  return std::make_unique<GivenPoses>(mode, std::move(poses));
}

std::unique_ptr<PoseSource> makePoseSource(PoseMode mode, const MarkerSpec& marker,
                                           const std::optional<capture::Pose>& T_world_marker,
                                           const TrackingOptions& options) {
  switch (mode) {
    case PoseMode::Marker:
      return std::make_unique<MarkerPoses>(marker);
    case PoseMode::GroundTruth:
      if (!T_world_marker)
        throw capture::InputError("--pose ground-truth", "needs ground_truth.T_world_marker in the manifest");
      return std::make_unique<GroundTruthPoses>(marker, *T_world_marker);
    case PoseMode::Odometry:
    case PoseMode::Tracked:
      return std::make_unique<OdometryPoses>(mode, marker, options);
  }
  return nullptr;
}

}  // namespace mrgi::runtime
