#include "reconstruction/marker.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "capture/npz.h"
#include "reconstruction/marker_image.h"

using namespace mrgi;
using namespace mrgi::reconstruction;

namespace {

const std::string kMarkerData = MRGI_SHARED_DATA;

capture::Pose poseFromRt(const cv::Vec3d& t, const cv::Vec3d& r) {
  cv::Matx33d R;
  cv::Rodrigues(r, R);
  return capture::makePose(R, t);
}

struct VispGroundTruth {
  std::map<int, std::array<cv::Point2d, 4>> corners;  // (x, y)
  std::map<int, capture::Pose> poses;
};

VispGroundTruth readVispAprilTag() {
  VispGroundTruth gt;
  std::ifstream det(kMarkerData + "/apriltag-visp/ground_truth_detection.txt"),
      pose(kMarkerData + "/apriltag-visp/ground_truth_pose.txt");
  std::string label;
  while (det >> label) {
    const int id = std::stoi(label.substr(label.rfind('_') + 1));
    for (auto& c : gt.corners[id]) det >> c.y >> c.x;  // stored as (row, col)
  }
  while (pose >> label) {
    const int id = std::stoi(label.substr(label.rfind('_') + 1));
    cv::Vec3d t, r;
    pose >> t[0] >> t[1] >> t[2] >> r[0] >> r[1] >> r[2];
    gt.poses[id] = poseFromRt(t, r);
  }
  return gt;
}

}  // namespace

TEST(Marker, RealPhotoCornersAndPosesMatchGroundTruth) {
  const cv::Mat img = cv::imread(kMarkerData + "/apriltag-visp/AprilTag.png", cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(img.empty());
  const capture::Intrinsics k{640, 480, 615.167, 615.168, 312.189, 243.437};
  const auto gt = readVispAprilTag();
  TagDetector detector;
  const auto found = detector.detect(img);
  double worstCorner = 0, worstT = 0, worstR = 0;
  int matched = 0;
  for (const auto& d : found) {
    if (!gt.poses.count(d.id)) continue;
    ++matched;
    for (int c = 0; c < 4; ++c) worstCorner = std::max(worstCorner, cv::norm(d.corners[c] - gt.corners.at(d.id)[c]));
    const auto pose = estimateTagPose(d, 0.053, k);
    ASSERT_TRUE(pose);
    worstT = std::max(worstT, translationError(pose->T_camera_tag, gt.poses.at(d.id)));
    worstR = std::max(worstR, rotationErrorDeg(pose->T_camera_tag, gt.poses.at(d.id)));
    std::printf("id %d  corner %.3f px  t %.2f mm  R %.3f deg amb %d rms %.3f alt %.3f\n", d.id,
                cv::norm(d.corners[0] - gt.corners.at(d.id)[0]),
                1e3 * translationError(pose->T_camera_tag, gt.poses.at(d.id)),
                rotationErrorDeg(pose->T_camera_tag, gt.poses.at(d.id)), pose->ambiguous, pose->reprojectionRms,
                pose->alternativeRms);
  }
  EXPECT_EQ(matched, static_cast<int>(gt.poses.size()));
  // Measured: worst corner 0.04 px, translation 0.4 mm, rotation 0.09 deg (12 tags, 0.4-0.6 m away).
  EXPECT_LT(worstCorner, 0.1);
  EXPECT_LT(worstT, 1e-3);
  EXPECT_LT(worstR, 0.25);
}

namespace {

struct VispSequence {
  capture::Intrinsics k;
  double tagSize = 0;
  nlohmann::json detections;
};

VispSequence readVispSequence() {
  VispSequence s;
  const std::string dir = kMarkerData + "/rgbd-visp-apriltag/";
  const auto cam = nlohmann::json::parse(std::ifstream(dir + "cam.json"));
  s.k = {cam["w"], cam["h"], cam["px"], cam["py"], cam["u0"], cam["v0"]};
  const auto data = nlohmann::json::parse(std::ifstream(dir + "apriltag_data.json"));
  s.tagSize = data["tag_size"];
  s.detections = data["detections"];
  return s;
}

capture::Pose poseFromJson(const nlohmann::json& m) {
  capture::Pose T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = m[r][c];
  return T;
}

}  // namespace

TEST(Marker, DetectionInARegionAroundTheTagMatchesTheWholeImages) {
  // The frame pipeline looks for its tag around where it last saw it: on real images (the 12-tag photo and
  // the 20 frames of the ViSP RGB-D sequence) every tag found in its search region has the corners found on
  // the whole image (to float rounding: 4e-5 px), and a region that cuts a tag gives no detection of it well
  // inside.
  std::vector<cv::Mat> images{cv::imread(kMarkerData + "/apriltag-visp/AprilTag.png", cv::IMREAD_COLOR)};
  for (int f = 0; f < 20; ++f) {
    char n[16];
    std::snprintf(n, sizeof n, "%04d", f);
    images.push_back(cv::imread(kMarkerData + "/rgbd-visp-apriltag/color_image_" + n + ".png", cv::IMREAD_COLOR));
  }
  TagDetector detector;
  int compared = 0, cut = 0;
  double maxDiff = 0, centreDiff = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    ASSERT_FALSE(images[i].empty()) << i;
    const cv::Mat& img = images[i];
    for (const TagDetection& whole : detector.detect(img)) {
      const cv::Rect roi = tagSearchRegion(whole.corners, 1.0);
      bool seen = false;
      for (const TagDetection& d : detector.detect(img, roi)) {
        if (d.id != whole.id) continue;
        seen = true;
        for (int c = 0; c < 4; ++c) maxDiff = std::max(maxDiff, cv::norm(d.corners[c] - whole.corners[c]));
        centreDiff = std::max(centreDiff, cv::norm(d.centre - whole.centre));
        EXPECT_TRUE(tagWellInside(d, roi & cv::Rect(0, 0, img.cols, img.rows), 4.0) ||
                    !tagWellInside(whole, cv::Rect(0, 0, img.cols, img.rows), 8.0));
      }
      EXPECT_TRUE(seen) << "image " << i << ", tag " << whole.id;
      compared += seen;
      // A region through the middle of the tag.
      const double w =
          std::abs(whole.corners[1].x - whole.corners[0].x) + std::abs(whole.corners[2].x - whole.corners[1].x);
      const cv::Rect half(cv::Point(static_cast<int>(whole.centre.x), static_cast<int>(whole.centre.y - w)),
                          cv::Point(static_cast<int>(whole.centre.x + 2 * w), static_cast<int>(whole.centre.y + w)));
      for (const TagDetection& d : detector.detect(img, half))
        if (d.id == whole.id) {
          EXPECT_FALSE(tagWellInside(d, half, 4.0)) << "image " << i << ", tag " << whole.id;
        }
      ++cut;
    }
  }
  std::printf("%d tags: corners within %.3g px, centres within %.3g px of the whole image's\n", compared, maxDiff,
              centreDiff);
  EXPECT_GT(compared, 30);
  EXPECT_EQ(compared, cut);
  EXPECT_LT(maxDiff, 1e-3);
  EXPECT_LT(centreDiff, 1e-3);
}

TEST(Marker, RealRgbdSequencePosesMatchGroundTruth) {
  const auto seq = readVispSequence();
  TagDetector detector;
  double sumT = 0, sumR = 0, sumTd = 0, sumRd = 0, worstT = 0, worstR = 0, sumTg = 0, sumRg = 0;
  int n = 0, nd = 0, reseated = 0;
  for (int f = 0; f < 20; ++f) {
    char name[64];
    std::snprintf(name, sizeof name, "%04d", f);
    const std::string dir = kMarkerData + "/rgbd-visp-apriltag/";
    const cv::Mat img = cv::imread(dir + "color_image_" + name + ".png", cv::IMREAD_GRAYSCALE);
    cv::Mat depth;
    capture::readNpzArray(dir + "depth_image_" + name + ".npz", "data.npy").convertTo(depth, CV_32F, 0.001);
    const auto& gtFrame = seq.detections[f];
    for (const auto& d : detector.detect(img)) {
      const std::string id = std::to_string(d.id);
      if (!gtFrame.contains(id)) continue;
      const capture::Pose gt = poseFromJson(gtFrame[id]["cMo"]);
      const auto pose = estimateTagPose(d, seq.tagSize, seq.k);
      ASSERT_TRUE(pose);
      const double et = translationError(pose->T_camera_tag, gt), er = rotationErrorDeg(pose->T_camera_tag, gt);
      sumT += et, sumR += er, worstT = std::max(worstT, et), worstR = std::max(worstR, er), ++n;
      if (const auto plane = fitTagPlane(d, depth, seq.k)) {
        const TagPose refined = refinePoseWithDepth(*pose, *plane);
        if (refined.depthRefined) {
          sumTd += translationError(refined.T_camera_tag, gt), sumRd += rotationErrorDeg(refined.T_camera_tag, gt),
              ++nd;
        }
      }
      // What the pipeline does: re-seat only when the depth plane agrees with the image pose.
      const auto gated = measureTagPose(d, seq.tagSize, seq.k, depth);
      ASSERT_TRUE(gated);
      sumTg += translationError(gated->T_camera_tag, gt), sumRg += rotationErrorDeg(gated->T_camera_tag, gt);
      reseated += gated->depthRefined;
    }
  }
  std::printf(
      "%d tag poses: mean t %.2f mm, R %.3f deg; worst t %.2f mm, R %.3f deg; depth-refined (%d): t %.2f mm R %.3f "
      "deg; "
      "gated (%d re-seated): t %.2f mm R %.3f deg\n",
      n, 1e3 * sumT / n, sumR / n, 1e3 * worstT, worstR, nd, 1e3 * sumTd / nd, sumRd / nd, reseated, 1e3 * sumTg / n,
      sumRg / n);
  // This sensor's depth on the tag is biased (3 cm, 6 degrees): the gate keeps the image poses.
  EXPECT_LT(1e3 * sumTg / n, 2.0);
  EXPECT_LT(sumRg / n, 0.4);
  // Measured: 147 poses (7 tags x 20 frames, ~1 m), mean 0.99 mm / 0.23 deg, worst 3.7 mm / 0.97 deg.
  EXPECT_GE(n, 140);
  EXPECT_LT(sumT / n, 2e-3);
  EXPECT_LT(sumR / n, 0.5);
  EXPECT_LT(worstT, 6e-3);
  EXPECT_LT(worstR, 2.0);
  // The sensor's depth sits ~3 cm behind the tag plane found by PnP at 1 m (and its normal ~6 deg off):
  // re-seating the pose on it moves away from this (PnP-derived) ground truth, which is why depth
  // refinement is off by default. Measured: 26 mm / 6.4 deg.
  ASSERT_GT(nd, 100);
  EXPECT_GT(sumTd / nd, sumT / n);
  EXPECT_LT(sumTd / nd, 0.05);
}

namespace {

// A tag rendered into a pinhole image at a known pose (bilinear warp of the libapriltag bitmap).
cv::Mat renderTagView(int id, double size, const capture::Pose& T_camera_tag, const capture::Intrinsics& k,
                      uchar background = 200) {
  TagLayout layout{};
  cv::Mat cells = renderTag("tag36h11", id, &layout);
  const int scale = 32;
  cv::Mat big;
  cv::resize(cells, big, {}, scale, scale, cv::INTER_NEAREST);
  const double cell = size / layout.borderCells, half = layout.totalCells / 2.0;
  // bitmap pixel (u, v) -> tag plane (X, Y, 1): X = (u / scale - half) * cell, Y = -(v / scale - half) * cell
  const cv::Matx33d A(cell / scale, 0, -half * cell, 0, -cell / scale, half * cell, 0, 0, 1);
  const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  const cv::Matx33d Rt(T_camera_tag(0, 0), T_camera_tag(0, 1), T_camera_tag(0, 3), T_camera_tag(1, 0),
                       T_camera_tag(1, 1), T_camera_tag(1, 3), T_camera_tag(2, 0), T_camera_tag(2, 1),
                       T_camera_tag(2, 3));
  // Half-pixel shift: bitmap pixel centres sit at +0.5 cell/scale.
  const cv::Matx33d shift(1, 0, -0.5, 0, 1, -0.5, 0, 0, 1);
  const cv::Matx33d H = K * Rt * A * shift.inv();
  cv::Mat out(k.height, k.width, CV_8UC1, cv::Scalar(background));
  cv::warpPerspective(big, out, cv::Mat(H), out.size(), cv::INTER_AREA, cv::BORDER_TRANSPARENT);
  return out;
}

capture::Pose lookAtTag(double distance, double tiltDeg, double yawDeg) {
  // Camera looking at the tag centre from `distance`, tag tilted about its x axis and turned about y.
  cv::Matx33d Rx, Ry;
  cv::Rodrigues(cv::Vec3d(CV_PI + tiltDeg * CV_PI / 180, 0, 0), Rx);  // z out of the tag towards the camera
  cv::Rodrigues(cv::Vec3d(0, yawDeg * CV_PI / 180, 0), Ry);
  return capture::makePose(Ry * Rx, cv::Vec3d(0.02, -0.01, distance));
}

}  // namespace

TEST(Marker, SyntheticViewGivesTheRenderedPoseAndFrameConvention) {
  const capture::Intrinsics k{640, 480, 600, 600, 319.5, 239.5};
  TagDetector detector;
  for (const auto& [dist, tilt, yaw] :
       {std::tuple{0.5, 20.0, 0.0}, std::tuple{0.8, 45.0, 30.0}, std::tuple{0.4, -10.0, -50.0}}) {
    const capture::Pose truth = lookAtTag(dist, tilt, yaw);
    const auto found = detector.detect(renderTagView(7, 0.1, truth, k));
    ASSERT_EQ(found.size(), 1u) << dist << " " << tilt << " " << yaw;
    EXPECT_EQ(found[0].id, 7);
    const auto pose = estimateTagPose(found[0], 0.1, k);
    ASSERT_TRUE(pose);
    EXPECT_LT(translationError(pose->T_camera_tag, truth), 0.005 * dist) << tilt << " " << yaw;  // measured <= 3 mm
    EXPECT_LT(rotationErrorDeg(pose->T_camera_tag, truth), 1.0) << tilt << " " << yaw;
    // z points back at the camera; x runs along the first edge.
    const cv::Vec3d z(pose->T_camera_tag(0, 2), pose->T_camera_tag(1, 2), pose->T_camera_tag(2, 2));
    const cv::Vec3d t = capture::translationOf(pose->T_camera_tag);
    EXPECT_LT(z.dot(t), 0.0);
    const cv::Point2d edge = found[0].corners[1] - found[0].corners[0];
    const cv::Vec3d x(pose->T_camera_tag(0, 0), pose->T_camera_tag(1, 0), pose->T_camera_tag(2, 0));
    EXPECT_GT(edge.x * x[0] + edge.y * x[1], 0.0);
  }
}

TEST(Marker, PartialGrazingAndEmptyViewsAreHandled) {
  const capture::Intrinsics k{640, 480, 600, 600, 319.5, 239.5};
  TagDetector detector;
  // Half out of frame: not detected (or detected with a valid pose), never a crash.
  capture::Pose T = lookAtTag(0.5, 0, 0);
  T(0, 3) = 0.27;
  for (const auto& d : detector.detect(renderTagView(3, 0.1, T, k)))
    EXPECT_TRUE(estimateTagPose(d, 0.1, k).has_value());
  // Grazing view (85 degrees).
  for (const auto& d : detector.detect(renderTagView(3, 0.1, lookAtTag(0.5, 85, 0), k))) {
    const auto p = estimateTagPose(d, 0.1, k);
    if (p) {
      EXPECT_TRUE(cv::checkRange(cv::Mat(p->T_camera_tag)));
    }
  }
  EXPECT_TRUE(detector.detect(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0))).empty());
  EXPECT_TRUE(detector.detect(cv::Mat(480, 640, CV_8UC1, cv::Scalar(255))).empty());
  EXPECT_TRUE(detector.detect(cv::Mat()).empty());
  // Degenerate corners: no pose rather than garbage.
  TagDetection collapsed;
  collapsed.corners = {cv::Point2d(10, 10), cv::Point2d(10, 10), cv::Point2d(10, 10), cv::Point2d(10, 10)};
  EXPECT_FALSE(estimateTagPose(collapsed, 0.1, k));
  collapsed.corners[2] = {std::nan(""), 3};
  EXPECT_FALSE(estimateTagPose(collapsed, 0.1, k));
  EXPECT_THROW(TagDetector(DetectorOptions{.family = "tag99h99"}), std::invalid_argument);
}

TEST(Marker, AmbiguousFrontoParallelViewFollowsThePreviousPose) {
  // A small, distant, nearly fronto-parallel tag: IPPE's two solutions explain the corners almost
  // equally; the one closer to the previous pose (or the depth plane's normal) must win.
  const capture::Intrinsics k{640, 480, 600, 600, 319.5, 239.5};
  const capture::Pose truth = lookAtTag(3.0, 8, 0);
  const auto& c = tagCornersInTagFrame(0.05);
  TagDetection d;
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 0.3);
  for (int i = 0; i < 4; ++i) {
    const cv::Vec3d p = capture::transformPoint(truth, cv::Vec3d(c[i].x, c[i].y, c[i].z));
    d.corners[i] = {k.fx * p[0] / p[2] + k.cx + noise(rng), k.fy * p[1] / p[2] + k.cy + noise(rng)};
  }
  const auto free = estimateTagPose(d, 0.05, k);
  ASSERT_TRUE(free);
  EXPECT_TRUE(free->ambiguous);
  // The mirror of the truth (tilted the other way) as a competing hint selects the other solution.
  const capture::Pose mirror = lookAtTag(3.0, -8, 0);
  const auto towardsTruth = estimateTagPose(d, 0.05, k, {}, &truth);
  const auto towardsMirror = estimateTagPose(d, 0.05, k, {}, &mirror);
  ASSERT_TRUE(towardsTruth && towardsMirror);
  const double good = rotationErrorDeg(towardsTruth->T_camera_tag, truth);
  const double bad = rotationErrorDeg(towardsMirror->T_camera_tag, truth);
  EXPECT_LT(good, 10.0);  // 10 px tag, 0.3 px corner noise: the right branch is still ~9 degrees off
  EXPECT_GT(bad, good + 5.0);
  const cv::Vec3d n(truth(0, 2), truth(1, 2), truth(2, 2));
  const auto withPlane = estimateTagPose(d, 0.05, k, {}, nullptr, &n);
  ASSERT_TRUE(withPlane);
  EXPECT_NEAR(rotationErrorDeg(withPlane->T_camera_tag, truth), good, 1e-9);
}

TEST(Marker, DepthPlaneRefinementSeatsThePoseOnTheMeasuredPlane) {
  const capture::Intrinsics k{640, 480, 600, 600, 319.5, 239.5};
  const capture::Pose truth = lookAtTag(0.6, 30, 10);
  TagDetector detector;
  const auto found = detector.detect(renderTagView(5, 0.1, truth, k));
  ASSERT_EQ(found.size(), 1u);
  // Depth of the true plane everywhere.
  const cv::Vec3d n(truth(0, 2), truth(1, 2), truth(2, 2)), p0 = capture::translationOf(truth);
  cv::Mat depth(480, 640, CV_32F);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      const cv::Vec3d ray((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1);
      depth.at<float>(y, x) = static_cast<float>(n.dot(p0) / n.dot(ray));
    }
  const auto plane = fitTagPlane(found[0], depth, k);
  ASSERT_TRUE(plane);
  EXPECT_GT(plane->first.dot(n), 0.99999);
  // A pose 3 degrees and 2 cm off is pulled back onto the plane.
  TagPose off;
  cv::Matx33d dR;
  cv::Rodrigues(0.05 * cv::Vec3d(truth(0, 0), truth(1, 0), truth(2, 0)), dR);  // tilt about the tag's x axis
  off.T_camera_tag = capture::makePose(dR * capture::rotationOf(truth), 1.03 * capture::translationOf(truth));
  const TagPose fixed = refinePoseWithDepth(off, *plane);
  EXPECT_TRUE(fixed.depthRefined);
  EXPECT_LT(translationError(fixed.T_camera_tag, truth), 1e-4);
  EXPECT_LT(rotationErrorDeg(fixed.T_camera_tag, truth), 0.01);
  // A plane that disagrees by more than the limit leaves the pose alone; no samples -> no plane.
  EXPECT_FALSE(refinePoseWithDepth(off, {cv::Vec3d(0, 0, -1) * -1.0, p0}, 25).depthRefined);
  EXPECT_FALSE(fitTagPlane(found[0], cv::Mat(480, 640, CV_32F, cv::Scalar(0)), k));
}

TEST(Marker, OneEuroSmoothsJitterWithoutLaggingFastMotion) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 0.002);  // 2 mm jitter
  PoseSmoother smoother;
  // Static tag: jitter is reduced at least 2.5x (measured 3.0x with the default beta).
  double rawVar = 0, outVar = 0;
  for (int i = 0; i < 300; ++i) {
    capture::Pose T = capture::identityPose();
    T(2, 3) = 1.0 + noise(rng);
    const capture::Pose s = smoother.filter(i / 30.0, T);
    if (i > 30) rawVar += std::pow(T(2, 3) - 1.0, 2), outVar += std::pow(s(2, 3) - 1.0, 2);
  }
  EXPECT_LT(std::sqrt(outVar / rawVar), 0.4);
  // Fast motion (1 m/s at 30 Hz): after settling, the smoothed pose trails by less than 1.5 frames of motion.
  smoother.reset();
  double worstLag = 0;
  for (int i = 0; i < 60; ++i) {
    capture::Pose T = capture::identityPose();
    T(0, 3) = i / 30.0;
    const capture::Pose s = smoother.filter(i / 30.0, T);
    if (i > 10) worstLag = std::max(worstLag, T(0, 3) - s(0, 3));
  }
  EXPECT_LT(worstLag, 1.5 / 30.0);
  // A 90-degree turn at 3 rad/s is followed to within 10 degrees while moving.
  smoother.reset();
  double worstAngle = 0;
  for (int i = 0; i <= 15; ++i) {
    const capture::Pose T = poseFromRt({0, 0, 0}, {0, i * 0.1, 0});
    const capture::Pose s = smoother.filter(i / 30.0, T);
    if (i > 5) worstAngle = std::max(worstAngle, rotationErrorDeg(s, T));
  }
  EXPECT_LT(worstAngle, 10.0);
}

TEST(Marker, TrackHoldsThenReportsLoss) {
  MarkerTrack track(TrackerOptions{.holdSeconds = 0.5});
  capture::Pose T = capture::identityPose();
  T(2, 3) = 1.0;
  EXPECT_EQ(track.update(0.0, std::nullopt), TrackStatus::Lost);  // never seen
  EXPECT_FALSE(track.pose());
  EXPECT_EQ(track.update(0.1, T), TrackStatus::Tracked);
  EXPECT_EQ(track.update(0.4, std::nullopt), TrackStatus::Held);
  EXPECT_NEAR((*track.pose())(2, 3), 1.0, 1e-12);
  EXPECT_EQ(track.update(0.6, std::nullopt), TrackStatus::Held);
  EXPECT_EQ(track.update(0.7, std::nullopt), TrackStatus::Lost);
  // Re-acquired after a loss: no smoothing across the gap, the new pose is taken as is.
  T(2, 3) = 2.0;
  EXPECT_EQ(track.update(1.0, T), TrackStatus::Tracked);
  EXPECT_NEAR((*track.pose())(2, 3), 2.0, 1e-12);
  EXPECT_STREQ(toString(TrackStatus::Held), "held");
}

TEST(Marker, TaggedPointLightFollowsItsTag) {
  // A lamp 12 cm above its tag (tag z out of the tag), seen in the synthetic view.
  const capture::Intrinsics k{640, 480, 600, 600, 319.5, 239.5};
  const capture::Pose truth = lookAtTag(0.7, 25, 15);
  TagDetector detector;
  const auto found = detector.detect(renderTagView(2, 0.08, truth, k));
  ASSERT_EQ(found.size(), 1u);
  const auto pose = estimateTagPose(found[0], 0.08, k);
  ASSERT_TRUE(pose);
  const TaggedPointLight lamp{2, {0, 0, 0.12}, {5, 5, 4}};
  const cv::Vec3d expected = capture::transformPoint(truth, lamp.offset);
  EXPECT_LT(cv::norm(taggedLightPosition(lamp, pose->T_camera_tag) - expected), 4e-3);
  // The light sits on the tag's normal, towards the camera side.
  const cv::Vec3d centre = capture::translationOf(truth);
  EXPECT_LT(cv::norm(expected), cv::norm(centre));
}

TEST(Marker, TrackerDefaultsFollowAnOrbitingCameraAndCalmAStaticOne) {
  // The bundled sessions' motion: the camera orbits the tag at 0.9 m, 1.35 rad/s, 30 fps. The old defaults
  // (beta 20, speed estimate at 1 Hz) trailed by 14-20 mm over the first frames; the tuned ones stay close.
  auto cameraAt = [](double a) {
    const cv::Vec3d eye(0.9 * std::sin(a), -0.9 * std::cos(a), 0.55);
    return capture::lookAtPose(eye, {0, 0, 0});  // T_tag_camera
  };
  std::mt19937 rng(5);
  std::normal_distribution<double> mm(0, 0.0005);  // 0.5 mm measurement jitter
  MarkerTrack moving;
  double sum = 0;
  for (int i = 0; i < 10; ++i) {
    const capture::Pose truth = cameraAt(1.35 * i / 30.0);
    capture::Pose measured = capture::inversePose(truth);
    for (int k = 0; k < 3; ++k) measured(k, 3) += mm(rng);
    moving.update(i / 30.0, measured);
    sum += translationError(capture::inversePose(*moving.pose()), truth);
  }
  EXPECT_LT(sum / 10 * 1000.0, 6.0);  // mean camera position error, mm
  // A static camera: the output moves less than half as much from frame to frame as the measurements.
  MarkerTrack still;
  double rawMove = 0, outMove = 0;
  capture::Pose lastRaw, lastOut;
  for (int i = 0; i < 120; ++i) {
    capture::Pose measured = capture::inversePose(cameraAt(0.3));
    for (int k = 0; k < 3; ++k) measured(k, 3) += mm(rng);
    still.update(i / 30.0, measured);
    if (i > 30) rawMove += translationError(measured, lastRaw), outMove += translationError(*still.pose(), lastOut);
    lastRaw = measured, lastOut = *still.pose();
  }
  EXPECT_LT(outMove / rawMove, 0.5);
}
