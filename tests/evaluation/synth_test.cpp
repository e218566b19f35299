// A synthetic session written by the library (evaluation/synth.h), without the command line: its frames, its
// ground truth and each frame's reference, readable through the same source as any recording.
#include "evaluation/synth.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/session.h"

namespace fs = std::filesystem;

namespace mrgi::evaluation {
namespace {

TEST(Synth, ASmallSessionHasItsFramesTruthAndReferences) {
  const fs::path dir = fs::temp_directory_path() / ("mrgi_synth_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  SynthOptions o;
  o.out = dir.string();
  o.frames = 2;
  o.scan = 1;
  o.width = 64;
  o.height = 48;
  o.render = "raycast";
  o.fisheyeEvery = 0;
  o.scene = std::string(MRGI_SOURCE_DIR) + "/recordings/scenes/tabletop.json";
  double last = 0;
  o.progress = [&last](double f) { last = f; };
  EXPECT_EQ(writeSynthSession(o), 3);
  EXPECT_NEAR(last, 1.0, 1e-9);
  auto source = capture::open(o.out);
  ASSERT_NE(source->sessionManifest(), nullptr);
  EXPECT_TRUE(source->sessionManifest()->truth.T_world_marker.has_value());
  int frames = 0;
  while (auto f = source->next()) {
    ASSERT_TRUE(f->rgbd && f->groundTruthT_world_camera) << frames;
    EXPECT_EQ(f->rgbd->colour.cols, 64);
    ++frames;
  }
  EXPECT_EQ(frames, 3);
  // References for the orbit's frames, none for the look-around's.
  EXPECT_TRUE(fs::exists(dir / "reference" / "000001.png"));
  EXPECT_TRUE(fs::exists(dir / "reference" / "delta_000001.exr"));
  EXPECT_FALSE(fs::exists(dir / "reference" / "000002.png"));
  // Options that do not go together are refused before anything is written.
  SynthOptions bad = o;
  bad.out = (dir / "bad").string();
  bad.moveBox = true;
  EXPECT_THROW(writeSynthSession(bad), std::invalid_argument);
  EXPECT_FALSE(fs::exists(bad.out));
  fs::remove_all(dir);
}

TEST(Synth, AFocusedReferenceTakesItsSamplesWithinTheRadiiItIsGiven) {
  // The reference delta from its own two renders, more samples per pixel within --reference-focus-radii of
  // the objects: with a reach of 0.1 radii the pixels far from the sphere keep --spp and their delta (where the
  // sphere changes it: the renders share their random numbers) differs from one whose focus reaches
  // everywhere; on the sphere both take the focus's samples alike.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_synth_focus_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  SynthOptions o;
  o.frames = 1;
  o.width = 48;
  o.height = 36;
  o.spp = 1;
  o.bounces = 1;
  o.referenceFocusSpp = 4;
  o.fisheyeEvery = 0;
  o.scene = std::string(MRGI_SOURCE_DIR) + "/recordings/scenes/tabletop.json";
  cv::Mat deltas[2];
  for (int k = 0; k < 2; ++k) {
    o.out = (dir / std::to_string(k)).string();
    o.referenceFocusRadii = k == 0 ? 0.1 : 50.0;
    ASSERT_EQ(writeSynthSession(o), 1);
    deltas[k] = capture::readAny((dir / std::to_string(k) / "reference" / "delta_000000.exr").string());
    std::ifstream in(dir / std::to_string(k) / "manifest.json");
    const nlohmann::json m = nlohmann::json::parse(in);
    EXPECT_DOUBLE_EQ(m["ground_truth"]["reference"]["delta_focus_radii"].get<double>(), o.referenceFocusRadii);
  }
  ASSERT_EQ(deltas[0].size(), deltas[1].size());
  ASSERT_EQ(deltas[0].type(), CV_32FC3);
  // The sphere's pixels (the reference's mask): its box, grown by its size, is "near".
  const cv::Mat mask = cv::imread((dir / "0" / "reference" / "mask_000000.png").string(), cv::IMREAD_GRAYSCALE);
  ASSERT_EQ(mask.type(), CV_8UC1);
  int x0 = mask.cols, y0 = mask.rows, x1 = -1, y1 = -1;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x)
      if (mask.at<uchar>(y, x) > 0)
        x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
  ASSERT_GE(x1, x0) << "the sphere is in view";
  const int grow = std::max(x1 - x0, y1 - y0) + 1;
  int farLit = 0, farDiffer = 0, nearDiffer = 0;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      const cv::Vec3f a = deltas[0].at<cv::Vec3f>(y, x), b = deltas[1].at<cv::Vec3f>(y, x);
      const bool d = a != b;
      const bool isFar = x < x0 - grow || x > x1 + grow || y < y0 - grow || y > y1 + grow;
      farLit += isFar && (a != cv::Vec3f() || b != cv::Vec3f());  // the objects change it in one of them
      farDiffer += isFar && d;
      nearDiffer += mask.at<uchar>(y, x) > 0 && d;
    }
  EXPECT_GT(farLit, 10);
  EXPECT_GT(farDiffer, farLit * 9 / 10);  // --spp there against the focus's samples
  EXPECT_EQ(nearDiffer, 0);               // the focus's samples in both, on the sphere itself
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mrgi::evaluation
