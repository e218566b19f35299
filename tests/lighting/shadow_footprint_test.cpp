// Where the shading pass runs its whole program (lighting/shadow_footprint.h): every receiver some part of a
// light cannot see past the objects' sphere is held, the bound is not needlessly loose, and the bounded pass
// writes the image the whole pass writes.
#include "lighting/shadow_footprint.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/lighting/test_scene.h"

namespace mrgi::test {
namespace {

using lighting::LightType;

/// Whether the ray from x along unit w meets the sphere (c, r).
bool hitsSphere(const cv::Vec3d& x, const cv::Vec3d& w, const cv::Vec3d& c, double r) {
  const cv::Vec3d o = c - x;
  const double along = o.dot(w);
  return along > 0 && o.dot(o) - along * along <= r * r;
}

/// Whether the sphere hides some of `light` from x: rays towards samples of the light's ball (point, spot) or
/// of its disc of directions (directional), its centre among them.
bool partlyHidden(const SceneLight& light, const cv::Vec3d& x, const cv::Vec3d& c, double r, std::mt19937& rng) {
  std::normal_distribution<double> g;
  std::uniform_real_distribution<double> u;
  for (int s = 0; s < 400; ++s) {
    const cv::Vec3d jitter =
        s == 0 ? cv::Vec3d(0, 0, 0) : cv::normalize(cv::Vec3d(g(rng), g(rng), g(rng))) * std::cbrt(u(rng));
    cv::Vec3d w;
    if (light.type == LightType::Directional) {
      w = cv::normalize(-light.direction + std::tan(light.extent) * jitter);
    } else {
      const cv::Vec3d to = light.position + light.extent * jitter - x;
      w = to / cv::norm(to);
      if (hitsSphere(x, w, c, r) && (c - x).dot(w) < cv::norm(to)) return true;
      continue;
    }
    if (hitsSphere(x, w, c, r)) return true;
  }
  return false;
}

TEST(ShadowFootprint, EveryReceiverAPartOfALightCannotSeeIsHeldAndLittleElse) {
  const cv::Vec3d c(0.05, -0.02, 0.1);
  const double r = 0.08;
  SceneLight lamp;  // a sphere lamp aslant above
  lamp.type = LightType::Point;
  lamp.position = {-0.4, -0.3, 0.6};
  lamp.extent = 0.1;
  SceneLight point = lamp;  // a point high above
  point.position = {0.2, 0.1, 1.5};
  point.extent = 0;
  SceneLight sun;  // a wide sun low over the plane
  sun.type = LightType::Directional;
  sun.direction = cv::normalize(cv::Vec3d(-0.9, 0.3, -0.35));
  sun.extent = 0.2;
  SceneLight sharp = sun;  // and a sharp one from above
  sharp.direction = cv::normalize(cv::Vec3d(0.3, 0.2, -0.9));
  sharp.extent = 0;
  std::mt19937 rng(7);
  for (const SceneLight& l : {lamp, point, sun, sharp}) {
    int hidden = 0, held = 0;
    for (int i = 0; i < 120; ++i)
      for (int j = 0; j < 120; ++j) {
        const cv::Vec3d x(-1.2 + 2.4 * (i + 0.5) / 120, -1.2 + 2.4 * (j + 0.5) / 120, 0.0);
        const bool h = partlyHidden(l, x, c, r, rng), m = lighting::mayShadow(l, c, r, x, 0.0);
        if (h) {
          ASSERT_TRUE(m) << "a receiver in the shadow left out at " << x;
        }
        hidden += h;
        held += m;
      }
    EXPECT_GT(hidden, 20);
    EXPECT_LT(held, 2 * hidden + 60) << "the bound is loose: " << held << " held, " << hidden << " hidden";
  }
  // The light inside the sphere, or touching it: everything.
  SceneLight inside = lamp;
  inside.position = c + cv::Vec3d(0, 0, 0.5 * r);
  EXPECT_TRUE(lighting::mayShadow(inside, c, r, {1.0, 1.0, 0.0}, 0.0));
}

TEST(ShadowFootprint, EmptyMeshHoldsTheObjectsAloneAndBehindTheCameraNothing) {
  const CameraView cam = topCamera(64, 64);
  const cv::Rect box = lighting::objectsFootprint(cam, {0, 0, 0.1}, 0.1, {pointAbove()}, 0.0, {}, {});
  EXPECT_FALSE(box.empty());
  EXPECT_LT(box.area(), 64 * 64 / 2);
  EXPECT_TRUE(box.contains({32, 30}));
  // Behind the camera (it looks down from 1.6 m): nothing of it in view.
  EXPECT_TRUE(lighting::objectsFootprint(cam, {0, -0.4, 3.0}, 0.1, {}, 0.0, {}, {}).empty());
  // Around the camera: the whole image.
  EXPECT_EQ(lighting::objectsFootprint(cam, {0, -0.25, 1.6}, 0.1, {}, 0.0, {}, {}), cv::Rect(0, 0, 64, 64));
}

TEST(ShadowFootprint, TheBandsAroundTheFootprintCoverTheRestOfTheImageOnce) {
  const cv::Rect image(0, 0, 64, 48);
  cv::RNG rng(5);
  for (int n = 0; n < 500; ++n) {
    // Footprints inside the image, on its edges, past them, empty, and the whole image.
    const int x0 = rng.uniform(-10, 70), y0 = rng.uniform(-10, 55);
    const cv::Rect inner(x0, y0, rng.uniform(0, 80), rng.uniform(0, 60));
    cv::Mat count(image.size(), CV_8UC1, cv::Scalar(0));
    const auto bands = lighting::bandsAround(image, inner);
    EXPECT_LE(bands.size(), 4u);
    for (const cv::Rect& b : bands) {
      ASSERT_FALSE(b.empty());
      ASSERT_EQ(b & image, b);
      count(b) += 1;
    }
    for (int y = 0; y < image.height; ++y)
      for (int x = 0; x < image.width; ++x)
        ASSERT_EQ(count.at<uchar>(y, x), inner.contains({x, y}) ? 0 : 1) << inner << " at " << x << "," << y;
  }
  EXPECT_TRUE(lighting::bandsAround(image, image).empty());
  EXPECT_EQ(lighting::bandsAround(image, cv::Rect()), std::vector<cv::Rect>{image});
}

TEST(GL, WithNoObjectTheShadingPassWritesZerosAndMarksTheSurfaceSeen) {
  // No virtual object: the pass draws its SHADE_UNLIT variant alone. Nothing to add to a real pixel, no virtual
  // pixel, no irradiance; the debug output's alpha is 1 exactly where the G-buffer saw a surface.
  auto ctx = makeContext();
  const int W = 64, H = 48;
  const TestScene s = makeScene(true, 0.0, {0, 0, 0});
  ASSERT_TRUE(s.objects.empty());
  for (const std::string technique : {"none", "kinect-val", "imperfect-volumes"}) {
    SCOPED_TRACE(technique);
    LightingPipeline pipe = makePipeline(testConfig(W, H, 16, 64, technique), s);
    CameraView cam = topCamera(W, H);
    cam.T_world_camera = capture::lookAtPose({0.0, -1.6, 1.0}, {0, 0, 0.3});  // the floor, the wall and the sky
    pipe.run(cam, {pointAbove()}, cv::Vec3d::all(0.2), nullptr);
    const cv::Mat shade = pipe.downloadShade(), irradiance = pipe.downloadIrradiance(),
                  position = pipe.downloadGBuffer(0);
    ASSERT_EQ(shade.type(), CV_32FC4);
    EXPECT_EQ(cv::countNonZero(shade.reshape(1) != 0), 0);
    size_t seen = 0, sky = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const cv::Vec4f e = irradiance.at<cv::Vec4f>(y, x);
        const bool surface = position.at<cv::Vec4f>(y, x)[3] >= 0.5f;
        ASSERT_EQ(e, cv::Vec4f(0, 0, 0, surface ? 1.f : 0.f)) << x << "," << y;
        (surface ? seen : sky) += 1;
      }
    EXPECT_GT(seen, 0u);
    EXPECT_GT(sky, 0u);
  }
}

TEST(GL, TheShadingPassBoundedToTheObjectsFootprintWritesTheWholePassImage) {
  // A cube on a finely meshed floor under a sphere lamp (soft shadows), then a sharp sun and a point light: at the
  // frame's resolution and at render_scale 1/2, with the shadow left to the pass and with a technique, the
  // pass bounded to the footprint writes what the whole pass writes, over less than the image.
  auto ctx = makeContext();
  const int W = 160, H = 120;
  TestScene s;
  addQuad(s.vertices, s.indices, {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, kFloorAlbedo, 128);
  s.objects = makeScene(false, 0.12, {0.05, 0.0, 0.06}).objects;
  CameraView cam = topCamera(W, H);
  cam.T_world_camera = capture::lookAtPose({0.0, -0.9, 1.1}, {0, 0, 0});
  const std::vector<std::vector<SceneLight>> lightSets = {{sphereLamp({-0.3, -0.25, 0.3}, 0.1)},
                                                          {obliqueSun(), pointAbove()}};
  for (const std::string technique : {"none", "kinect-val"})
    for (const double scale : {1.0, 0.5})
      for (const std::vector<SceneLight>& lights : lightSets) {
        SCOPED_TRACE(technique + " at render_scale " + std::to_string(scale) + ", lights " +
                     std::to_string(lights.size()));
        PipelineConfig cfg = testConfig(W, H, 16, 128, technique);
        cfg.set("frame", "render_scale", scale);
        cfg.set("frame", "soft_shadow_lights", 16);
        LightingPipeline pipe = makePipeline(cfg, s);
        const cv::Vec3d ambient(0.05, 0.05, 0.05);
        pipe.run(cam, lights, ambient, nullptr);
        const cv::Mat bounded = pipe.downloadShade();
        const cv::Rect footprint = pipe.shadedFootprint();
        pipe.setBoundedShading(false);
        pipe.invalidate();
        pipe.run(cam, lights, ambient, nullptr);
        const cv::Mat whole = pipe.downloadShade();
        EXPECT_EQ(pipe.shadedFootprint(), cv::Rect(0, 0, W, H));
        EXPECT_GT(footprint.area(), 0);
        EXPECT_LT(footprint.area(), W * H * 6 / 10);
        double worst = 0, peak = 0;
        int outside = 0;
        for (int y = 0; y < H; ++y)
          for (int x = 0; x < W; ++x) {
            const cv::Vec4f a = bounded.at<cv::Vec4f>(y, x), b = whole.at<cv::Vec4f>(y, x);
            for (int k = 0; k < 4; ++k) worst = std::max(worst, double(std::abs(a[k] - b[k])));
            peak = std::max(peak, double(std::abs(b[0])));
            if (!footprint.contains({x, y}) && std::abs(b[0]) > 1e-4) ++outside;
          }
        EXPECT_GT(peak, 0.01);
        EXPECT_GT(outside, 100);  // the pixels outside still take the objects' other terms
        EXPECT_LE(worst, 1e-6 * std::max(1.0, peak)) << "footprint " << footprint;
      }
}

}  // namespace
}  // namespace mrgi::test
