// Splatting on the lighting pipeline's frame resources (llvmpipe): the GPU's sampling, pixel lights and splats against the
// C++ reference (splat.h), texels the object does not change cancel exactly, the splat bounds cut less than
// I_low per light, and a white cube next to a red wall receives red bounce.
#include <gtest/gtest.h>

#include <cmath>

#include "lighting/pipeline.h"
#include "lighting/techniques/splatting/splat.h"
#include "lighting/techniques/splatting/splatting.h"
#include "tests/lighting/test_scene.h"

using namespace mrgi;
using namespace mrgi::lighting;
using namespace mrgi::test;

namespace {

// The frame's resources come from a pipeline without a technique ("none": real pixels get the direct
// shadow alone); with one light its RSMs are that light's after a run, and the technique is driven by hand
// as the pipeline drives its techniques (beginLights, light, update).
PipelineConfig frameConfig(int rsm = 64) { return testConfig(96, 72, 16, rsm, "none"); }

std::unique_ptr<SplattingTechnique> runSplat(const LightingPipeline& pipe, int vpls, double iLow) {
  TechniqueSetup setup;
  setup.knobs = {{"vpls", vpls}, {"i_low", iLow}};
  setup.real = setup.virtualObject = true;
  setup.frame = &pipe.frame();
  auto t = std::make_unique<SplattingTechnique>(setup);
  t->beginLights(pipe.frame(), nullptr);
  t->light(pipe.frame(), 0, nullptr);
  t->endLights(pipe.frame(), nullptr);
  t->update(pipe.frame(), nullptr);
  return t;
}


}  // namespace

TEST(GL, SplattingGpuMatchesTheCppReference) {
  auto ctx = makeContext();
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  LightingPipeline pipe = makePipeline(frameConfig(), s);
  pipe.run(wallCamera(), wallLamp(), {0, 0, 0}, nullptr);
  const auto tp = runSplat(pipe, 512, 16.0);
  const SplattingTechnique& t = *tp;
  const std::vector<splat::PixelLight> delta = t.downloadLights(true), object = t.downloadLights(false);
  ASSERT_EQ(delta.size(), 3u * 512u);
  ASSERT_EQ(object.size(), 512u);

  // Sampling: the GPU's texels are those the reference warps to on the GPU's importance map, and the delta
  // lights' total flux estimates the sum of (Phi_rho - Phi_mu) over the texels.
  const cv::Mat imp = t.downloadImportance(true);
  const splat::Pyramid pyr = splat::buildPyramid(imp);
  const RsmTexels rho = pipe.frame().downloadRsm(true), mu = pipe.frame().downloadRsm(false);
  int same = 0, sampled = 0;
  for (int i = 0; i < 512; ++i) {
    const splat::Warped w = splat::warp(pyr, splat::samplePoint(i));
    if (w.texel.x < 0) continue;
    ++sampled;
    const cv::Vec4f p = rho.position.at<cv::Vec4f>(w.texel);
    const splat::PixelLight& l = delta[static_cast<size_t>(3 * i)];
    const splat::PixelLight& m = delta[static_cast<size_t>(3 * i + 2)];
    const cv::Vec3f at = p[3] > 0.5f ? l.position : m.position;
    const cv::Vec4f q = p[3] > 0.5f ? p : mu.position.at<cv::Vec4f>(w.texel);
    same += cv::norm(at - cv::Vec3f(q[0], q[1], q[2])) < 1e-6;
  }
  EXPECT_GT(sampled, 500);
  EXPECT_GE(same, sampled * 99 / 100) << same << " of " << sampled;
  double exact = 0, estimate = 0;
  for (int y = 0; y < rho.flux.rows; ++y)
    for (int x = 0; x < rho.flux.cols; ++x) {
      if (imp.at<float>(y, x) <= 0.f) continue;
      const cv::Vec4f a = rho.flux.at<cv::Vec4f>(y, x), b = mu.flux.at<cv::Vec4f>(y, x);
      exact += (rho.position.at<cv::Vec4f>(y, x)[3] > 0.5f ? a[0] : 0.f) - (mu.position.at<cv::Vec4f>(y, x)[3] > 0.5f ? b[0] : 0.f);
    }
  for (const splat::PixelLight& l : delta) estimate += l.flux[0];
  EXPECT_NEAR(estimate, exact, 0.05 * std::abs(exact) + 1e-6) << "exact " << exact;

  // Splats: per pixel the bounded sum of the downloaded lights, each cut at its own I_low; and the cut is
  // never more than the sum of the I_low of the lights.
  const cv::Mat pos = pipe.frame().downloadGBuffer(0), nrm = pipe.frame().downloadGBuffer(1), alb = pipe.frame().downloadGBuffer(2);
  const cv::Mat dOut = download4(*t.outputs().realDelta), vOut = download4(*t.outputs().virtualIrradiance);
  int checked = 0, good = 0, virt = 0, virtGood = 0;
  double boundSum = 0;
  for (const splat::PixelLight& l : delta) boundSum += splat::scaledILow(l, t.iLowScale());
  for (int i = 0; i < static_cast<int>(pos.total()); ++i) {
    const cv::Vec4f p = pos.at<cv::Vec4f>(i), n = nrm.at<cv::Vec4f>(i);
    if (p[3] < 0.5f) continue;
    const cv::Vec3f x(p[0], p[1], p[2]), nn(n[0], n[1], n[2]);
    const bool isVirtual = alb.at<cv::Vec4f>(i)[3] > 0.5f;
    const auto& lights = isVirtual ? object : delta;
    cv::Vec3f bounded(0, 0, 0);
    for (const splat::PixelLight& l : lights) {
      const float iLow = splat::scaledILow(l, t.iLowScale());
      if (iLow > 0) bounded += splat::splatIrradiance(l, x, nn, iLow);
    }
    const cv::Vec4f got = isVirtual ? vOut.at<cv::Vec4f>(i) : dOut.at<cv::Vec4f>(i);
    const bool ok = std::abs(got[0] - bounded[0]) <= 1e-4f + 2e-3f * std::abs(bounded[0]);
    if (isVirtual) {
      ++virt, virtGood += ok;
    } else {
      ++checked, good += ok;
      const cv::Vec3f full = splat::gather(delta, x, nn);
      ASSERT_LE(std::abs(full[0] - bounded[0]), boundSum * 1.001 + 1e-6) << i;
    }
  }
  EXPECT_GT(checked, 2000);
  EXPECT_GE(good, checked * 995 / 1000) << good << " of " << checked;
  EXPECT_GT(virt, 100);
  EXPECT_GE(virtGood, virt * 99 / 100) << virtGood << " of " << virt;
}

// An object the light cannot see (under the floor): RSM^rho and RSM^mu agree texel for texel, nothing is
// sampled for the delta, and it is exactly 0 on every real pixel.
TEST(GL, SplattingDeltaIsExactlyZeroWhereTheObjectChangesNoTexel) {
  auto ctx = makeContext();
  const TestScene s = makeScene(true, 0.12, {-0.2, 0.0, -0.3});
  LightingPipeline pipe = makePipeline(frameConfig(), s);
  pipe.run(wallCamera(), wallLamp(), {0, 0, 0}, nullptr);
  const auto tp = runSplat(pipe, 256, 4.0);
  const SplattingTechnique& t = *tp;
  const cv::Mat imp = t.downloadImportance(true);
  EXPECT_EQ(cv::countNonZero(imp), 0);
  const cv::Mat d = download4(*t.outputs().realDelta);
  for (int i = 0; i < static_cast<int>(d.total()); ++i) ASSERT_EQ(cv::Vec3f(d.at<cv::Vec4f>(i)[0], d.at<cv::Vec4f>(i)[1], d.at<cv::Vec4f>(i)[2]), cv::Vec3f(0, 0, 0));
}

// A white cube next to a red wall under a lamp: besides the grey floor's bounce, the wall's red reaches it.
TEST(GL, SplattingTheObjectTakesTheWallsRed) {
  auto ctx = makeContext();
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  LightingPipeline pipe = makePipeline(frameConfig(), s);
  pipe.run(wallCamera(), wallLamp(), {0, 0, 0}, nullptr);
  const auto t = runSplat(pipe, 1024, 4.0);
  const cv::Mat v = download4(*t->outputs().virtualIrradiance);
  const cv::Mat alb = pipe.frame().downloadGBuffer(2);
  double r = 0, g = 0;
  int n = 0;
  for (int i = 0; i < static_cast<int>(v.total()); ++i) {
    if (alb.at<cv::Vec4f>(i)[3] < 0.5f) continue;
    r += v.at<cv::Vec4f>(i)[0], g += v.at<cv::Vec4f>(i)[1], ++n;
  }
  ASSERT_GT(n, 100);
  EXPECT_GT(r, 1.2 * g);
  EXPECT_GT(r, 0.0);
}

// One pixel light and 16384 of them, a glossy object of exponent 10^4: finite outputs everywhere.
TEST(GL, SplattingStaysFiniteFromOneToSixteenThousandLights) {
  auto ctx = makeContext();
  TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  s.objects[0].material.specular = 0.5f;
  s.objects[0].material.albedo = {0.4f, 0.4f, 0.4f};
  s.objects[0].material.roughness = 0.0141f;  // exponent 2 / r^2 - 2 = 10^4
  LightingPipeline pipe = makePipeline(frameConfig(), s);
  pipe.run(wallCamera(), wallLamp(), {0, 0, 0}, nullptr);
  for (int vpls : {1, 16384}) {
    const auto t = runSplat(pipe, vpls, 16.0);
    EXPECT_EQ(t->downloadLights(true).size(), 3u * static_cast<size_t>(vpls));
    for (const gl::Texture* tex : {t->outputs().realDelta, t->outputs().virtualIrradiance}) {
      const cv::Mat m = download4(*tex);
      EXPECT_TRUE(cv::checkRange(m)) << vpls;
    }
  }
}
