// The lighting pipeline runs only the stages whose inputs changed, and a skipped stage leaves exactly what
// running it again would compute: after every change the cached pipeline's shading equals a fresh
// pipeline's, for every technique.
#include <gtest/gtest.h>

#include <set>

#include "tests/lighting/test_scene.h"

namespace mrgi::test {
namespace {

struct Inputs {
  CameraView camera;
  std::vector<SceneLight> lights;
  cv::Vec3d at{0.0, 0.0, 0.1};  ///< the cube's centre
  float valExitance = 2.f;
  cv::Vec3d ambient{0.02, 0.02, 0.02};
};

/// The shading a pipeline computes from scratch for these inputs.
cv::Mat fresh(const PipelineConfig& cfg, const Inputs& in) {
  TestScene s = makeScene(true, 0.15, {0, 0, 0.1});
  LightingPipeline pipe = makePipeline(cfg, s);
  pipe.setObjectTransform(0, capture::makePose(cv::Matx33d::eye(), in.at));
  setTechniqueInputs(pipe, wallFrame(in.valExitance));
  pipe.run(in.camera, in.lights, in.ambient, nullptr);
  return pipe.downloadShade();
}

std::set<std::string> skipped(const LightingPipeline& p) {
  return {p.skippedStages().begin(), p.skippedStages().end()};
}

class StageSkipping : public ::testing::TestWithParam<std::string> {};

TEST_P(StageSkipping, SkipsUnchangedStagesAndMatchesAFreshPipelineAfterEveryChange) {
  auto ctx = makeContext();
  PipelineConfig cfg = testConfig(64, 48, 16, 64, GetParam());
  cfg.set("val", "sparse_points", 64);
  TestScene s = makeScene(true, 0.15, {0, 0, 0.1});
  LightingPipeline pipe = makePipeline(cfg, s);
  const bool own = !pipe.inputBuilders().empty();
  // Each technique's update reruns when one of the inputs it declares changed (or the lights / geometry did).
  auto techniquesSkippedUnless = [&](unsigned changed) {
    std::set<std::string> out;
    for (const auto& t : pipe.techniques())
      if (!(t->inputs() & changed)) out.insert(t->name());
    return out;
  };
  Inputs in;
  in.camera = topCamera(64, 48);
  in.lights = {pointAbove()};
  setTechniqueInputs(pipe, wallFrame(in.valExitance));
  auto check = [&](std::set<std::string> expect, const char* what) {
    pipe.run(in.camera, in.lights, in.ambient, nullptr);
    EXPECT_EQ(skipped(pipe), expect) << what;
    const cv::Mat got = pipe.downloadShade(), want = fresh(cfg, in);
    double peak = 0;
    cv::minMaxLoc(cv::Mat(cv::abs(want)).reshape(1), nullptr, &peak);
    ASSERT_GT(peak, 0.0) << what;
    EXPECT_LE(cv::norm(got, want, cv::NORM_INF), 1e-5 * peak) << what;
  };
  auto with = [](std::set<std::string> a, const std::set<std::string>& b) {
    a.insert(b.begin(), b.end());
    return a;
  };
  std::set<std::string> all{"gbuffer", "rsm", "shade"};
  for (const auto& t : pipe.techniques()) all.insert(t->name());
  check({}, "first run");
  check(all, "nothing changed");
  in.camera.T_world_camera = capture::lookAtPose({0.1, -0.3, 1.5}, {0, 0, 0});
  check(with({"rsm"}, techniquesSkippedUnless(lighting::kInputCamera)), "camera moved");
  in.lights = {sunDown(8.0)};
  check({"gbuffer"}, "new light");
  in.ambient = {0.05, 0.05, 0.05};
  // The lights' pass (and with it every technique) reruns where a technique's per-light work reads the ambient.
  bool lightsReadAmbient = false;
  for (const auto& t : pipe.techniques())
    lightsReadAmbient = lightsReadAmbient || (t->lightInputs() & lighting::kInputAmbient);
  check(lightsReadAmbient ? std::set<std::string>{"gbuffer"}
                          : with({"gbuffer", "rsm"}, techniquesSkippedUnless(lighting::kInputAmbient)),
        "new ambient");
  in.at = {0.05, 0.0, 0.1};
  pipe.setObjectTransform(0, capture::makePose(cv::Matx33d::eye(), in.at));
  check({}, "object moved");
  pipe.setRealMesh(s.vertices, s.indices);  // the same mesh uploaded again still counts as new geometry
  check({}, "real mesh set");
  if (own) {
    in.valExitance = 4.f;
    setTechniqueInputs(pipe, wallFrame(in.valExitance));
    check(with({"gbuffer", "rsm"}, techniquesSkippedUnless(lighting::kInputOwn)), "new inputs of their own");
  }
  pipe.invalidate();
  check({}, "invalidated");
}

INSTANTIATE_TEST_SUITE_P(GL, StageSkipping, ::testing::ValuesIn(allTechniqueSpellings()),
                         [](const auto& info) { return testName(info.param); });

}  // namespace
}  // namespace mrgi::test
