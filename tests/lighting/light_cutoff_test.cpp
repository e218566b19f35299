// Lights too dim at the objects to be worth rendering (lighting::irradianceBound, lightsThatMatter, the frame
// knob light_cutoff): the bound holds everywhere in the region's sphere, the lights left out carry at most
// the cutoff's share of it, and the pipeline renders only the lights kept, shading as with them alone.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>
#include <random>

#include "tests/lighting/test_scene.h"

namespace mrgi::test {
namespace {

using lighting::LightType;
using lighting::Region;

SceneLight point(cv::Vec3d at, double intensity) {
  SceneLight l;
  l.type = LightType::Point;
  l.position = at;
  l.intensity = cv::Vec3d::all(intensity);
  return l;
}

SceneLight spot(cv::Vec3d at, cv::Vec3d towards, double halfAngleDeg, double intensity) {
  SceneLight l = point(at, intensity);
  l.type = LightType::Spot;
  l.direction = cv::normalize(towards - at);
  l.spotHalfAngleDeg = halfAngleDeg;
  return l;
}

cv::Vec3d randomUnit(std::mt19937& rng) {
  std::normal_distribution<double> g;
  return cv::normalize(cv::Vec3d(g(rng), g(rng), g(rng)));
}

// Sampled over points of the sphere (surface and inside) and every normal, a light's unshadowed irradiance
// never exceeds its bound; a spot whose cone misses the sphere has a bound of exactly 0 and gives nothing.
TEST(LightCutoff, TheBoundHoldsEverywhereInTheRegionsSphere) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  const Region region = lighting::fitRegion({-0.06, -0.06, 0}, {0.06, 0.06, 0.12}, 4.0);
  const double r = region.radius();
  int missed = 0, tight = 0;
  for (int trial = 0; trial < 400; ++trial) {
    SceneLight l;
    const cv::Vec3d at = region.centre() + randomUnit(rng) * (r * (1.001 + 6 * u(rng)));
    switch (trial % 3) {
      case 0:
        l = point(at, 0.1 + 10 * u(rng));
        break;
      case 1:
        l = spot(at, region.centre() + randomUnit(rng) * (3 * r * u(rng)), 1 + 60 * u(rng), 5);
        break;
      default:
        l.type = LightType::Directional;
        l.direction = randomUnit(rng);
        l.irradiance = {3, 2, 1};
    }
    const cv::Vec3d bound = lighting::irradianceBound(l, region);
    ASSERT_TRUE(std::isfinite(bound[0]) && bound[0] >= 0) << trial;
    if (bound == cv::Vec3d(0, 0, 0)) ++missed;
    double most = 0;
    for (int k = 0; k < 2000; ++k) {
      // Half the samples on the sphere's surface facing the light (where the bound is reached), half inside.
      cv::Vec3d x = region.centre() + randomUnit(rng) * (k % 2 ? r : r * std::cbrt(u(rng)));
      if (k % 4 == 0 && l.type != LightType::Directional)
        x = region.centre() + cv::normalize(l.position - region.centre()) * r;
      cv::Vec3d n = randomUnit(rng);
      if (k % 3 == 0) n = l.type == LightType::Directional ? -l.direction : cv::normalize(l.position - x);
      const cv::Vec3d e = lighting::unshadowedIrradiance(l, x, n);
      for (int c = 0; c < 3; ++c) {
        ASSERT_LE(e[c], bound[c] * (1 + 1e-9)) << "trial " << trial << " sample " << k;
        if (bound[c] > 0) most = std::max(most, e[c] / bound[c]);
      }
    }
    if (l.type != LightType::Spot && most > 0.999) ++tight;  // reached where the sphere is nearest the light
  }
  EXPECT_GT(missed, 10);  // spots aimed away were among the trials
  EXPECT_GT(tight, 200);  // the bound is the irradiance's maximum for points and suns, not a loose multiple
}

TEST(LightCutoff, ALightInsideTheSphereHasNoFiniteBoundAndIsKept) {
  const Region region = lighting::fitRegion({-0.06, -0.06, 0}, {0.06, 0.06, 0.12}, 4.0);
  const std::vector<SceneLight> lights = {point(region.centre() + cv::Vec3d(0.1, 0, 0), 1e-12),
                                          point({0.4, 0.3, 1.5}, 5)};
  EXPECT_TRUE(std::isinf(lighting::irradianceBound(lights[0], region)[0]));
  // The light inside counts for nothing in the total, so the far lamp is not dropped beside it.
  EXPECT_EQ(lighting::lightsThatMatter(lights, {0, 0, 0}, region, 0.5), (std::vector<size_t>{0, 1}));
}

// A room with the objects' lamp, two spots aimed elsewhere and two dim lamps across it (the bundled
// recordings/scenes/tabletop-lamps.json): at the default cutoff only the objects' lamp is rendered; what is
// left out is within the cutoff's share in every channel; a cutoff of 0 keeps everything.
TEST(LightCutoff, TheDimmestLightsWithinTheCutoffAreLeftOut) {
  const Region region = lighting::fitRegion({-0.06, -0.06, 0}, {0.06, 0.06, 0.12}, 4.0);
  std::vector<SceneLight> lights = {point({0.45, -0.55, 1.2}, 9), spot({-1.5, 1.5, 1.8}, {-1.9, 1.9, 0.8}, 30, 6),
                                    spot({1.6, 1.0, 1.8}, {1.8, 1.5, -0.75}, 20, 8), point({-1.8, -1.7, 0.1}, 0.15),
                                    point({1.7, -1.6, 1.6}, 0.2)};
  lights[3].intensity = {0.15, 0.1, 0.05};
  const cv::Vec3d ambient(0.05, 0.05, 0.05);
  EXPECT_EQ(lighting::lightsThatMatter(lights, ambient, region, 0.01), (std::vector<size_t>{0}));
  EXPECT_EQ(lighting::lightsThatMatter(lights, ambient, region, 0.0), (std::vector<size_t>{0, 1, 2, 3, 4}));
  // The spots give the region nothing: left out at any cutoff above 0; the dim lamps only above their share.
  EXPECT_EQ(lighting::lightsThatMatter(lights, ambient, region, 1e-9), (std::vector<size_t>{0, 3, 4}));
  for (double cutoff : {1e-6, 1e-3, 3e-3, 0.01, 0.1, 0.5}) {
    const auto kept = lighting::lightsThatMatter(lights, ambient, region, cutoff);
    cv::Vec3d total = CV_PI * ambient, out(0, 0, 0);
    for (size_t i = 0; i < lights.size(); ++i) {
      const cv::Vec3d b = lighting::irradianceBound(lights[i], region);
      total += b;
      if (std::find(kept.begin(), kept.end(), i) == kept.end()) out += b;
    }
    for (int c = 0; c < 3; ++c) EXPECT_LE(out[c], cutoff * total[c]) << cutoff;
    EXPECT_TRUE(std::is_sorted(kept.begin(), kept.end()));
    EXPECT_EQ(kept.front(), 0u) << cutoff;  // the objects' lamp carries most of the light
  }
  // A light that matters in one channel only is kept: a red lamp beside a blue-free scene.
  std::vector<SceneLight> coloured = {point({0.45, -0.55, 1.2}, 9), point({1.0, 1.0, 1.2}, 0)};
  coloured[0].intensity = {9, 9, 0};
  coloured[1].intensity = {0, 0, 0.5};
  EXPECT_EQ(lighting::lightsThatMatter(coloured, {0, 0, 0}, region, 0.1), (std::vector<size_t>{0, 1}));
}

TEST(LightCutoff, ExtremesGiveFiniteDecisions) {
  const Region tiny = lighting::fitRegion({0, 0, 0}, {0, 0, 0}, 1.0);  // 1 mm
  EXPECT_TRUE(lighting::lightsThatMatter({}, {0, 0, 0}, tiny, 0.01).empty());
  // Lights of no flux, with no ambient: leaving them out changes nothing.
  EXPECT_TRUE(lighting::lightsThatMatter({point({0, 0, 1}, 0), point({0, 1, 0}, 0)}, {0, 0, 0}, tiny, 0.01).empty());
  // 1e9 W/sr beside a denormal lamp and a grazing sun.
  SceneLight sun;
  sun.type = LightType::Directional;
  sun.direction = cv::normalize(cv::Vec3d(1, 0, -1e-12));
  sun.irradiance = {1e9, 1e9, 1e9};
  const std::vector<SceneLight> lights = {point({0, 0, 1}, 1e9), point({0, 0, 2}, 1e-310), sun};
  const auto kept = lighting::lightsThatMatter(lights, {0, 0, 0}, tiny, 0.01);
  EXPECT_EQ(kept, (std::vector<size_t>{0, 2}));
  for (const SceneLight& l : lights) {
    const cv::Vec3d b = lighting::irradianceBound(l, tiny);
    EXPECT_TRUE(std::isfinite(b[0]) && b[0] >= 0);
  }
  // A spot of a 1e-12 degree cone aimed at the region's centre is kept; turned 17 degrees, past the 12 the
  // sphere covers seen from it, it is left out.
  const Region region = lighting::fitRegion({-0.06, -0.06, 0}, {0.06, 0.06, 0.12}, 4.0);
  const SceneLight onAxis = spot({0, 0, 2}, region.centre(), 1e-12, 5);
  SceneLight off = onAxis;
  off.direction = cv::normalize(cv::Vec3d(std::sin(0.3), 0, -std::cos(0.3)));
  EXPECT_GT(lighting::irradianceBound(onAxis, region)[0], 1.0);
  EXPECT_EQ(lighting::irradianceBound(off, region), cv::Vec3d(0, 0, 0));
}

// The pipeline renders only the lights that matter (lightsRendered) and shades exactly as a pipeline given
// those lights alone; with the cutoff at 0 it renders them all, and the composite it shades differs from the
// skipping one by no more than the left-out lights' bound allows.
TEST(LightCutoff, ThePipelineRendersOnlyTheLightsThatMatter) {
  auto ctx = makeContext();
  const int W = 96, H = 72;
  const TestScene s = makeScene(true, 0.15, {0.05, 0.0, 0.075});
  const SceneLight lamp = pointAbove();
  const std::vector<SceneLight> lights = {spot({-0.9, 0.9, 1.4}, {-0.9, 0.9, 0}, 20, 6), lamp,
                                          point({0.9, -0.9, 0.6}, 0.01)};
  const cv::Vec3d ambient(0.02, 0.02, 0.02);
  for (const std::string technique : {"kinect-val", "dlpv"}) {
    SCOPED_TRACE(technique);
    PipelineConfig cfg = testConfig(W, H, 16, 64, technique);
    LightingPipeline skipping = makePipeline(cfg, s);
    skipping.run(topCamera(W, H), lights, ambient, nullptr);
    EXPECT_EQ(skipping.lightsRendered(), (std::vector<size_t>{1}));
    EXPECT_EQ(skipping.frame().lights().size(), 1u);
    LightingPipeline alone = makePipeline(cfg, s);
    alone.run(topCamera(W, H), {lamp}, ambient, nullptr);
    const cv::Mat a = skipping.downloadShade(), b = alone.downloadShade();
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);

    cfg.set("frame", "light_cutoff", 0.0);
    LightingPipeline every = makePipeline(cfg, s);
    every.run(topCamera(W, H), lights, ambient, nullptr);
    ASSERT_EQ(every.lightsRendered().size(), 3u);
    const cv::Mat c = every.downloadShade(), alb = every.downloadGBuffer(2);
    const Region region = *every.region();
    const double leftOut =
        lighting::irradianceBound(lights[0], region)[0] + lighting::irradianceBound(lights[2], region)[0];
    // Every pixel, the object's radiance and the real pixels' delta: at most albedo / pi (0.9 the largest
    // here) x the left-out irradiance, direct and once more bounced off surfaces it lit (albedo < 1).
    double most = 0, mostOnObject = 0;
    for (int i = 0; i < static_cast<int>(c.total()); ++i)
      for (int ch = 0; ch < 3; ++ch) {
        const double d = std::abs(c.at<cv::Vec4f>(i)[ch] - a.at<cv::Vec4f>(i)[ch]);
        most = std::max(most, d);
        if (alb.at<cv::Vec4f>(i)[3] > 0.5f) mostOnObject = std::max(mostOnObject, d);
      }
    EXPECT_GT(mostOnObject, 0.0);  // the dim lamp does light the object a little
    EXPECT_LE(most, 0.9 / CV_PI * 2 * leftOut);
  }
}

}  // namespace
}  // namespace mrgi::test
