// The shading pass's direct light and shadows (lighting/direct_light.glsl) against their C++ twin
// (lighting::lightVisibility), and the objects' shadow maps: the object's shadow edge follows the object at
// the objects' map's resolution, not the region's RSM's.
#include <gtest/gtest.h>

#include "lighting/object_shadow.h"
#include "tests/lighting/test_scene.h"

namespace mrgi::test {
namespace {

using lighting::LightType;

SceneLight spotAbove() {
  SceneLight l;
  l.type = LightType::Spot;
  l.position = {-0.2, 0.3, 0.9};
  l.direction = cv::normalize(cv::Vec3d(0.2, -0.3, -0.9));
  l.spotHalfAngleDeg = 35;
  l.intensity = {3, 3, 3};
  return l;
}

// Lights with extent (lighting::SceneLight::extent): a wide sun low over the cube and a sphere lamp
// (test_scene.h's sphereLamp()).
SceneLight wideLowSun() {
  SceneLight l = sunDown(6.0);
  l.direction = cv::normalize(cv::Vec3d(-0.9, 0.3, -0.25));  // 15 degrees over the floor
  l.extent = 0.5;                                            // radians: the floor straddles its horizon
  return l;
}

// Technique "none": real pixels get exactly the object's direct shadow, sum_i E_i (V_i(rho) - V_i(mu)); the
// object gets sum_i E_i V_i(rho) + pi ambient. Both are recomputed per pixel on the CPU from the downloaded
// maps through the twin.
TEST(DirectLight, ShadingPassMatchesItsCppTwinForEveryLightType) {
  auto ctx = makeContext();
  const int W = 200, H = 150;
  TestScene s = makeScene(true, 0.15, {0.05, 0.0, 0.075});
  PipelineConfig cfg = testConfig(W, H, 16, 128, "none");
  cfg.set("frame", "shadow_size", 256);
  cfg.set("frame", "soft_shadow_lights", 16);   // the wide lights' soft shadows
  cfg.set("frame", "object_terms_scale", 1.0);  // every pixel's own object terms
  LightingPipeline pipe = makePipeline(cfg, s);
  const std::vector<SceneLight> lights = {obliqueSun(), pointAbove(), spotAbove(), wideLowSun(), sphereLamp()};
  const cv::Vec3d ambient(0.03, 0.03, 0.03);
  pipe.run(topCamera(W, H), lights, ambient, nullptr);
  const auto& frame = pipe.frame();
  std::vector<lighting::ShadowTexels> maps;
  for (size_t i = 0; i < lights.size(); ++i) {
    maps.push_back(frame.downloadShadowTexels(i));
    ASSERT_FALSE(maps.back().objects.empty()) << i;  // every light here is far enough for the objects' view
  }
  const cv::Mat irr = pipe.downloadIrradiance(), shade = pipe.downloadShade();
  const cv::Mat pos = pipe.downloadGBuffer(0), nrm = pipe.downloadGBuffer(1), alb = pipe.downloadGBuffer(2);
  lighting::Ambient sky;
  sky.uniform = cv::Vec3f(ambient);
  const std::vector<lighting::OccluderSphere> spheres{lighting::occluderSphere(s.objects[0])};
  // A light reaches the cube where the real scene's map sees the cube's point facing it (the wall hides the sun).
  int hidden = 0;
  const lighting::LightReaches reaches = [&](size_t l, const cv::Vec3d& p, const cv::Vec3d& towards) {
    const bool seen = lighting::lightVisibility(maps[l], lights[l], frame.lightViews()[l], false, p, towards) > 0.f;
    hidden += !seen;
    return seen;
  };
  int real = 0, shadowed = 0, virt = 0, differ = 0, extentMatters = 0, penumbra = 0;
  for (int i = 0; i < static_cast<int>(pos.total()); ++i) {
    const cv::Vec4f p = pos.at<cv::Vec4f>(i), n = nrm.at<cv::Vec4f>(i), a = alb.at<cv::Vec4f>(i);
    if (p[3] < 0.5f) continue;
    const cv::Vec3d x(p[0], p[1], p[2]), nn(n[0], n[1], n[2]);
    cv::Vec3d with(0, 0, 0), without(0, 0, 0);
    for (size_t l = 0; l < lights.size(); ++l) {
      const cv::Vec3d e = lighting::unshadowedIrradiance(lights[l], x, nn);
      SceneLight point = lights[l];
      point.extent = 0;
      if (cv::norm(e - lighting::unshadowedIrradiance(point, x, nn)) > 1e-2 * (1 + cv::norm(e))) ++extentMatters;
      // A virtual surface tests the real surfaces' map smoothly (lighting::virtualLightVisibility).
      const float v = a[3] > 0.5f ? lighting::virtualLightVisibility(maps[l], lights[l], frame.lightViews()[l], x, nn)
                                  : lighting::lightVisibility(maps[l], lights[l], frame.lightViews()[l], true, x, nn);
      with += e * v;
      penumbra += v > 0.f && v < 1.f && cv::norm(e) > 0;
      without += e * lighting::lightVisibility(maps[l], lights[l], frame.lightViews()[l], false, x, nn);
    }
    double got, want;
    if (a[3] > 0.5f) {
      ++virt;
      want = (with[0] + CV_PI * ambient[0]) * a[0] / CV_PI;
      got = shade.at<cv::Vec4f>(i)[0];
    } else {
      ++real;
      // The direct shadow, the ambient the cube hides and the lights it reflects (lighting/object_shadow.h).
      // What the cube reflects of the ambient is lit as the floor around it is, and it reflects the lights.
      // ... and as the ground under the cube, where the face it turns towards x looks (lighting::facedGround).
      const lighting::FacedGround g = lighting::facedGround(cv::Vec3f(x), cv::Vec3f(nn), spheres);
      cv::Vec3d groundWith(0, 0, 0), groundWithout(0, 0, 0);
      const cv::Vec3d gx(g.point);
      for (size_t l = 0; l < lights.size(); ++l) {
        const cv::Vec3d e = lighting::unshadowedIrradiance(lights[l], gx, nn);
        groundWith += e * lighting::lightVisibility(maps[l], lights[l], frame.lightViews()[l], true, gx, nn);
        groundWithout += e * lighting::lightVisibility(maps[l], lights[l], frame.lightViews()[l], false, gx, nn);
      }
      const cv::Vec3f lit = lighting::blendLit(
          lighting::litFraction(sky, cv::Vec3f(x), cv::Vec3f(nn), spheres, cv::Vec3f(without), cv::Vec3f(with)),
          lighting::litFraction(sky, g.point, cv::Vec3f(nn), spheres, cv::Vec3f(groundWithout), cv::Vec3f(groundWith)),
          g.weight);
      want = with[0] - without[0] - lighting::ambientShadow(sky, cv::Vec3f(x), cv::Vec3f(nn), spheres, lit)[0] +
             lighting::reflectedLight(cv::Vec3f(x), cv::Vec3f(nn), spheres, lights, reaches)[0];
      got = irr.at<cv::Vec4f>(i)[0];
      if (want < -1e-3) ++shadowed;
    }
    // A lookup on a texel boundary may round the other way in float; such pixels are counted, not failed.
    if (std::abs(got - want) > 1e-4 * (1.0 + std::abs(want))) ++differ;
  }
  EXPECT_GT(real, 5000);
  EXPECT_GT(virt, 250);
  EXPECT_GT(shadowed, 250);
  EXPECT_GT(extentMatters, 250);  // the cube's sides near the wide lights' horizons
  EXPECT_GT(penumbra, 250);       // the soft edges of the wide lights' shadows
  EXPECT_GT(hidden, 0);           // the oblique sun, behind the wall as the cube sees it
  EXPECT_LE(differ, (real + virt) / 500) << differ << " of " << real + virt << " pixels differ";
}

// A virtual surface crossed by a real occluder's shadow edge (the wall's, from a low sun) sees it over a texel of
// the real surfaces' map, not in a step: along a line across the edge, visibility falls monotonically through
// values between 0 and 1, where the hard test jumps (the stair-step bands a table's edge drew on a sphere).
TEST(DirectLight, AVirtualSurfaceSeesARealShadowEdgeWithoutSteps) {
  auto ctx = makeContext();
  const int W = 64, H = 48;
  const TestScene s = makeScene(true, 0.15, {0.05, 0.0, 0.075});
  PipelineConfig cfg = testConfig(W, H, 16, 32, "none");  // a coarse region map: 32 texels
  LightingPipeline pipe = makePipeline(cfg, s);
  SceneLight sun = sunDown(5.0);
  sun.direction = cv::normalize(cv::Vec3d(0.7, 0.0, -1.5));  // over the wall: its shadow ends at x = 0.2
  pipe.run(topCamera(W, H), {sun}, {0.0, 0.0, 0.0}, nullptr);
  const lighting::ShadowTexels maps = pipe.frame().downloadShadowTexels(0);
  const lighting::LightView& view = pipe.frame().lightViews()[0];
  // Along the floor from under the wall's shadow out into the sun (the floor stands in for any surface: the
  // test of the real surfaces' map is the same function for a virtual one).
  int between = 0, hardBetween = 0, rises = 0;
  float last = -1.f;
  bool monotonic = true;
  const cv::Vec3d n(0, 0, 1);
  for (double x = 0.0; x <= 0.4; x += 0.002) {
    const cv::Vec3d p(x, 0.3, 0.0);
    const float v = lighting::smoothShadowTest(maps.mu, sun, view.viewProj, view.shadowBias, p, n);
    const float hard = lighting::shadowTest(maps.mu, sun, view.viewProj, view.shadowBias, p, n);
    between += v > 0.02f && v < 0.98f;
    hardBetween += hard > 0.f && hard < 1.f;
    if (last >= 0 && v < last - 1e-6f) monotonic = false;
    rises += last >= 0 && v > last;
    last = v;
  }
  EXPECT_EQ(hardBetween, 0);
  EXPECT_GE(between, 5) << "a ramp over about a texel (3 cm here), sampled every 2 mm";
  EXPECT_GT(rises, 0);
  EXPECT_TRUE(monotonic);
  EXPECT_NEAR(last, 1.f, 1e-6f);
}

// An oblique sun: the cube's shadow on the floor is where a ray towards the sun hits the cube. With a region
// RSM of 32 texels (3.2 cm each) the edge is wrong over a band of pixels; the objects' map (512 over the
// cube's bounding sphere, 0.5 mm) puts it where the cube is. Pixels within 2 mm of the edge are not judged.
TEST(DirectLight, ObjectShadowEdgeFollowsTheObjectsMap) {
  auto ctx = makeContext();
  const int W = 200, H = 150;
  const double cube = 0.15;
  const cv::Vec3d centre(0.013, -0.007, 0.075);
  TestScene s = makeScene(false, cube, centre);
  s.objects[0].material.albedo = {0, 0, 0};  // black: its shadow alone, none of the sun it would reflect
  PipelineConfig cfg = testConfig(W, H, 16, 32, "none");
  cfg.set("frame", "shadow_size", 512);
  LightingPipeline pipe = makePipeline(cfg, s);
  SceneLight sun = sunDown(10.0);
  sun.direction = {0.6, 0.0, -0.8};
  pipe.run(topCamera(W, H), {sun}, cv::Vec3d::all(0.0), nullptr);
  const cv::Mat irr = pipe.downloadIrradiance(), pos = pipe.downloadGBuffer(0), alb = pipe.downloadGBuffer(2);
  int judged = 0, inShadowJudged = 0, wrong = 0;
  for (int i = 0; i < static_cast<int>(pos.total()); ++i) {
    const cv::Vec4f p = pos.at<cv::Vec4f>(i);
    if (p[3] < 0.5f || alb.at<cv::Vec4f>(i)[3] > 0.5f || p[2] > 1e-3f) continue;
    const cv::Vec3d x(p[0], p[1], p[2]);
    const bool inside = inShadow(x, sun.direction, centre, 0.5 * cube - 0.002);
    const bool outside = !inShadow(x, sun.direction, centre, 0.5 * cube + 0.002);
    if (!inside && !outside) continue;
    ++judged;
    inShadowJudged += inside;
    const float e = irr.at<cv::Vec4f>(i)[0];
    if (inside ? std::abs(e + 8.0f) > 1e-4f : e != 0.0f) ++wrong;  // E cos = 10 x 0.8 lost
  }
  EXPECT_GT(judged, 20000);
  EXPECT_GT(inShadowJudged, 150);  // the region map gets about 100 of these wrong
  EXPECT_EQ(wrong, 0);
}

// The objects' view: orthographic for a directional light, a frustum around the bounding sphere for a
// point light, none when the light is among the objects (RSM^rho tests them then, and the output stays
// defined).
TEST(DirectLight, ObjectViewFallsBackToTheRegionsMapWhenALightSitsAmongTheObjects) {
  lighting::Region region = lighting::fitRegion({-0.1, -0.1, 0}, {0.1, 0.1, 0.2}, 4.0);
  lighting::LightView v = lighting::fitLightView(pointAbove(), region, 64);
  lighting::fitObjectView(v, pointAbove(), {0, 0, 0.1}, 0.17, 256);
  EXPECT_GT(v.objectShadowBias, 0);
  // The sphere's silhouette fills the view: a point on it at right angles to the light's axis maps to the
  // frustum's edge.
  SceneLight inside = pointAbove();
  inside.position = {0.02, 0.0, 0.12};
  lighting::fitObjectView(v, inside, {0, 0, 0.1}, 0.17, 256);
  EXPECT_LT(v.objectShadowBias, 0);

  auto ctx = makeContext();
  TestScene s = makeScene(false, 0.15, {0, 0, 0.075});
  PipelineConfig cfg = testConfig(64, 48, 16, 64, "none");
  LightingPipeline pipe = makePipeline(cfg, s);
  SceneLight close = pointAbove();
  close.position = {0.0, 0.0, 0.2};  // 12.5 cm from the cube's centre, inside its bounding sphere (13 cm)
  pipe.run(topCamera(64, 48), {close}, cv::Vec3d::all(0.01), nullptr);
  EXPECT_LT(pipe.frame().lightViews()[0].objectShadowBias, 0);
  const cv::Mat shade = pipe.downloadShade();
  EXPECT_TRUE(cv::checkRange(shade));
  const auto maps = pipe.frame().downloadShadowTexels(0);
  EXPECT_TRUE(maps.objects.empty());
  EXPECT_FALSE(maps.rho.empty());  // RSM^rho stands in for the objects' map
}

// A sphere of radius 6 cm, 30 cm over the floor, under a sun of 6 degrees half-angle 30 degrees off the
// vertical (so the camera above sees the shadow beside the sphere): each
// floor point sees the sun's disc partly covered by the sphere's (half-angle b = asin(R / distance), at angle
// g from the sun's centre); the visible fraction is 1 - the two discs' overlap / the sun's disc. The shading
// pass's real pixels hold E (V - 1) (no ambient). Its soft shadow against that, and the hard shadow of the
// same sun without extent.
TEST(DirectLight, ASunWithExtentCastsThePenumbraOfItsDisc) {
  auto ctx = makeContext();
  const int W = 400, H = 300;
  const double R = 0.06, h = 0.3, a = 6 * CV_PI / 180;
  TestScene s = makeScene(false, 0, {0, 0, 0});
  VirtualObject ball;
  ball.mesh = lighting::loadMesh(std::string(MRGI_SOURCE_DIR) + "/recordings/models/sphere.ply");
  for (auto& p : ball.mesh.positions) p *= static_cast<float>(R);
  ball.mesh.computeBounds();
  ball.material.albedo = {0.9f, 0.9f, 0.9f};
  const cv::Vec3d c(0.02, -0.01, h);
  ball.T_marker_object = capture::makePose(cv::Matx33d::eye(), c);
  s.objects.push_back(ball);
  const auto overlap = [](double r1, double r2, double d) {  // area of two circles' intersection
    if (d >= r1 + r2) return 0.0;
    if (d <= std::abs(r1 - r2)) return CV_PI * std::min(r1, r2) * std::min(r1, r2);
    const double a1 = std::acos(std::clamp((d * d + r1 * r1 - r2 * r2) / (2 * d * r1), -1.0, 1.0));
    const double a2 = std::acos(std::clamp((d * d + r2 * r2 - r1 * r1) / (2 * d * r2), -1.0, 1.0));
    return r1 * r1 * (a1 - std::sin(2 * a1) / 2) + r2 * r2 * (a2 - std::sin(2 * a2) / 2);
  };
  const cv::Vec3d toSun(0.5, 0.0, std::sqrt(0.75));
  double errSoft = 0, errHard = 0, errOff = 0;
  int judged = 0, partial = 0;
  // The sun with extent, without, and with extent but no soft shadows (frame knob soft_shadow_lights 0).
  for (const double extent : {a, 0.0, -a}) {
    PipelineConfig cfg = testConfig(W, H, 16, 32, "none");
    cfg.set("frame", "shadow_size", 512);
    cfg.set("frame", "soft_shadow_lights", extent < 0 ? 0 : 1);
    LightingPipeline pipe = makePipeline(cfg, s);
    SceneLight sun = sunDown(10.0);
    sun.direction = toSun * -1.0;
    sun.extent = std::abs(extent);
    pipe.run(topCamera(W, H), {sun}, cv::Vec3d::all(0.0), nullptr);
    const cv::Mat irr = pipe.downloadIrradiance(), pos = pipe.downloadGBuffer(0), alb = pipe.downloadGBuffer(2);
    for (int i = 0; i < static_cast<int>(pos.total()); ++i) {
      const cv::Vec4f p = pos.at<cv::Vec4f>(i);
      if (p[3] < 0.5f || alb.at<cv::Vec4f>(i)[3] > 0.5f || p[2] > 1e-3f) continue;
      const cv::Vec3d x(p[0], p[1], p[2]), d = c - x;
      const double b = std::asin(R / cv::norm(d)), g = std::acos(std::clamp(d.dot(toSun) / cv::norm(d), -1.0, 1.0));
      if (g > a + b + 0.02) continue;  // far from the shadow: both exact
      const double want = 1 - overlap(a, b, g) / (CV_PI * a * a);
      const double got = 1 + irr.at<cv::Vec4f>(i)[0] / (10.0 * toSun[2]);
      if (extent > 0) {
        errSoft += std::abs(got - want), ++judged;
        partial += want > 0.05 && want < 0.95;
      } else if (extent == 0) {
        errHard += std::abs(got - want);
      } else {
        errOff += std::abs(got - want);
      }
    }
  }
  ASSERT_GT(judged, 1500);
  EXPECT_GT(partial, 1000);  // the penumbra, about 6 cm wide
  errSoft /= judged, errHard /= judged, errOff /= judged;
  std::printf("sun of 6 degrees over a sphere: visible fraction off by %.3f on average (a hard shadow: %.3f)\n",
              errSoft, errHard);
  EXPECT_LT(errSoft, 0.04);
  EXPECT_GT(errHard, 3 * errSoft);
  EXPECT_NEAR(errOff, errHard, 1e-6);
}

}  // namespace
}  // namespace mrgi::test
