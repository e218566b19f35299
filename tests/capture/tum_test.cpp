// TUM RGB-D reader: association by timestamp, depth scale 5000, ground truth, bad lists. Uses the two real
// TUM freiburg2 frames in ../shared/data/rgbd-slambook/ch7 (MIT), arranged as a TUM sequence in a temp dir.
#include "capture/tum.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "capture/error.h"
#include "capture/frame_source.h"

namespace fs = std::filesystem;
using namespace mrgi::capture;

namespace {
const fs::path kCh7 = fs::path(MRGI_SHARED_DATA) / "rgbd-slambook/ch7";

fs::path makeTumDir() {
  const fs::path d = fs::temp_directory_path() / ("rgbd_dataset_freiburg2_mrgi_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d / "rgb");
  fs::create_directories(d / "depth");
  fs::copy_file(kCh7 / "1.png", d / "rgb/100.000.png");
  fs::copy_file(kCh7 / "2.png", d / "rgb/100.033.png");
  fs::copy_file(kCh7 / "1_depth.png", d / "depth/100.004.png");
  fs::copy_file(kCh7 / "2_depth.png", d / "depth/100.041.png");
  std::ofstream(d / "rgb.txt")
      << "# colour images\n# timestamp filename\n100.000 rgb/100.000.png\n100.033 rgb/100.033.png\n";
  // 100.090 has no colour partner within 20 ms and must be skipped.
  std::ofstream(d / "depth.txt") << "100.004 depth/100.004.png\n100.041 depth/100.041.png\n100.090 depth/100.041.png\n";
  std::ofstream(d / "groundtruth.txt") << "# timestamp tx ty tz qx qy qz qw\n"
                                          "99.995 1.0 2.0 3.0 0 0 0 1\n"
                                          "100.035 1.5 2.0 3.0 0 0 0.7071068 0.7071068\n";
  return d;
}
}  // namespace

TEST(Tum, AssociationPairsNearestWithinGap) {
  const auto pairs = associateTimestamps({1.0, 1.033, 1.5}, {1.004, 1.041, 1.09}, 0.02);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0], std::make_pair(size_t{0}, size_t{0}));
  EXPECT_EQ(pairs[1], std::make_pair(size_t{1}, size_t{1}));
  // One-to-one: two colour frames near one depth frame get one match.
  EXPECT_EQ(associateTimestamps({1.0, 1.001}, {1.0005}, 0.02).size(), 1u);
}

TEST(Tum, ReadsRealFramesWithScaleAndGroundTruth) {
  const fs::path d = makeTumDir();
  auto src = open(d.string());
  EXPECT_EQ(src->info().kind, "tum");
  EXPECT_EQ(*src->info().frameCount, 2);
  EXPECT_DOUBLE_EQ(src->info().colourIntrinsics.fx, 520.9);  // freiburg2 from the directory name
  const auto f = src->next();
  ASSERT_TRUE(f && f->rgbd);
  EXPECT_DOUBLE_EQ(f->timestamp, 100.0);
  const cv::Mat raw = cv::imread((kCh7 / "1_depth.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(raw.type(), CV_16UC1);
  cv::Point p;
  double maxRaw = 0;
  cv::minMaxLoc(raw, nullptr, &maxRaw, nullptr, &p);
  EXPECT_FLOAT_EQ(f->rgbd->depth.at<float>(p), static_cast<float>(maxRaw / 5000.0));
  EXPECT_EQ(f->rgbd->depth.at<float>(0, 0) == 0.f, raw.at<uint16_t>(0, 0) == 0);
  ASSERT_TRUE(f->groundTruthT_world_camera);
  EXPECT_DOUBLE_EQ((*f->groundTruthT_world_camera)(0, 3), 1.0);  // nearest pose at 99.995
  const auto g = src->next();
  ASSERT_TRUE(g && g->groundTruthT_world_camera);
  EXPECT_NEAR((*g->groundTruthT_world_camera)(0, 1), -1.0, 1e-6);  // 90 degrees about z
  EXPECT_FALSE(src->next());
  fs::remove_all(d);
}

TEST(Tum, NonMonotonicListIsAnErrorNamingFileAndLine) {
  const fs::path d = makeTumDir();
  std::ofstream(d / "rgb.txt", std::ios::trunc) << "100.033 rgb/100.033.png\n100.000 rgb/100.000.png\n";
  try {
    open(d.string());
    FAIL() << "expected an error";
  } catch (const CaptureError& e) {
    EXPECT_NE(std::string(e.what()).find("rgb.txt:2: timestamp"), std::string::npos) << e.what();
  }
  fs::remove_all(d);
}

TEST(Tum, AFolderOfUnknownCameraFallsBackAndSaysSoOrTakesItsCalibration) {
  // The same frames in a folder whose name says no Kinect: the ROS default, said in one line; a
  // camera_intrinsic.json beside the lists, or the flags' values, are taken instead.
  const fs::path named = makeTumDir();
  const fs::path d = fs::temp_directory_path() / ("mrgi_tum_unknown_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::rename(named, d);
  auto bare = open(d.string());
  EXPECT_DOUBLE_EQ(bare->info().colourIntrinsics.fx, 525.0);
  EXPECT_NE(bare->info().calibrationNote.find("no calibration beside the frames"), std::string::npos);
  std::ofstream(d / "camera_intrinsic.json")
      << R"({"width": 640, "height": 480, "intrinsic_matrix": [520.9, 0, 0, 0, 521.0, 0, 325.1, 249.7, 1]})";
  auto calibrated = open(d.string());
  EXPECT_DOUBLE_EQ(calibrated->info().colourIntrinsics.fy, 521.0);
  EXPECT_TRUE(calibrated->info().calibrationNote.empty());
  OpenOptions o;
  o.intrinsics = std::array<double, 4>{500, 500, 320, 240};
  o.depthUnitsPerMetre = 1000;
  auto given = open(d.string(), o);
  EXPECT_DOUBLE_EQ(given->info().colourIntrinsics.fx, 500.0);
  const cv::Mat raw = cv::imread((kCh7 / "1_depth.png").string(), cv::IMREAD_UNCHANGED);
  cv::Point p;
  double maxRaw = 0;
  cv::minMaxLoc(raw, nullptr, &maxRaw, nullptr, &p);
  EXPECT_FLOAT_EQ(given->next()->rgbd->depth.at<float>(p), static_cast<float>(maxRaw / 1000.0));
  fs::remove_all(d);
}
