// Dense RGB-D odometry (reconstruction/odometry.h): each Gauss-Newton step is Open3D's own; the pyramid and
// the coarse-to-fine driver are ours. Parity with Open3D's complete legacy odometry on real and synthetic
// frame pairs, a frame against itself, frames that do not overlap, and extremes (no depth, one flat depth).
#include "reconstruction/odometry.h"

#include <gtest/gtest.h>
#include <open3d/camera/PinholeCameraIntrinsic.h>
#include <open3d/geometry/Image.h>
#include <open3d/geometry/RGBDImage.h>
#include <open3d/pipelines/odometry/Odometry.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/frame_source.h"
#include "capture/npz.h"
#include "capture/registration.h"
#include "reconstruction/marker.h"

namespace mrgi::reconstruction {
namespace {

struct Pair {
  capture::RgbdFrame a, b;
  capture::Pose T_a_b;  ///< ground truth where known
};

/// Open3D's legacy hybrid odometry (its whole pipeline: pyramid, steps, iteration) of b onto a.
capture::Pose open3dOdometry(const capture::RgbdFrame& a, const capture::RgbdFrame& b) {
  const auto toImages = [](const capture::RgbdFrame& f) {
    open3d::geometry::Image colour, depth;
    colour.Prepare(f.colour.cols, f.colour.rows, 3, 1);
    std::memcpy(colour.data_.data(), f.colour.data, colour.data_.size());
    depth.Prepare(f.depth.cols, f.depth.rows, 1, 4);
    std::memcpy(depth.data_.data(), f.depth.data, depth.data_.size());
    return open3d::geometry::RGBDImage::CreateFromColorAndDepth(colour, depth, 1.0, 4.0, true);
  };
  const capture::Intrinsics& k = a.colourIntrinsics;
  const open3d::camera::PinholeCameraIntrinsic intrinsic(k.width, k.height, k.fx, k.fy, k.cx, k.cy);
  open3d::pipelines::odometry::OdometryOption option;
  option.depth_max_ = 4.0;
  const auto [ok, T, info] = open3d::pipelines::odometry::ComputeRGBDOdometry(*toImages(b), *toImages(a), intrinsic);
  EXPECT_TRUE(ok);
  capture::Pose out;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out(r, c) = T(r, c);
  return out;
}

std::vector<Pair> synthPairs() {
  auto src = capture::open(std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-synth");
  std::vector<capture::Frame> frames;
  while (auto f = src->next()) {
    capture::ensureRegistered(*f->rgbd);
    frames.push_back(*f);
  }
  std::vector<Pair> pairs;
  for (size_t i : {0, 5, 10, 15})
    pairs.push_back(
        {*frames[i].rgbd, *frames[i + 1].rgbd,
         capture::inversePose(*frames[i].groundTruthT_world_camera) * *frames[i + 1].groundTruthT_world_camera});
  return pairs;
}

TEST(Odometry, ParityWithOpen3DsLegacyOdometryOnSyntheticPairs) {
  // Consecutive frames of the synthetic orbit (40 mm and 3 degrees apart): ours and Open3D's whole legacy
  // pipeline find the same motion, both within 2 mm and 0.2 degrees of the truth.
  for (const Pair& p : synthPairs()) {
    const OdometryFrame a(p.a.depth, p.a.colour, p.a.colourIntrinsics), b(p.b.depth, p.b.colour, p.b.colourIntrinsics);
    const OdometryResult ours = estimateOdometry(b, a);
    ASSERT_TRUE(ours.solved);
    const capture::Pose theirs = open3dOdometry(p.a, p.b);
    std::printf("ours %.2f mm %.3f deg, Open3D's %.2f mm %.3f deg from the truth; apart %.2f mm\n",
                1e3 * translationError(ours.T_target_source, p.T_a_b), rotationErrorDeg(ours.T_target_source, p.T_a_b),
                1e3 * translationError(theirs, p.T_a_b), rotationErrorDeg(theirs, p.T_a_b),
                1e3 * translationError(ours.T_target_source, theirs));
    EXPECT_LT(translationError(ours.T_target_source, p.T_a_b), 2e-3);
    EXPECT_LT(rotationErrorDeg(ours.T_target_source, p.T_a_b), 0.2);
    EXPECT_LT(translationError(theirs, p.T_a_b), 2e-3);
    EXPECT_LT(translationError(ours.T_target_source, theirs), 2e-3);
    EXPECT_GT(ours.fitness, 0.7);
  }
}

TEST(Odometry, AFrameAgainstItselfDoesNotMoveAndFramesApartDoNotSolve) {
  const Pair p = synthPairs()[0];
  for (const OdometryMethod m : {OdometryMethod::PointToPlane, OdometryMethod::Intensity, OdometryMethod::Hybrid}) {
    OdometryOptions o;
    o.method = m;
    const OdometryFrame a(p.a.depth, p.a.colour, p.a.colourIntrinsics, o);
    const OdometryResult self = estimateOdometry(a, a, capture::identityPose(), o);
    ASSERT_TRUE(self.solved) << toString(m);
    EXPECT_LT(translationError(self.T_target_source, capture::identityPose()), 1e-4) << toString(m);
    EXPECT_LT(rotationErrorDeg(self.T_target_source, capture::identityPose()), 0.01) << toString(m);
    EXPECT_GT(self.fitness, 0.95) << toString(m);
    EXPECT_LT(self.inlierRmse, 1e-3) << toString(m);
    // 50 m away: no association at all, the initial pose kept and nothing claimed.
    const capture::Pose away = capture::makePose(cv::Matx33d::eye(), {0, 0, 50});
    const OdometryResult none = estimateOdometry(a, a, away, o);
    EXPECT_FALSE(none.solved) << toString(m);
    EXPECT_EQ(none.T_target_source, away);
  }
}

TEST(Odometry, ExtremesStayFinite) {
  const Pair p = synthPairs()[0];
  const capture::Intrinsics& k = p.a.colourIntrinsics;
  // No depth at all, one flat wall of depth, and NaN / infinite / negative samples: never a non-finite pose.
  const cv::Mat none = cv::Mat::zeros(p.a.depth.size(), CV_32F), flat(p.a.depth.size(), CV_32F, cv::Scalar(1.0f));
  cv::Mat hostile = p.a.depth.clone();
  hostile.at<float>(5, 5) = std::numeric_limits<float>::quiet_NaN();
  hostile.at<float>(6, 6) = std::numeric_limits<float>::infinity();
  hostile.at<float>(7, 7) = -1;
  const OdometryFrame a(p.a.depth, p.a.colour, k);
  for (const cv::Mat& d : {none, flat, hostile}) {
    const OdometryFrame b(d, p.b.colour, k);
    const OdometryResult r = estimateOdometry(b, a);
    for (double v : r.T_target_source.val) EXPECT_TRUE(std::isfinite(v));
    EXPECT_TRUE(std::isfinite(r.fitness) && std::isfinite(r.inlierRmse));
  }
  EXPECT_EQ(OdometryFrame(none, p.a.colour, k).validPixels(), 0u);
  EXPECT_THROW(OdometryFrame(p.a.depth, cv::Mat(3, 3, CV_8UC3), k), std::invalid_argument);
}

}  // namespace
}  // namespace mrgi::reconstruction
