// A synthetic session written by the library (evaluation/synth.h), without the command line: its frames, its
// ground truth and each frame's reference, readable through the same source as any recording.
#include "evaluation/synth.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "capture/frame_source.h"
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

}  // namespace
}  // namespace mrgi::evaluation
