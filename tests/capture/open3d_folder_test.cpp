// Open3D RGB-D folders as a source: the shared ICL-NUIM folder (5 frames, trajectory.log), and copies of it
// altered to fail or to fall back.
#include "capture/open3d_folder.h"

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
const fs::path kIcl = fs::path(MRGI_SHARED_DATA) / "rgbd-open3d-iclnuim";

/// A copy of the folder's frames (and of the files named in `keep`) in a fresh temporary folder.
fs::path copyFolder(const std::string& tag, const std::vector<std::string>& keep) {
  const fs::path d = fs::temp_directory_path() / ("mrgi_open3d_" + tag + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  fs::copy(kIcl / "color", d / "color");
  fs::copy(kIcl / "depth", d / "depth");
  for (const auto& f : keep) fs::copy_file(kIcl / f, d / f);
  return d;
}
}  // namespace

TEST(Open3dFolder, ReadsTheFramesTheirDepthInMetresAndTheTrajectory) {
  ASSERT_TRUE(isOpen3dFolder(kIcl.string()));
  auto src = open(kIcl.string());
  const SourceInfo& info = src->info();
  EXPECT_EQ(info.kind, "open3d");
  EXPECT_EQ(*info.frameCount, 5);
  EXPECT_TRUE(info.hasGroundTruth);
  // camera.json (fx 415.7) and camera_primesense.json (525) disagree: the one under which frames 0 and 1 agree
  // through trajectory.log's poses is taken, and said.
  EXPECT_DOUBLE_EQ(info.colourIntrinsics.fx, 525.0);
  EXPECT_DOUBLE_EQ(info.colourIntrinsics.cx, 319.5);
  EXPECT_NE(info.calibrationNote.find("camera_primesense.json takes"), std::string::npos) << info.calibrationNote;
  const auto f = src->next();
  ASSERT_TRUE(f && f->rgbd && f->groundTruthT_world_camera);
  const cv::Mat raw = cv::imread((kIcl / "depth/00000.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(raw.type(), CV_16UC1);
  cv::Point p;
  double maxRaw = 0;
  cv::minMaxLoc(raw, nullptr, &maxRaw, nullptr, &p);
  EXPECT_FLOAT_EQ(f->rgbd->depth.at<float>(p), static_cast<float>(maxRaw / 1000.0));
  EXPECT_EQ(f->rgbd->colour.size(), cv::Size(640, 480));
  // trajectory.log's first block, camera to world.
  EXPECT_NEAR((*f->groundTruthT_world_camera)(0, 0), -0.2739592186924325, 1e-12);
  EXPECT_NEAR((*f->groundTruthT_world_camera)(2, 3), 2.1264800183565487, 1e-12);
  int n = 1;
  while (src->next()) ++n;
  EXPECT_EQ(n, 5);
}

TEST(Open3dFolder, WithoutCalibrationItFallsBackAndSaysSoOrTakesTheGivenOne) {
  const fs::path d = copyFolder("bare", {"trajectory.log"});
  auto bare = open(d.string());
  EXPECT_DOUBLE_EQ(bare->info().colourIntrinsics.fx, 525.0);  // Open3D's PrimeSense default
  EXPECT_NE(bare->info().calibrationNote.find("fall back to fx 525"), std::string::npos)
      << bare->info().calibrationNote;
  OpenOptions o;
  o.intrinsics = std::array<double, 4>{500, 501, 320, 240};
  o.depthUnitsPerMetre = 2000;
  auto given = open(d.string(), o);
  EXPECT_DOUBLE_EQ(given->info().colourIntrinsics.fy, 501.0);
  EXPECT_TRUE(given->info().calibrationNote.empty());
  const cv::Mat raw = cv::imread((kIcl / "depth/00000.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_FLOAT_EQ(given->next()->rgbd->depth.at<float>(240, 320),
                  static_cast<float>(raw.at<uint16_t>(240, 320) / 2000.0));
  o.intrinsics = std::array<double, 4>{500, 500, 900, 240};  // principal point outside the image
  EXPECT_THROW(open(d.string(), o), CaptureError);
  fs::remove_all(d);
}

TEST(Open3dFolder, BrokenFilesAreOneLineNamingThem) {
  const fs::path d = copyFolder("broken", {});
  std::ofstream(d / "trajectory.log") << "0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 nan\n0 0 0 1\n";
  try {
    open(d.string());
    FAIL();
  } catch (const CaptureError& e) {
    EXPECT_NE(std::string(e.what()).find("trajectory.log:4"), std::string::npos) << e.what();
  }
  std::ofstream(d / "trajectory.log") << "7 7 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  EXPECT_THROW(open(d.string()), CaptureError);  // a pose for frame 7 of 5
  fs::remove(d / "trajectory.log");
  std::ofstream(d / "camera_intrinsic.json")
      << R"({"width": 320, "height": 240, "intrinsic_matrix": [1,0,0,0,1,0,0,0,1]})";
  try {
    open(d.string());
    FAIL();
  } catch (const CaptureError& e) {
    EXPECT_NE(std::string(e.what()).find("camera_intrinsic.json: is for 320x240"), std::string::npos) << e.what();
  }
  fs::remove(d / "camera_intrinsic.json");
  fs::remove(d / "depth/00004.png");
  try {
    open(d.string());
    FAIL();
  } catch (const CaptureError& e) {
    EXPECT_NE(std::string(e.what()).find("color/ holds 5 images and depth/ 4"), std::string::npos) << e.what();
  }
  fs::remove_all(d);
}
