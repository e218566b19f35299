// Camera poses beyond the marker: the pose modes' one spelling, dense RGB-D odometry against the tags' own
// poses on real frames with every tag painted out after the first, on synthetic sessions against their ground
// truth, the marker's bounded correction when the tag returns, and loss and relocalisation across a jump.
#include "runtime/pose_source.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/colour.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/npz.h"
#include "capture/registration.h"
#include "capture/session.h"
#include "compositor/compositor.h"
#include "evaluation/tracking_metrics.h"
#include "gl/context.h"
#include "lighting/scene_file.h"
#include "reconstruction/marker.h"
#include "reconstruction/odometry.h"
#include "reconstruction/room_lights.h"
#include "runtime/frame_pipeline.h"
#include "runtime/room_fusion.h"

namespace mrgi::runtime {
namespace {

const std::string kData = MRGI_SHARED_DATA;
const std::string kRecordings = std::string(MRGI_SOURCE_DIR) + "/recordings/";

capture::Pose poseFromRows(const nlohmann::json& m) {
  capture::Pose T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = m[r][c];
  return T;
}

/// The ViSP desk sequence (real RealSense frames, 640x480) with its tags' poses; from `paintFrom` on, every
/// tag is painted out (its quad, grown by half its size, filled flat grey) so that no marker is found.
struct Visp {
  std::vector<capture::Frame> frames;
  std::vector<capture::Pose> T_world_camera;  ///< ground truth: the camera in tag 0's frame
  MarkerSpec marker;
  std::vector<cv::Vec3d> tagCentres;                  ///< every tag's centre in tag 0's frame (from frame 0)
  std::vector<std::vector<cv::Point2d>> seenCentres;  ///< per frame, where each tag's centre was detected
};

Visp readVisp(int paintFrom) {
  const std::string dir = kData + "/rgbd-visp-apriltag/";
  const auto cam = nlohmann::json::parse(std::ifstream(dir + "cam.json"));
  const auto data = nlohmann::json::parse(std::ifstream(dir + "apriltag_data.json"));
  const capture::Intrinsics k{cam["w"], cam["h"], cam["px"], cam["py"], cam["u0"], cam["v0"]};
  Visp v;
  v.marker = {"tag36h11", data["tag_size"].get<double>(), 0};
  for (int f = 0; f < 20; ++f) {
    char name[16];
    std::snprintf(name, sizeof name, "%04d", f);
    cv::Mat bgr = cv::imread(dir + "color_image_" + name + ".png", cv::IMREAD_COLOR), rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    const auto& tags = data["detections"][f];
    if (f >= paintFrom)
      for (const auto& [id, tag] : tags.items()) {
        std::vector<cv::Point2f> quad;
        cv::Point2f centre(0, 0);
        for (const auto& rc : tag["tag_corners"])
          quad.emplace_back(rc[1].get<float>(), rc[0].get<float>()), centre += quad.back() / 4;
        std::vector<cv::Point> grown;
        for (const auto& p : quad) grown.emplace_back(centre + 1.5f * (p - centre));
        cv::fillConvexPoly(rgb, grown, cv::Scalar(128, 128, 128));
      }
    std::vector<cv::Point2d> centres;
    for (const auto& [id, tag] : tags.items()) {
      cv::Point2d c(0, 0);
      for (const auto& rc : tag["tag_corners"]) c += cv::Point2d(rc[1].get<double>(), rc[0].get<double>()) / 4;
      centres.push_back(c);
      if (f == 0)
        v.tagCentres.push_back(
            capture::translationOf(capture::inversePose(poseFromRows(tags["0"]["cMo"])) * poseFromRows(tag["cMo"])));
    }
    v.seenCentres.push_back(centres);
    capture::Frame fr;
    fr.index = f;
    fr.timestamp = f / 30.0;
    capture::RgbdFrame rgbd;
    rgbd.colour = rgb;
    capture::readNpzArray(dir + "depth_image_" + name + ".npz", "data.npy").convertTo(rgbd.depth, CV_32F, 0.001);
    rgbd.colourIntrinsics = rgbd.depthIntrinsics = k;
    fr.rgbd = rgbd;
    v.frames.push_back(fr);
    v.T_world_camera.push_back(capture::inversePose(poseFromRows(data["grid"][f])));
  }
  // The board's camera poses (from every tag: steadier than one tag's) in tag 0's frame, the world the marker
  // anchors: through frame 0, so that what is measured is the motion since the anchor.
  const capture::Pose T_tag_board =
      capture::inversePose(poseFromRows(data["detections"][0]["0"]["cMo"])) * poseFromRows(data["grid"][0]);
  for (auto& T : v.T_world_camera) T = T_tag_board * T;
  return v;
}

struct Trajectory {
  std::vector<CameraPose> poses;
  double ateRmseM = 0, lastDriftM = 0, maxM = 0;
  int tracked = 0;
};

Trajectory run(PoseSource& source, std::vector<capture::Frame> frames, const std::vector<capture::Pose>& truth) {
  Trajectory t;
  gl::Profiler profiler;
  std::vector<std::optional<capture::Pose>> estimate;
  for (size_t i = 0; i < frames.size(); ++i) {
    capture::ensureRegistered(*frames[i].rgbd);
    t.poses.push_back(source.locate(frames[i], profiler));
    estimate.push_back(t.poses.back().T_world_camera);
  }
  const evaluation::TrajectoryError e = evaluation::trajectoryError(estimate, truth);
  t.tracked = e.tracked, t.ateRmseM = e.ateRmseM, t.maxM = e.ateMaxM, t.lastDriftM = e.lastM;
  return t;
}

/// A bundled synthetic session: its frames (those `keep` accepts, possibly altered) with their true camera
/// poses in the marker frame, and its marker.
struct Synthetic {
  std::vector<capture::Frame> frames;
  std::vector<capture::Pose> truth;
  MarkerSpec marker;
};
Synthetic readSynthetic(const std::string& name, const std::function<bool(capture::Frame&)>& keep = {}) {
  auto src = capture::open(kRecordings + name);
  const auto* m = src->sessionManifest();
  EXPECT_TRUE(m && m->marker && m->truth.T_world_marker) << name;
  Synthetic s;
  s.marker = {m->marker->family, m->marker->sizeMetres, m->marker->id};
  const capture::Pose T_marker_world = capture::inversePose(*m->truth.T_world_marker);
  while (auto f = src->next()) {
    if (keep && !keep(*f)) continue;
    s.truth.push_back(T_marker_world * *f->groundTruthT_world_camera);
    s.frames.push_back(*f);
  }
  return s;
}

/// How far from where they were detected a trajectory draws the ViSP tags' centres over frames [from, to)
/// (pixels, RMS): how far an object placed on the board would slide in the image.
double centreReprojectionPx(const Visp& v, const Trajectory& t, int from, int to) {
  double sum2 = 0;
  int n = 0;
  for (int f = from; f < to; ++f) {
    if (!t.poses[f].tracked()) continue;
    const capture::Pose T_camera_world = capture::inversePose(*t.poses[f].T_world_camera);
    const capture::Intrinsics& k = v.frames[f].rgbd->colourIntrinsics;
    for (size_t i = 0; i < v.tagCentres.size(); ++i) {
      const cv::Vec3d p = capture::transformPoint(T_camera_world, v.tagCentres[i]);
      const cv::Point2d uv(k.fx * p[0] / p[2] + k.cx, k.fy * p[1] / p[2] + k.cy);
      sum2 += std::pow(cv::norm(uv - v.seenCentres[f][i]), 2), ++n;
    }
  }
  return n ? std::sqrt(sum2 / n) : 0.0;
}

TEST(PoseModes, OneSpellingRoundTripsAndABadNameNamesTheFlag) {
  ASSERT_EQ(poseModeNames(), (std::vector<std::string>{"marker", "ground-truth", "odometry", "tracked"}));
  for (const auto& n : poseModeNames()) EXPECT_EQ(toString(poseModeFromName(n)), n);
  try {
    poseModeFromName("markr", "--pose");
    FAIL();
  } catch (const capture::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--pose: 'markr'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(makePoseSource(PoseMode::GroundTruth, {}, std::nullopt), capture::InputError);
}

TEST(Odometry, PaintedVispFramesFollowTheTagsPoses) {
  // The real desk sequence with every tag painted out after frame 0: the marker anchors the world on frame 0,
  // odometry carries it through the other 19 frames. Against the tags' own poses (about 1 mm).
  const Visp v = readVisp(1);
  auto source = makePoseSource(PoseMode::Odometry, v.marker, std::nullopt);
  const Trajectory t = run(*source, v.frames, v.T_world_camera);
  std::printf("painted ViSP, odometry: %d of %zu frames tracked, ATE RMSE %.2f mm, max %.2f mm, last frame %.2f mm\n",
              t.tracked, v.frames.size(), 1e3 * t.ateRmseM, 1e3 * t.maxM, 1e3 * t.lastDriftM);
  EXPECT_EQ(t.tracked, 20);
  EXPECT_EQ(t.poses[0].by, PosedBy::Marker);
  for (size_t i = 1; i < t.poses.size(); ++i) {
    EXPECT_EQ(t.poses[i].marker, "-") << "odometry mode looks for the marker only until it has anchored the world";
    if (t.poses[i].tracked()) {
      EXPECT_NE(t.poses[i].by, PosedBy::Marker) << i;
    }
  }
  const double px = centreReprojectionPx(v, t, 1, 20);
  std::printf("  the tags' centres drawn %.2f px RMS from where they were detected\n", px);
  // Measured: 13.9 mm ATE, 2.6 px. The 5 mm is not reached against these poses: they and the
  // sensor's depth disagree (Odometry.VispDepthDisagreesWithTheTagsMotion), while the image, which is what an
  // inserted object is judged by, stays within 3 px.
  EXPECT_LT(t.ateRmseM, 0.02);
  EXPECT_LT(px, 3.5);
}

TEST(Odometry, VispDepthDisagreesWithTheTagsMotion) {
  // Why the ViSP ATE stays above 5 mm: from frame 0 to 16 the tags say the camera moved 35 mm and 3.3 degrees;
  // the sensor's depth aligns far worse at that motion than at the one odometry finds (point-to-plane RMSE
  // over the whole view), so the two references cannot both be met. Frames 0-8, where the tags say the camera
  // stood still to 0.2 mm, show odometry's own noise: under 5 mm.
  const Visp v = readVisp(100);
  reconstruction::OdometryOptions o;
  o.method = reconstruction::OdometryMethod::PointToPlane;  // depth alone
  const auto& a = *v.frames[0].rgbd;
  const auto& b = *v.frames[16].rgbd;
  const reconstruction::OdometryFrame A(a.depth, a.colour, a.colourIntrinsics, o),
      B(b.depth, b.colour, b.colourIntrinsics, o);
  const auto estimate = reconstruction::estimateOdometry(B, A, capture::identityPose(), o);
  ASSERT_TRUE(estimate.solved);
  reconstruction::OdometryOptions measureOnly = o;
  measureOnly.iterations = {0, 0, 0};
  const capture::Pose tags = capture::inversePose(v.T_world_camera[0]) * v.T_world_camera[16];
  const auto atTags = reconstruction::estimateOdometry(B, A, tags, measureOnly);
  std::printf(
      "frame 16 against 0: depth residual %.1f mm at the tags' motion (%.1f mm, %.2f deg), %.1f mm at odometry's\n",
      1e3 * atTags.inlierRmse, 1e3 * cv::norm(capture::translationOf(tags)),
      reconstruction::rotationErrorDeg(tags, capture::identityPose()), 1e3 * estimate.inlierRmse);
  EXPECT_GT(atTags.inlierRmse, 1.3 * estimate.inlierRmse);
  // Nor do the tags agree among themselves: the camera placed by each tag alone (through its place on the
  // board in frame 0) lies 10-30 mm from the board's pose over frames 16-19, where 5 mm is asked of odometry.
  const auto data = nlohmann::json::parse(std::ifstream(kData + "/rgbd-visp-apriltag/apriltag_data.json"));
  const capture::Pose board0 = poseFromRows(data["grid"][0]);
  double sum2 = 0;
  int n = 0;
  for (int f = 16; f < 20; ++f) {
    const cv::Vec3d byBoard = capture::translationOf(capture::inversePose(poseFromRows(data["grid"][f])));
    for (const auto& [id, tag] : data["detections"][f].items()) {
      if (!data["detections"][0].contains(id)) continue;
      const capture::Pose T_tag_board = capture::inversePose(poseFromRows(data["detections"][0][id]["cMo"])) * board0;
      const cv::Vec3d byTag =
          capture::translationOf(capture::inversePose(T_tag_board) * capture::inversePose(poseFromRows(tag["cMo"])));
      sum2 += std::pow(cv::norm(byTag - byBoard), 2), ++n;
    }
  }
  ASSERT_GT(n, 20);
  std::printf("frames 16-19: the camera by each tag alone %.1f mm RMS from the board's pose (%d sightings)\n",
              1e3 * std::sqrt(sum2 / n), n);
  EXPECT_GT(std::sqrt(sum2 / n), 0.01);
  for (int f = 1; f <= 8; ++f) {
    const auto& c = *v.frames[f].rgbd;
    const reconstruction::OdometryFrame C(c.depth, c.colour, c.colourIntrinsics, o);
    const auto still = reconstruction::estimateOdometry(C, A, capture::identityPose(), o);
    EXPECT_LT(cv::norm(capture::translationOf(still.T_target_source)), 5e-3) << f;
  }
}

TEST(Odometry, SyntheticSessionsFollowTheirGroundTruth) {
  // Every frame from the first marker sighting on is tracked; the motion since that anchor against the
  // session's ground truth (the anchor's own error is the marker's: 27 mm on tabletop-carve, whose tag is
  // half hidden).
  for (const std::string name : {"tabletop-synth", "tabletop-carve"}) {
    const Synthetic session = readSynthetic(name);
    const auto& frames = session.frames;
    const auto& truth = session.truth;
    auto source = makePoseSource(PoseMode::Odometry, session.marker, std::nullopt);
    Trajectory t = run(*source, frames, truth);
    size_t anchor = 0;
    while (anchor < frames.size() && !t.poses[anchor].tracked()) ++anchor;
    ASSERT_LT(anchor, frames.size());
    EXPECT_EQ(t.poses[anchor].by, PosedBy::Marker);
    const capture::Pose align = *t.poses[anchor].T_world_camera * capture::inversePose(truth[anchor]);
    double sum2 = 0, last = 0;
    for (size_t i = anchor; i < frames.size(); ++i) {
      ASSERT_TRUE(t.poses[i].tracked()) << name << " frame " << i;
      last = reconstruction::translationError(*t.poses[i].T_world_camera, align * truth[i]);
      sum2 += last * last;
    }
    const double rmse = std::sqrt(sum2 / static_cast<double>(frames.size() - anchor));
    std::printf(
        "%s, odometry: frames %zu-%zu tracked from the marker's anchor, drift RMSE %.2f mm, last frame %.2f mm\n",
        name.c_str(), anchor, frames.size() - 1, 1e3 * rmse, 1e3 * last);
    EXPECT_LT(rmse, 6e-3) << name;  // measured 1.2 (synth) and 4.9 mm (carve, whose objects move)
    EXPECT_LT(last, 8e-3) << name;
  }
}

TEST(Tracking, ASessionWithTheMarkerInViewStaysOnItAndRigid) {
  // tabletop-synth with its tag seen in every frame, tracked: every pose within 3 mm of the truth (the marker's
  // own error at 320x240 is 4 mm RMS, odometry's drift 2 mm), and a rotation to rounding however many
  // corrections its keyframes carried (a correction carried each frame once compounded to 180 mm by frame 19).
  const Synthetic session = readSynthetic("tabletop-synth");
  const auto& frames = session.frames;
  const auto& truth = session.truth;
  auto source = makePoseSource(PoseMode::Tracked, session.marker, std::nullopt);
  const Trajectory t = run(*source, frames, truth);
  std::printf("tabletop-synth, tracked: ATE RMSE %.2f mm, max %.2f mm\n", 1e3 * t.ateRmseM, 1e3 * t.maxM);
  EXPECT_EQ(t.tracked, 20);
  EXPECT_LT(t.maxM, 3e-3);
  for (const CameraPose& p : t.poses) {
    const cv::Matx33d R = capture::rotationOf(*p.T_world_camera);
    EXPECT_LT(cv::norm(R.t() * R - cv::Matx33d::eye()), 1e-9);
  }
}

TEST(Tracking, TheReturningMarkerCorrectsWithoutAJump) {
  // Tags painted out over frames 1-9 and back from 10 (real frames). Tracked: odometry alone over 1-9; from
  // frame 10 each sighting pulls the pose towards the marker's by a bounded step, so the object does not jump
  // by the drift odometry gathered, and the pose ends at the marker's.
  Visp v = readVisp(1);
  const Visp seen = readVisp(100);
  for (int f = 10; f < 20; ++f) v.frames[f] = seen.frames[f];
  auto tracked = makePoseSource(PoseMode::Tracked, v.marker, std::nullopt);
  auto odometry = makePoseSource(PoseMode::Odometry, v.marker, std::nullopt);
  auto marker = makePoseSource(PoseMode::Marker, v.marker, std::nullopt);
  const Trajectory t = run(*tracked, v.frames, v.T_world_camera);
  const Trajectory o = run(*odometry, v.frames, v.T_world_camera);
  const Trajectory m = run(*marker, v.frames, v.T_world_camera);
  ASSERT_EQ(t.tracked, 20);
  const TrackingOptions defaults;
  for (int f = 1; f < 10; ++f) {
    EXPECT_EQ(t.poses[f].by, PosedBy::Odometry) << f;
    EXPECT_EQ(t.poses[f].marker, "lost") << f;
  }
  for (int f = 10; f < 20; ++f) {
    EXPECT_EQ(t.poses[f].by, PosedBy::Marker) << f;
    EXPECT_LE(t.poses[f].correctionM, defaults.maxCorrectionM + 1e-9);
    EXPECT_LE(t.poses[f].correctionDeg, defaults.maxCorrectionDeg + 1e-9);
  }
  // The returning tag moves the object by at most the correction's bound beyond what odometry moved it.
  const capture::Pose stepTracked = capture::inversePose(*t.poses[9].T_world_camera) * *t.poses[10].T_world_camera;
  const capture::Pose stepOdometry = capture::inversePose(*o.poses[9].T_world_camera) * *o.poses[10].T_world_camera;
  EXPECT_LT(reconstruction::translationError(stepTracked, stepOdometry), defaults.maxCorrectionM + 1e-3);
  EXPECT_LT(reconstruction::rotationErrorDeg(stepTracked, stepOdometry), defaults.maxCorrectionDeg + 0.1);
  // Where the tags are drawn while they are seen: the marker's own poses, tracked (the marker's pull over
  // odometry) and odometry alone. Tracked comes back to the marker: closer than odometry alone.
  const double pxTracked = centreReprojectionPx(v, t, 10, 20), pxOdometry = centreReprojectionPx(v, o, 10, 20),
               pxMarker = centreReprojectionPx(v, m, 10, 20);
  std::printf(
      "tags back from frame 10: their centres drawn %.2f px RMS (tracked), %.2f (odometry alone), %.2f (marker "
      "alone)\n",
      pxTracked, pxOdometry, pxMarker);
  EXPECT_LT(pxTracked, pxOdometry);
  EXPECT_LT(pxTracked, 2.0);
}

TEST(Tracking, AJumpIsLostThenRelocalised) {
  // Frames 6-11 of the synthetic orbit dropped (the camera jumps 0.25 m and 18 degrees) and a blank frame
  // (no depth, black image: a sensor hiccup) where they were. The blank frame is lost: no pose at all, never
  // a guess. Odometry cannot follow the jump, and within 3 frames the keyframes' ORB features and depth place
  // the camera again, at the right pose.
  const Synthetic session = readSynthetic("tabletop-synth", [](capture::Frame& f) {
    if (f.index == 6) {
      f.rgbd->depth.setTo(0);
      f.rgbd->colour.setTo(0);
    }
    return f.index <= 6 || f.index >= 12;
  });
  const auto& frames = session.frames;
  const auto& truth = session.truth;
  auto source = makePoseSource(PoseMode::Odometry, session.marker, std::nullopt);
  const Trajectory t = run(*source, frames, truth);
  ASSERT_TRUE(t.poses[5].tracked());
  EXPECT_FALSE(t.poses[6].tracked()) << "a blank frame is lost";
  int back = -1;
  for (int i = 7; i < 10 && back < 0; ++i) {
    if (t.poses[i].tracked())
      back = i;
    else
      EXPECT_EQ(t.poses[i].fitness < 0 || t.poses[i].fitness < 0.9, true);
  }
  ASSERT_GE(back, 0) << "relocalised within 3 frames";
  EXPECT_EQ(t.poses[back].by, PosedBy::Relocalised);
  EXPECT_LT(reconstruction::translationError(*t.poses[back].T_world_camera, truth[back]), 0.015);
  EXPECT_LT(reconstruction::rotationErrorDeg(*t.poses[back].T_world_camera, truth[back]), 1.0);
  // From there odometry carries on at the drift it had before the jump.
  for (size_t i = static_cast<size_t>(back); i < t.poses.size(); ++i) {
    ASSERT_TRUE(t.poses[i].tracked()) << i;
    EXPECT_LT(reconstruction::translationError(*t.poses[i].T_world_camera, truth[i]), 0.015) << i;
  }
}

TEST(Tracking, FrameToModelAlignsEachFrameWithTheRoom) {
  // With a saved room (fused here at the true poses), odometry aligns each frame with the room as seen from
  // the predicted pose (frame-to-model, point to plane) before any keyframe: the room holds the world, so the
  // marker's error on the anchoring frame does not stay (tabletop-pt: 8 mm against keyframes alone).
  for (const std::string name : {"tabletop-synth", "tabletop-pt"}) {
    RoomFusionOptions truthPoses;
    truthPoses.pose = PoseMode::GroundTruth;
    const auto room =
        std::make_shared<const reconstruction::RoomMesh>(fuseRoom(kRecordings + name, truthPoses).model.mesh());
    const Synthetic session = readSynthetic(name);
    const auto& frames = session.frames;
    const auto& truth = session.truth;
    const MarkerSpec& marker = session.marker;
    auto keyframes = makePoseSource(PoseMode::Odometry, marker, std::nullopt);
    auto model = makePoseSource(PoseMode::Odometry, marker, std::nullopt);
    model->useModel(room);
    const Trajectory k = run(*keyframes, frames, truth), t = run(*model, frames, truth);
    std::printf(
        "%s, odometry: ATE RMSE %.2f mm against keyframes, %.2f mm against the room (last frame %.2f / %.2f mm)\n",
        name.c_str(), 1e3 * k.ateRmseM, 1e3 * t.ateRmseM, 1e3 * k.lastDriftM, 1e3 * t.lastDriftM);
    EXPECT_EQ(t.tracked, static_cast<int>(frames.size()));
    for (size_t i = 1; i < t.poses.size(); ++i) EXPECT_EQ(t.poses[i].against, "model") << name << " " << i;
    // Measured: tabletop-synth 1.9 mm ATE either way; tabletop-pt 4.1 mm against the room (last frame 2.0 mm)
    // where the keyframes keep the anchor's 8 mm.
    EXPECT_LT(t.ateRmseM, 5e-3) << name;
    EXPECT_LT(t.lastDriftM, std::min(k.lastDriftM, 3e-3)) << name;
  }
}

TEST(Tracking, ALookAroundIsTrackedThroughout) {
  // tabletop-scan: an orbit that sees the marker, a step back, a full turn in place 35 degrees up (walls,
  // ceiling, the lamp; 12 degrees a frame, no marker) and back down to the table. Every frame is tracked and
  // lies within a centimetre of the truth. Three guards hold it: where the camera stops stepping back and starts
  // to turn, the odometry's coarsest level is also solved from the start turned in place
  // (OdometryOptions::turnInPlace); the translation a bare wall does not hold stays as predicted
  // (OdometryOptions::weakDirection); and where odometry slid with the tag in view the marker places the pose
  // outright (TrackingOptions::markerOverrideM), shown on odometry without the turned start, which slides there.
  const Synthetic scan = readSynthetic("tabletop-scan");
  const auto runWith = [&](const TrackingOptions& o) {
    auto source = makePoseSource(PoseMode::Tracked, scan.marker, std::nullopt, o);
    return run(*source, scan.frames, scan.truth);
  };
  const TrackingOptions defaults;
  TrackingOptions noReset = defaults, noGuard = defaults, sliding = defaults;
  noReset.markerOverrideM = noReset.markerOverrideDeg = 1e9;
  noGuard.odometry.weakDirection = 0;
  sliding.odometry.turnInPlace = false;
  TrackingOptions slidingNoReset = sliding;
  slidingNoReset.markerOverrideM = slidingNoReset.markerOverrideDeg = 1e9;
  const Trajectory t = runWith(defaults), r = runWith(noReset), g = runWith(noGuard), s = runWith(sliding),
                   sr = runWith(slidingNoReset);
  int byOdometry = 0, resets = 0;
  for (size_t i = 0; i < t.poses.size(); ++i) byOdometry += t.poses[i].by == PosedBy::Odometry;
  for (size_t i = 0; i < s.poses.size(); ++i) {
    if (!s.poses[i].markerReset) continue;
    ++resets;
    EXPECT_GT(s.poses[i].correctionM, defaults.markerOverrideM);  // how far odometry had slid
    EXPECT_LT(reconstruction::translationError(*s.poses[i].T_world_camera, scan.truth[i]), 0.01) << i;
  }
  std::printf(
      "tabletop-scan, tracked: %d of %zu frames (%d by odometry alone), ATE %.2f mm, worst %.2f mm; without the "
      "marker's reset worst %.1f mm; without the turned start worst %.1f mm (%d reset by the marker), %.1f mm "
      "without the reset too; without the weak-direction guard ATE %.1f mm, worst %.1f mm\n",
      t.tracked, scan.frames.size(), byOdometry, 1e3 * t.ateRmseM, 1e3 * t.maxM, 1e3 * r.maxM, 1e3 * s.maxM, resets,
      1e3 * sr.maxM, 1e3 * g.ateRmseM, 1e3 * g.maxM);
  EXPECT_EQ(t.tracked, static_cast<int>(scan.frames.size()));
  EXPECT_GE(byOdometry, 20);
  EXPECT_LT(t.ateRmseM, 0.006);
  EXPECT_LT(t.maxM, 0.01);
  EXPECT_LT(r.maxM, 0.01);  // the turned start: odometry holds the look-around without the marker's reset
  EXPECT_LT(s.maxM, 0.01);  // the marker's reset: the sliding odometry held by it
  EXPECT_GE(resets, 1);
  EXPECT_GT(sr.maxM, 0.03);
  EXPECT_GT(g.maxM, 2 * t.maxM);
  EXPECT_GT(g.ateRmseM, t.ateRmseM);
}

TEST(Tracking, TheDefaultRoomOfAScanLiesOnTheGroundTruthRoom) {
  // tabletop-scan with the default poses (tracked): every frame is placed or lost, never fused at a held or
  // guessed pose, and the room lies on the room fused at the true poses and covers it.
  const std::string scan = kRecordings + "tabletop-scan";
  RoomFusionOptions truthPoses, markerPoses;
  truthPoses.pose = PoseMode::GroundTruth;
  markerPoses.pose = PoseMode::Marker;
  RoomFusion tracked = fuseRoom(scan, RoomFusionOptions{});
  RoomFusion truth = fuseRoom(scan, truthPoses);
  const auto mt = tracked.model.mesh(), mg = truth.model.mesh();
  const auto accuracy = evaluation::surfaceDistance(mt, mg), coverage = evaluation::surfaceDistance(mg, mt);
  std::printf(
      "tabletop-scan, tracked: %d of %lld frames fused (%lld lost, %lld held); surface %.2f mm mean (90 %%: %.2f mm) "
      "from the ground-truth room, which it covers %.0f %% of (within 2 cm)\n",
      tracked.model.framesIntegrated(), static_cast<long long>(tracked.frames), static_cast<long long>(tracked.lost),
      static_cast<long long>(tracked.held), 1e3 * accuracy.meanM, 1e3 * accuracy.p90M, 100 * coverage.within2cm);
  // Fused at the optimised trajectory (a pose graph over the tracker's poses): nearer the truth than the
  // tracker's own poses.
  const Synthetic session = readSynthetic("tabletop-scan");
  const auto before = evaluation::trajectoryError(tracked.trackerPoses, session.truth),
             after = evaluation::trajectoryError(tracked.poses, session.truth);
  std::printf("tabletop-scan: ATE %.2f -> %.2f mm optimised; %s\n", 1e3 * before.ateRmseM, 1e3 * after.ateRmseM,
              tracked.trajectory.dump().c_str());
  EXPECT_LT(after.ateRmseM, before.ateRmseM);
  EXPECT_LT(after.ateRmseM, 0.0035);
  EXPECT_EQ(tracked.model.framesIntegrated(), tracked.frames);
  EXPECT_EQ(tracked.held, 0);
  EXPECT_LT(accuracy.meanM, 0.005);
  EXPECT_GT(coverage.within2cm, 0.9);
  for (const auto& line : tracked.perFrame)
    if (line["pose"]["status"] == "lost") {
      EXPECT_FALSE(line["integrated"].get<bool>()) << line.dump();
    }
  // Lights from either room: the lamp, whose every observation clipped, within 10 % of its true irradiance at
  // the object (the white-patch gain on its clip bound: the surfaces it lights see the bound's cells past the
  // lamp's own body; without that the tracked room read 44 % bright).
  const auto source = capture::open(scan);  // owns the manifest
  const auto* manifest = source->sessionManifest();
  ASSERT_TRUE(manifest && manifest->truth.T_world_marker && !manifest->truth.lights.empty());
  const capture::GroundTruthLight& lamp = manifest->truth.lights[0];
  const cv::Vec3d centre(0, 0, 0.06),
      at = capture::transformPoint(capture::inversePose(*manifest->truth.T_world_marker), lamp.position);
  const double trueE = capture::luminance(lamp.intensity) / (at - centre).dot(at - centre);
  for (const auto* room : {&mt, &mg}) {
    const reconstruction::RoomLights lights = reconstruction::estimateRoomLights(*room, centre);
    double E = 0;
    for (const auto& l : lights.lights) E = std::max(E, capture::luminance(l.irradiance));
    std::printf("the lamp from the %s room: irradiance %.2f (true %.2f), gain %.0f\n", room == &mt ? "tracked" : "true",
                E, trueE, lights.gain);
    EXPECT_NEAR(E, trueE, 0.1 * trueE);
  }
  // The marker alone holds its last pose over the look-around: those frames are refused, not fused wrong.
  RoomFusion marker = fuseRoom(scan, markerPoses);
  EXPECT_GT(marker.held, 0);
  EXPECT_LT(evaluation::surfaceDistance(marker.model.mesh(), mg).meanM, 0.01);
}

TEST(Tracking, AnOptimisedTrajectoryFusesTheRoomNearerTheTrueOne) {
  // mrgi room optimises the tracked trajectory before fusing (a pose graph of odometry, loop-closure and
  // marker edges: each sighting counts for the whole trajectory instead of pulling the next frames a bounded
  // step). Against the true poses and the room fused at them, next to the tracker's own poses. Measured (ATE,
  // tracker -> optimised): pt 6.44 -> 2.63 mm, hdr 4.99 -> 2.73, scan 4.23 -> 2.69, carve 6.60 -> 6.78 (its
  // 160 x 120 view of the tag: four sightings, three more refused or flipped, hold the optimised trajectory
  // where they are; the tracker, which leaves out the box that moves, came nearer the truth than they: 7.49 mm
  // before it did).
  struct Case {
    const char* name;
    double maxAteM;
    double slackM;  ///< how much farther than the tracker's the optimised trajectory may lie
  };
  // (tabletop-scan's look-around: Tracking.TheDefaultRoomOfAScan...)
  for (const Case c :
       {Case{"tabletop-pt", 0.0035, 0.0}, Case{"tabletop-hdr", 0.0035, 0.0}, Case{"tabletop-carve", 0.0075, 0.0005}}) {
    const std::string path = kRecordings + c.name;
    RoomFusionOptions truthPoses, optimised;
    truthPoses.pose = PoseMode::GroundTruth;
    const auto mg = fuseRoom(path, truthPoses).model.mesh();
    // The tracker's own poses come with the optimised fusion (its first pass): the same as fusing with
    // optimise = false would track (RoomFusion::trackerPoses).
    const RoomFusion b = fuseRoom(path, optimised);
    const Synthetic session = readSynthetic(c.name);
    const auto ea = evaluation::trajectoryError(b.trackerPoses, session.truth),
               eb = evaluation::trajectoryError(b.poses, session.truth);
    const auto db = evaluation::surfaceDistance(b.model.mesh(), mg);
    std::printf("%s: ATE %.2f -> %.2f mm (%d frames); room %.2f mm from the true one; %s\n", c.name, 1e3 * ea.ateRmseM,
                1e3 * eb.ateRmseM, eb.tracked, 1e3 * db.meanM, b.trajectory.dump().c_str());
    EXPECT_EQ(eb.tracked, ea.tracked) << c.name;
    EXPECT_LT(eb.ateRmseM, ea.ateRmseM + c.slackM) << c.name;  // the optimised trajectory nearer the truth
    EXPECT_LT(eb.ateRmseM, c.maxAteM) << c.name;
    EXPECT_LT(db.meanM, 0.01) << c.name;
    EXPECT_GT(b.trajectory["marker_edges"].get<int>(), 0) << c.name;
    EXPECT_GT(b.trajectory["odometry_edges"].get<int>(), eb.tracked - 2) << c.name;
  }
  RoomFusionOptions single;
  single.optimise = false;
  single.limit = 3;
  const RoomFusion a = fuseRoom(kRecordings + "tabletop-pt", single);
  EXPECT_TRUE(a.trajectory.is_null());
  EXPECT_TRUE(a.trackerPoses.empty());
}

TEST(Tracking, ASmallTagIsReseatedOnItsDepthPlane) {
  // tabletop-carve sees its 16 cm tag at 0.9 m in a 160 x 120 view (about 25 pixels a side): the distance from
  // the tag's apparent size is uncertain by ~10 mm, so the depth plane's gate grows with it (31 mm, 3.1
  // degrees) and the plane re-seats the pose. Measured: the tracked sightings 27-35 mm off before, 6.6-10 mm
  // after; the others are in-plane rotation errors (4-9 degrees) the plane cannot see. The real ViSP
  // sequence's tags keep the base gate (Marker.RealRgbdSequencePosesMatchGroundTruth: the same 6 of 147
  // re-seated).
  reconstruction::TagDetection small;
  small.corners = {cv::Point2d(0, 0), cv::Point2d(25, 0), cv::Point2d(25, 25), cv::Point2d(0, 25)};
  const auto [angle, shift] = reconstruction::depthGateLimits({}, small, 0.9);
  EXPECT_NEAR(shift, 3 * 0.9 * std::sqrt(2.0) * 0.2 / 25, 1e-9);
  EXPECT_NEAR(angle, 2.5 * shift / 0.025, 1e-9);
  reconstruction::TagDetection large = small;
  for (auto& p : large.corners) p *= 4;
  EXPECT_EQ(reconstruction::depthGateLimits({}, large, 0.5), std::make_pair(2.5, 0.025));

  const Synthetic session = readSynthetic("tabletop-carve");
  auto marker = makePoseSource(PoseMode::Marker, session.marker, std::nullopt);
  const Trajectory t = run(*marker, session.frames, session.truth);
  std::vector<double> errors;
  for (size_t i = 0; i < t.poses.size(); ++i)
    if (t.poses[i].markerT_world_camera)
      errors.push_back(reconstruction::translationError(*t.poses[i].markerT_world_camera, session.truth[i]));
  ASSERT_GE(errors.size(), 4u);
  std::sort(errors.begin(), errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.012);  // 35 mm with the fixed 25 mm gate
}

TEST(Tracking, ARoomFusedAsTheFramesComeIsTrackedAgainst) {
  // replay / live --fuse-room --track-room: each refreshed surface of the room being fused becomes what the
  // next frames are aligned with first (handed from the fusing thread to the measuring one between frames).
  // Measured: ATE 5.95 -> 10.0 mm (pt), 4.93 -> 9.3 mm (hdr), refreshed every 1, 3 or 6 frames alike: a room
  // fused from the frames' own poses, its surface from 2 cm voxels and aligned point to plane, places them
  // worse than the keyframes' hybrid odometry with the marker in view, so it is off by default.
  EXPECT_FALSE(FrameOptions{}.trackFusedRoom);
  gl::ContextConfig cfg;
  cfg.width = 320;
  cfg.height = 240;
  auto context = gl::createContext(cfg);
  for (const std::string name : {"tabletop-pt", "tabletop-hdr"}) {
    const Synthetic session = readSynthetic(name);
    const auto replay = [&](bool track) {
      auto source = capture::open(kRecordings + name);
      const std::string scenePath = std::string(MRGI_SOURCE_DIR) + "/recordings/scenes/tabletop.json";
      const LightingSetup setup =
          prepareLighting(lighting::loadScene(scenePath), scenePath, *source, name, PoseMode::Tracked, true);
      FrameOptions fo;
      fo.pose = PoseMode::Tracked;
      fo.fuse = std::make_shared<reconstruction::RoomModel>();
      fo.fuseRefresh = 3;
      fo.trackFusedRoom = track;
      fo.techniqueStats = false;
      const auto& k = source->info().colourIntrinsics;
      FramePipeline pipeline(setup, k.width, k.height, fo);
      compositor::Compositor compositor(k.width, k.height);
      gl::Profiler profiler;
      std::vector<std::optional<capture::Pose>> poses;
      int model = 0;
      while (auto frame = source->next()) {
        const FrameResult r = pipeline.process(*frame, compositor, profiler);
        poses.push_back(r.pose.T_world_camera);
        model += r.pose.against == "model";
      }
      return std::make_pair(evaluation::trajectoryError(poses, session.truth), model);
    };
    const auto [without, none] = replay(false);
    const auto [with, model] = replay(true);
    std::printf(
        "%s, replay --fuse-room: ATE %.2f mm tracking against keyframes, %.2f mm against the room as it is fused (%d "
        "frames "
        "aligned with it)\n",
        name.c_str(), 1e3 * without.ateRmseM, 1e3 * with.ateRmseM, model);
    EXPECT_EQ(none, 0);
    EXPECT_GE(model, static_cast<int>(session.truth.size()) - 3) << name;  // from the first refresh on
    EXPECT_EQ(with.tracked, without.tracked) << name;
    EXPECT_LT(with.ateRmseM, 0.015) << name;
  }
}

TEST(Odometry, AnOpen3dFolderFollowsItsTrajectory) {
  // The shared ICL-NUIM folder (Open3D's layout, no marker): the world is founded on the first frame's floor,
  // odometry carries it; the motion against trajectory.log's poses after aligning frame 0. Measured: 5.8 mm
  // at most over 98 mm of travel (under camera.json's fx 415.7, which the folder's depths contradict, 15 mm).
  auto src = capture::open(kData + "/rgbd-open3d-iclnuim");
  std::vector<capture::Frame> frames;
  std::vector<capture::Pose> truth;
  while (auto f = src->next()) frames.push_back(*f), truth.push_back(*f->groundTruthT_world_camera);
  ASSERT_EQ(frames.size(), 5u);
  TrackingOptions o;
  o.worldFromFirstFrame = true;
  auto source = makePoseSource(PoseMode::Odometry, {}, std::nullopt, o);
  const Trajectory t = run(*source, frames, truth);
  ASSERT_EQ(t.tracked, 5);
  EXPECT_EQ(t.poses[0].by, PosedBy::FirstFrame);
  // The founded world's origin lies on the floor the camera sees, not where its level view meets the floor
  // 20 m away.
  EXPECT_LT(cv::norm(capture::translationOf(*t.poses[0].T_world_camera)), 3.0);
  const capture::Pose align = truth[0] * capture::inversePose(*t.poses[0].T_world_camera);
  double worst = 0;
  for (size_t i = 0; i < frames.size(); ++i)
    worst = std::max(worst, reconstruction::translationError(align * *t.poses[i].T_world_camera, truth[i]));
  std::printf("Open3D folder, odometry: worst frame %.1f mm from trajectory.log\n", 1e3 * worst);
  EXPECT_LT(worst, 0.008);
}

}  // namespace
}  // namespace mrgi::runtime
