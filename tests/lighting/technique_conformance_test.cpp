// Conformance of every registered technique, in every role it can serve and under each alias (walked over
// the registry, so a new technique is tested by adding its registry line): unlit input gives exactly 0; it
// hands out outputs for exactly the roles it serves; lit input gives it something to do; GPU memory, stats
// and debug views are reported. Two more suites walk the same registry: StageSkipping (a skipped run equals
// a fresh one after each kind of change) and Extremes (finite, bounded outputs at the numerical extremes).
#include <gtest/gtest.h>

#include <cmath>

#include "tests/lighting/test_scene.h"

namespace mrgi::test {
namespace {

using lighting::Role;

/// Every spelling that puts each technique in each role it supports, with "none" in the other.
std::vector<std::string> roleSpellings() {
  std::vector<std::string> out;
  for (const auto& t : lighting::techniques()) {
    if (t.real && t.virtualObject) out.push_back(t.name);
    if (t.real) out.push_back(t.name + "+none");
    if (t.virtualObject) out.push_back("none+" + t.name);
    for (const auto& a : t.aliases) out.push_back(a.name);
  }
  return out;
}

double maxAbsRgb(const cv::Mat& m) {
  double worst = 0;
  for (auto it = m.begin<cv::Vec4f>(); it != m.end<cv::Vec4f>(); ++it)
    for (int c = 0; c < 3; ++c) worst = std::max(worst, static_cast<double>(std::abs((*it)[c])));
  return worst;
}

class Conformance : public ::testing::TestWithParam<std::string> {};

TEST_P(Conformance, UnlitIsExactlyZeroAndOutputsFollowTheRoles) {
  auto ctx = makeContext();
  PipelineConfig cfg = testConfig(64, 48, 16, 64, GetParam());
  cfg.set("val", "sparse_points", 64);
  const TestScene s = makeScene(true, 0.15, {0, 0, 0.1});
  LightingPipeline pipe = makePipeline(cfg, s);
  ASSERT_GE(pipe.techniques().size(), 1u);

  // Nothing lights the scene: no light, no ambient, dark real surfaces -> every output exactly 0.
  for (const bool zeroLight : {false, true}) {
    setTechniqueInputs(pipe, wallFrame(0.f));
    SceneLight off = pointAbove();
    off.intensity = {0, 0, 0};
    pipe.invalidate();
    pipe.run(topCamera(64, 48), zeroLight ? std::vector<SceneLight>{off} : std::vector<SceneLight>{}, {0, 0, 0},
             nullptr);
    EXPECT_EQ(maxAbsRgb(pipe.downloadShade()), 0.0) << (zeroLight ? "zero light" : "no light");
    for (const auto& t : pipe.techniques()) {
      const lighting::TechniqueOutputs o = t->outputs();
      for (const gl::Texture* tex : {o.realDelta, o.virtualIrradiance, o.virtualRadiance})
        if (tex) {
          EXPECT_EQ(maxAbsRgb(lighting::download4(*tex)), 0.0) << t->name();
        }
    }
  }

  // Outputs for exactly the roles served.
  for (const auto& t : pipe.techniques()) {
    const lighting::TechniqueOutputs o = t->outputs();
    const bool real = pipe.techniqueFor(Role::Real) == t.get(), virt = pipe.techniqueFor(Role::Virtual) == t.get();
    EXPECT_EQ(o.realDelta != nullptr, real) << t->name();
    EXPECT_EQ(o.virtualIrradiance != nullptr || o.virtualRadiance != nullptr, virt) << t->name();
  }

  // Lit: each technique adds something where it serves, reports its GPU memory, stats and debug views.
  setTechniqueInputs(pipe, wallFrame(2.f));
  pipe.run(topCamera(64, 48), {pointAbove(), sunDown(8.0)}, {0.02, 0.02, 0.02}, nullptr);
  const cv::Mat alb = pipe.downloadGBuffer(2);
  size_t sum = pipe.frame().gpuBytes();
  for (const auto& t : pipe.techniques()) {
    EXPECT_GT(t->gpuBytes(), 0u) << t->name();
    sum += t->gpuBytes();
    const lighting::TechniqueOutputs o = t->outputs();
    if (o.realDelta) {
      const cv::Mat d = lighting::download4(*o.realDelta);
      double onReal = 0;
      for (int i = 0; i < static_cast<int>(d.total()); ++i)
        if (alb.at<cv::Vec4f>(i)[3] < 0.5f)
          onReal = std::max(onReal,
                            cv::norm(cv::Vec3f(d.at<cv::Vec4f>(i)[0], d.at<cv::Vec4f>(i)[1], d.at<cv::Vec4f>(i)[2])));
      EXPECT_GT(onReal, 0.0) << t->name() << ": no real-pixel delta under two lights";
    }
    double onVirtual = 0;
    for (const gl::Texture* tex : {o.virtualIrradiance, o.virtualRadiance}) {
      if (!tex) continue;
      const cv::Mat v = lighting::download4(*tex);
      for (int i = 0; i < static_cast<int>(v.total()); ++i)
        if (alb.at<cv::Vec4f>(i)[3] > 0.5f)
          onVirtual = std::max(
              onVirtual, cv::norm(cv::Vec3f(v.at<cv::Vec4f>(i)[0], v.at<cv::Vec4f>(i)[1], v.at<cv::Vec4f>(i)[2])));
    }
    if (o.virtualIrradiance || o.virtualRadiance) {
      EXPECT_GT(onVirtual, 0.0) << t->name() << ": no indirect light on the object";
    }
    EXPECT_TRUE(t->stats().is_object()) << t->name();
    lighting::DebugContext context;
    context.composite = cv::Mat(48, 64, CV_8UC3, cv::Scalar::all(128));
    context.intrinsics = topCamera(64, 48).intrinsics;
    context.T_world_camera = topCamera(64, 48).T_world_camera;
    for (const std::string& view : t->debugViews()) {
      nlohmann::json info;
      const cv::Mat img = t->debugImage(view, context, info);
      ASSERT_FALSE(img.empty()) << t->name() << " view " << view;
      EXPECT_EQ(img.type(), CV_8UC3) << view;
    }
  }
  EXPECT_GE(pipe.gpuBytes(), sum);  // plus the shading targets
  // The estimate made before allocating covers what was allocated (two lights), without inflating it.
  const size_t estimate = lighting::estimateGpuBytes(cfg, 2);
  EXPECT_GE(estimate, pipe.gpuBytes());
  EXPECT_LE(estimate, pipe.gpuBytes() * 5 / 4);
}

INSTANTIATE_TEST_SUITE_P(GL, Conformance, ::testing::ValuesIn(roleSpellings()),
                         [](const auto& info) { return testName(info.param); });

}  // namespace
}  // namespace mrgi::test
