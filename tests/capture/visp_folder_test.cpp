// ViSP's RGB-D sequence folders (capture/visp_folder.h) on the shared desk recording: its intrinsics, its frames
// in metres, its end, and a folder that is not one.
#include "capture/visp_folder.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "capture/error.h"

namespace mrgi::capture {
namespace {

const std::string kVisp = std::string(MRGI_SHARED_DATA) + "/rgbd-visp-apriltag";

TEST(VispFolder, ReadsTheDesksFramesInMetresAndEndsAfterTheLast) {
  const VispFolder folder(kVisp);
  EXPECT_EQ(folder.intrinsics().width, 640);
  EXPECT_EQ(folder.intrinsics().height, 480);
  EXPECT_NEAR(folder.intrinsics().fx, 607.18, 0.01);
  EXPECT_NEAR(folder.intrinsics().cx, 321.39, 0.01);
  const std::optional<Frame> f = folder.frame(5);
  ASSERT_TRUE(f && f->rgbd);
  EXPECT_EQ(f->index, 5);
  EXPECT_NEAR(f->timestamp, 5 / 30.0, 1e-12);
  EXPECT_EQ(f->rgbd->colour.type(), CV_8UC3);
  EXPECT_EQ(f->rgbd->depth.type(), CV_32FC1);
  // The desk lies about a metre away: the median depth over the valid pixels, in metres.
  std::vector<float> z;
  for (int y = 0; y < f->rgbd->depth.rows; y += 4)
    for (int x = 0; x < f->rgbd->depth.cols; x += 4)
      if (f->rgbd->depth.at<float>(y, x) > 0) z.push_back(f->rgbd->depth.at<float>(y, x));
  ASSERT_GT(z.size(), 5000u);
  std::nth_element(z.begin(), z.begin() + static_cast<long>(z.size() / 2), z.end());
  EXPECT_GT(z[z.size() / 2], 0.5f);
  EXPECT_LT(z[z.size() / 2], 1.5f);
  EXPECT_TRUE(folder.frame(19).has_value());
  EXPECT_FALSE(folder.frame(20).has_value());
  EXPECT_DOUBLE_EQ(folder.tagSize(), 0.0955);  // apriltag_data.json's tag_size
}

TEST(VispFolder, AFolderWithoutItsCameraOrWithABadOneIsOneErrorNamingTheFile) {
  const auto dir = std::filesystem::temp_directory_path() / ("mrgi_visp_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  try {
    VispFolder{dir.string()};
    ADD_FAILURE() << "no cam.json read";
  } catch (const CaptureError& e) {
    EXPECT_NE(std::string(e.what()).find("cam.json"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "cam.json") << R"({"w": 640, "h": 480, "px": 600, "py": 600, "u0": 320, "v0": 240,
                                        "depthScale": -1})";
  try {
    VispFolder{dir.string()};
    ADD_FAILURE() << "a negative depth scale read";
  } catch (const CaptureError& e) {
    EXPECT_NE(std::string(e.what()).find("depthScale"), std::string::npos) << e.what();
  }
  // A readable camera but no tag file, then a tag file without its size or with a size out of range.
  std::ofstream(dir / "cam.json") << R"({"w": 640, "h": 480, "px": 600, "py": 600, "u0": 320, "v0": 240})";
  const VispFolder folder(dir.string());
  for (const std::string tags : {"", R"({"grid": []})", R"({"tag_size": 1e9})"}) {
    if (!tags.empty()) std::ofstream(dir / "apriltag_data.json") << tags;
    try {
      (void)folder.tagSize();
      ADD_FAILURE() << "a tag size read from '" << tags << "'";
    } catch (const CaptureError& e) {
      EXPECT_NE(std::string(e.what()).find("apriltag_data.json"), std::string::npos) << e.what();
    }
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mrgi::capture
