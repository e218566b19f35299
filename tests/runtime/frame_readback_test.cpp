// The frame path waits for the GPU only where an output needs a result on the CPU: with the technique facts
// off and the composite left on the GPU (a live view) or read into a pixel buffer (replay), processing a
// frame makes no synchronous readback, for every registered technique; the composites read later are the
// ones read at once, bit for bit. (Kinect-VAL builds its VALs from the RSMs and dims the real ones in the
// object's shadow on the GPU; it read 6 layers per light per frame back when it did that on the CPU.)
#include <gtest/gtest.h>

#include "capture/session.h"
#include "gl/context.h"
#include "lighting/techniques/registry.h"
#include "runtime/frame_pipeline.h"

namespace mrgi::runtime {
namespace {

const std::string kSession = std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-carve";
const std::string kScene = std::string(MRGI_SOURCE_DIR) + "/recordings/scenes/tabletop.json";

struct Frames {
  size_t lights = 0;
  std::vector<uint64_t> readbacks;  ///< per frame, inside process() and the profiler's non-blocking collect
  std::vector<cv::Mat> composites;
};

Frames run(const std::string& technique, compositor::Compositor::Readback mode, bool stats, int frames) {
  capture::SessionSource source(kSession);
  lighting::SceneDescription scene = lighting::loadScene(kScene);
  scene.technique = lighting::parseTechniqueChoice(technique, &scene.knobs);
  LightingSetup setup = prepareLighting(scene, kScene, source, kSession, PoseMode::GroundTruth);
  const capture::Intrinsics& k = source.info().colourIntrinsics;
  FrameOptions fo;
  fo.pose = PoseMode::GroundTruth;
  fo.techniqueStats = stats;
  FramePipeline pipeline(setup, k.width, k.height, fo);
  compositor::Compositor compositor(k.width, k.height);
  compositor.setReadback(mode);
  gl::Profiler profiler;
  Frames r;
  r.lights = setup.lights.size();
  for (int i = 0; i < frames; ++i) {
    std::optional<capture::Frame> frame = source.next();
    EXPECT_TRUE(frame);
    if (!frame) break;
    const uint64_t before = gl::synchronousReadbacks();
    FrameResult result = pipeline.process(*frame, compositor, profiler);
    profiler.endFrame();
    profiler.collect(false);
    r.readbacks.push_back(gl::synchronousReadbacks() - before);
    EXPECT_TRUE(result.lit) << technique;
    if (!result.composite.empty()) r.composites.push_back(result.composite);
    for (cv::Mat& c : compositor.takeComposites(false)) r.composites.push_back(c);
  }
  for (cv::Mat& c : compositor.takeComposites(true)) r.composites.push_back(c);
  profiler.collect(true);
  return r;
}

class FrameReadbacks : public ::testing::TestWithParam<std::string> {};

TEST_P(FrameReadbacks, NoneOnTheFramePathWhenNoOutputNeedsThem) {
  gl::ContextConfig cfg;
  cfg.width = 160;
  cfg.height = 120;
  auto context = gl::createContext(cfg);
  const std::string technique = GetParam();
  // The composite is read at once; the techniques' facts too (Kinect-VAL's sums).
  const Frames now = run(technique, compositor::Compositor::Readback::Now, true, 3);
  const Frames none = run(technique, compositor::Compositor::Readback::None, false, 3);
  const Frames later = run(technique, compositor::Compositor::Readback::Later, false, 3);
  ASSERT_GT(none.lights, 0u);  // every light stage runs (RSMs, shadow maps, Kinect-VAL's virtual VALs)
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_GE(now.readbacks[i], 1u) << "frame " << i << ": the composite is read at once";
    EXPECT_EQ(none.readbacks[i], 0u) << technique << ", frame " << i;
    EXPECT_EQ(later.readbacks[i], 0u) << technique << ", frame " << i;
  }
  EXPECT_TRUE(none.composites.empty());
  ASSERT_EQ(now.composites.size(), 3u);
  ASSERT_EQ(later.composites.size(), 3u);
  for (size_t i = 0; i < 3; ++i)
    EXPECT_EQ(cv::norm(now.composites[i], later.composites[i], cv::NORM_INF), 0.0) << "frame " << i;
}

std::vector<std::string> names() {
  std::vector<std::string> out;
  for (const auto& t : lighting::techniques()) out.push_back(t.name);
  return out;
}

INSTANTIATE_TEST_SUITE_P(GL, FrameReadbacks, ::testing::ValuesIn(names()), [](const auto& info) {
  std::string n = info.param;
  for (char& c : n)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return n;
});

}  // namespace
}  // namespace mrgi::runtime
