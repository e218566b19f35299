// The reference path tracer against analytic results: furnaces, a plane under delta lights, an area light's
// form factor, 1/sqrt(spp) convergence, determinism, and the ρ/μ differential images.
#include "groundtruth/path_tracer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "capture/colour.h"
#include "capture/session.h"
#include "lighting/scene_file.h"

namespace mrgi::groundtruth {
namespace {

constexpr double kPi = CV_PI;

lighting::Mesh unitSphere() {
  return lighting::loadMesh(std::string(MRGI_SOURCE_DIR) + "/recordings/models/sphere.ply");
}

/// Adds a sphere of `radius` at `centre` to `scene` with a virtual material of `albedo`.
void addVirtualSphere(Scene& scene, double radius, const cv::Vec3d& centre, const cv::Vec3f& albedo) {
  Material v{"object", albedo};
  v.isVirtual = true;
  const int obj = scene.addMaterial(v);
  const lighting::Mesh sphere = unitSphere();
  scene.addMesh(sphere.positions, sphere.normals, sphere.indices, obj,
                capture::makePose(cv::Matx33d::eye() * radius, centre));
}

/// A camera at `eye` looking at `target` (OpenCV frame), w x h pixels, 60° horizontal field of view.
PinholeCamera camera(cv::Vec3d eye, cv::Vec3d target, int w = 32, int h = 24) {
  PinholeCamera c;
  const double f = 0.5 * w / std::tan(30 * kPi / 180);
  c.intrinsics = {w, h, f, f, (w - 1) / 2.0, (h - 1) / 2.0};
  c.T_world_camera = capture::lookAtPose(eye, target);
  return c;
}

/// Camera straight down (-z) from height hc over the origin, looking at the plane z = 0.
PinholeCamera downCamera(double hc, int w, int h) {
  PinholeCamera c;
  const double f = 0.5 * w / std::tan(30 * kPi / 180);
  c.intrinsics = {w, h, f, f, (w - 1) / 2.0, (h - 1) / 2.0};
  // x right = world x, y down = world -y, z forward = world -z.
  c.T_world_camera = capture::Pose(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, hc, 0, 0, 0, 1);
  return c;
}

/// Where pixel (x, y) of a down camera meets the plane z = 0.
cv::Vec3f onPlane(const PinholeCamera& c, int x, int y) {
  cv::Vec3f o, d;
  cameraRay(c, x, y, o, d);
  return o + (-o[2] / d[2]) * d;
}

TEST(PathTracer, ClosedEmissiveSphereIsAGeometricSeries) {
  // Inside a closed sphere whose walls have albedo a and emit Le, a path of B bounces gathers
  // Le (1 + a + ... + a^B); the cosine-sampled estimator of a Lambertian wall has no variance.
  const float a = 0.8f;
  Scene s;
  const int m = s.addMaterial({"wall", {a, a, a}, -1, {0, 0, 0}, 0, {1.0f, 0.5f, 0.25f}});
  const lighting::Mesh sphere = unitSphere();
  s.addMesh(sphere.positions, {}, sphere.indices, m);  // flat facets
  const RayCaster rc(s);
  for (int bounces : {0, 3, 12}) {
    PathTraceOptions o;
    o.spp = 4;
    o.bounces = bounces;
    const cv::Mat img = PathTracer(rc, o).render(camera({0.1, 0.05, 0}, {1, 0.2, 0.3}, 16, 12));
    const double series = (1 - std::pow(a, bounces + 1)) / (1 - a);
    for (int i = 0; i < static_cast<int>(img.total()); ++i) {
      const cv::Vec3f L = img.at<cv::Vec3f>(i);
      ASSERT_NEAR(L[0], series, 1e-4 * series) << "bounces " << bounces;
      ASSERT_NEAR(L[2], 0.25 * series, 1e-4 * series);
    }
  }
}

TEST(PathTracer, GlossyFurnaceConservesAlbedoPlusSpecular) {
  // With k = 0 the glossy lobe is uniform over the hemisphere and reflects exactly `specular`: the closed
  // sphere's radiance is the geometric series of a + s (now with sampling variance: mixture pdf).
  const float a = 0.45f, sp = 0.35f;
  Scene s;
  const int m = s.addMaterial({"wall", {a, a, a}, -1, {sp, sp, sp}, 0, {1, 1, 1}});
  const lighting::Mesh sphere = unitSphere();
  s.addMesh(sphere.positions, {}, sphere.indices, m);
  const RayCaster rc(s);
  PathTraceOptions o;
  o.spp = 256;
  o.bounces = 6;
  const cv::Mat img = PathTracer(rc, o).render(camera({0, 0, 0}, {0, 0, 1}, 8, 6));
  const double r = a + sp, series = (1 - std::pow(r, 7)) / (1 - r);
  EXPECT_NEAR(cv::mean(img)[0], series, 0.01 * series);
  // A sharp lobe loses what falls below the surface: bounded by the same series, never above it.
  Scene sharp;
  const int m2 = sharp.addMaterial({"wall", {a, a, a}, -1, {sp, sp, sp}, 200, {1, 1, 1}});
  sharp.addMesh(sphere.positions, {}, sphere.indices, m2);
  const RayCaster rc2(sharp);
  const cv::Mat img2 = PathTracer(rc2, o).render(camera({0, 0, 0}, {0, 0, 1}, 8, 6));
  EXPECT_LE(cv::mean(img2)[0], series * 1.01);
  EXPECT_GT(cv::mean(img2)[0], (1 - std::pow(a, 7)) / (1 - a));  // more than the diffuse part alone
}

TEST(PathTracer, WhiteConvexObjectInAUniformSkyIsInvisible) {
  // Albedo 1 under a uniform environment: every path off a convex object escapes, so L = L_env exactly.
  Scene s;
  const int m = s.addMaterial({"white", {1, 1, 1}});
  const lighting::Mesh sphere = unitSphere();
  s.addMesh(sphere.positions, {}, sphere.indices, m, capture::makePose(cv::Matx33d::eye(), {0, 0, 3}));
  s.environment = {0.7f, 0.7f, 0.7f};
  const RayCaster rc(s);
  PathTraceOptions o;
  o.spp = 2;
  o.bounces = 1;
  const cv::Mat img = PathTracer(rc, o).render(camera({0, 0, 0}, {0, 0, 3}, 16, 12));
  cv::Mat diff = cv::abs(img - cv::Scalar::all(0.7));
  double worst;
  cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
  EXPECT_LT(worst, 1e-5);
}

TEST(PathTracer, DiffusePlaneUnderDeltaLightsMatchesTheAnalyticIrradiance) {
  const float a = 0.6f;
  Scene s;
  const int m = s.addMaterial({"floor", {a, a, a}});
  s.addQuad({-5, -5, 0}, {10, 0, 0}, {0, 10, 0}, m);
  Light point;
  point.position = {0.1f, -0.05f, 0.5f};
  point.intensity = {2, 1, 0.5f};
  point.radius = 0;
  Light spot = point;
  spot.type = LightType::Spot;
  spot.position = {-0.2f, 0.1f, 0.4f};
  spot.direction = {0, 0, -1};
  spot.spotCos = static_cast<float>(std::cos(20 * kPi / 180));
  spot.intensity = {3, 3, 3};
  Light sun;
  sun.type = LightType::Directional;
  sun.direction = cv::normalize(cv::Vec3f(1, 0, -2));
  sun.irradiance = {0.5f, 0.5f, 0.5f};
  s.lights = {point, spot, sun};
  const RayCaster rc(s);
  PathTraceOptions o;
  o.spp = 1;
  o.bounces = 3;  // nothing to bounce off: the plane is alone under a black sky
  const PinholeCamera cam = downCamera(1.0, 48, 36);
  const cv::Mat img = PathTracer(rc, o).render(cam);
  int inCone = 0;
  for (int y = 0; y < 36; ++y)
    for (int x = 0; x < 48; ++x) {
      const cv::Vec3f p = onPlane(cam, x, y);
      cv::Vec3d E(0, 0, 0);
      const cv::Vec3f dp = point.position - p;
      E += cv::Vec3d(point.intensity) * (dp[2] / std::pow(cv::norm(dp), 3));
      const cv::Vec3f ds = spot.position - p;
      if (-cv::normalize(ds).dot(spot.direction) >= spot.spotCos) {
        E += cv::Vec3d(spot.intensity) * (ds[2] / std::pow(cv::norm(ds), 3));
        ++inCone;
      }
      E += cv::Vec3d(sun.irradiance) * static_cast<double>(-sun.direction[2]);
      const cv::Vec3f L = img.at<cv::Vec3f>(y, x);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(L[c], a / kPi * E[c], 1e-4 * a / kPi * E[c]) << x << "," << y;
    }
  EXPECT_GT(inCone, 20);           // the spot's disc is in view ...
  EXPECT_LT(inCone, 48 * 36 / 2);  // ... and its edge too
}

/// Form factor from a point to a parallel rectangle with one corner straight above it (sides w, l at height h).
double cornerFormFactor(double w, double l, double h) {
  if (w <= 0 || l <= 0) return 0;
  const double A = w / h, B = l / h;
  return (A / std::sqrt(1 + A * A) * std::atan(B / std::sqrt(1 + A * A)) +
          B / std::sqrt(1 + B * B) * std::atan(A / std::sqrt(1 + B * B))) /
         (2 * kPi);
}

TEST(PathTracer, AreaLightConvergesToItsFormFactorAsOneOverSqrtSpp) {
  // A plane under an emissive square found only by the sampled paths: L = a Le F (F: form factor).
  const float a = 0.5f, Le = 4.0f, h = 0.5f, half = 0.2f;
  Scene s;
  const int floor = s.addMaterial({"floor", {a, a, a}});
  const int lamp = s.addMaterial({"lamp", {0, 0, 0}, -1, {0, 0, 0}, 0, {Le, Le, Le}});
  s.addQuad({-5, -5, 0}, {10, 0, 0}, {0, 10, 0}, floor);
  s.addQuad({-half, -half, h}, {2 * half, 0, 0}, {0, 2 * half, 0}, lamp);
  const RayCaster rc(s);
  const PinholeCamera cam = downCamera(0.3, 24, 24);  // below the lamp, looking down
  cv::Mat truth(24, 24, CV_32FC1);
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 24; ++x) {
      const cv::Vec3f p = onPlane(cam, x, y);
      double F = 0;
      for (double sx : {-1.0, 1.0})
        for (double sy : {-1.0, 1.0})
          F += cornerFormFactor(half - sx * p[0], half - sy * p[1], h);  // the four corner rectangles
      truth.at<float>(y, x) = static_cast<float>(a * Le * F);
    }
  // Each sample returns a Le with probability F (the lamp's share of the cosine-weighted directions),
  // else 0: the per-sample standard deviation is a Le sqrt(F (1 - F)).
  cv::Mat F = truth / (a * Le), var = F.mul(1 - F);
  const double sigma = a * Le * std::sqrt(cv::mean(var)[0]);
  std::vector<double> spps, errors;
  for (int spp : {4, 16, 64, 256}) {
    PathTraceOptions o;
    o.spp = spp;
    o.bounces = 1;
    cv::Mat img = PathTracer(rc, o).render(cam), green;
    cv::extractChannel(img, green, 1);
    spps.push_back(std::log(spp));
    errors.push_back(std::log(cv::norm(green, truth, cv::NORM_L2) / std::sqrt(truth.total())));
  }
  // Least-squares slope of log RMSE against log spp: -1/2 for an unbiased Monte-Carlo estimator.
  double mx = 0, my = 0;
  for (size_t i = 0; i < spps.size(); ++i) mx += spps[i] / 4, my += errors[i] / 4;
  double sxy = 0, sxx = 0;
  for (size_t i = 0; i < spps.size(); ++i)
    sxy += (spps[i] - mx) * (errors[i] - my), sxx += (spps[i] - mx) * (spps[i] - mx);
  EXPECT_NEAR(sxy / sxx, -0.5, 0.08);
  // No bias: the RMSE at 256 spp is the sampling noise alone (within 15 %).
  EXPECT_NEAR(std::exp(errors.back()), sigma / 16, 0.15 * sigma / 16);
}

TEST(RayCaster, RaysThroughMeshVerticesNeverSlipThrough) {
  // A depth mesh has a vertex exactly on every second pixel's ray; a fast (non-watertight) traversal lets
  // such rays pass between the triangles sharing that vertex.
  const PinholeCamera cam = downCamera(1.0, 64, 48);
  Scene s;
  const int m = s.addMaterial({"grid", {0.5f, 0.5f, 0.5f}});
  std::vector<cv::Vec3f> positions;
  std::vector<uint32_t> indices;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      cv::Vec3f o, d;
      cameraRay(cam, x, y, o, d);
      const float depth = 0.8f + 0.1f * std::sin(0.7f * x) * std::cos(0.5f * y);  // a bumpy surface
      positions.push_back(o + (depth / -d[2]) * d);
    }
  for (uint32_t y = 0; y + 1 < 48; ++y)
    for (uint32_t x = 0; x + 1 < 64; ++x) {
      const uint32_t a = y * 64 + x, b = a + 1, c = a + 64, e = c + 1;
      indices.insert(indices.end(), {a, c, b, b, c, e});
    }
  s.addMesh(positions, {}, indices, m);
  const RayCaster rc(s);
  int misses = 0;
  for (int y = 1; y + 1 < 48; ++y)
    for (int x = 1; x + 1 < 64; ++x) {
      cv::Vec3f o, d;
      cameraRay(cam, x, y, o, d);
      misses += !rc.intersect(o, d);
    }
  // Fast traversal: 568 of the 2852 rays (20 %) escaped; Embree's robust mode alone 30 (1 %), rays that
  // meet a vertex exactly; with the nudged second look none.
  EXPECT_EQ(misses, 0);
}

TEST(PathTracer, ImageDependsOnTheSeedAloneNotOnTheThreads) {
  Scene s;
  const int m = s.addMaterial({"grey", {0.5f, 0.5f, 0.5f}});
  s.addBox({-1, -1, -1}, {1, 1, 1}, m, true);
  s.addBox({-0.2f, -0.2f, -0.2f}, {0.2f, 0.2f, 0.2f}, m);
  s.lights.push_back({{0.5f, 0.5f, 0.5f}, {1, 1, 1}, 0.0f});
  const RayCaster rc(s);
  PathTraceOptions o;
  o.spp = 3;
  o.bounces = 2;
  o.threads = 1;
  const PinholeCamera cam = camera({0.8, 0.7, -0.9}, {0, 0, 0});
  const cv::Mat one = PathTracer(rc, o).render(cam);
  o.threads = 4;
  const cv::Mat four = PathTracer(rc, o).render(cam);
  EXPECT_EQ(cv::norm(one, four, cv::NORM_INF), 0.0);
  o.seed = 2;
  EXPECT_GT(cv::norm(one, PathTracer(rc, o).render(cam), cv::NORM_INF), 1e-3);
}

TEST(PathTracer, DifferentialImagesShadowAndMaskTheVirtualObject) {
  // A plane lit from above with a virtual sphere hovering over it. Direct light only: outside the shadow
  // ρ − μ is exactly 0 (common random numbers), inside it is −a/π · E; virtual pixels carry ρ.
  const float a = 0.5f;
  Scene real;
  const int floor = real.addMaterial({"floor", {a, a, a}});
  real.addQuad({-5, -5, 0}, {10, 0, 0}, {0, 10, 0}, floor);
  real.lights.push_back({{0.8f, 0, 2}, {4, 4, 4}, 0.0f});
  Scene with = real;
  addVirtualSphere(with, 0.1, {0.0, 0.0, 0.3}, {0.8f, 0.2f, 0.2f});
  PathTraceOptions o;
  o.spp = 2;
  o.bounces = 0;
  int progressCalls = 0;
  double last = 0;
  o.progress = [&](double f) { ++progressCalls, last = f; };
  o.threads = 1;  // progress is reported by the calling thread: with one, every row of both renders
  const PinholeCamera cam = downCamera(1.0, 40, 30);
  const DifferentialImages d = renderDifferential(with, real, cam, o);
  EXPECT_GT(progressCalls, 30);
  EXPECT_DOUBLE_EQ(last, 1.0);
  const cv::Mat delta = d.delta();
  int shadowed = 0, virtualPixels = 0, litVirtual = 0;
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x) {
      const cv::Vec3f dv = delta.at<cv::Vec3f>(y, x);
      if (d.mask.at<uchar>(y, x)) {
        ++virtualPixels;
        EXPECT_NEAR(dv[0], 4 * dv[1], 1e-6);  // the red object's own radiance (albedo 0.8 vs 0.2)
        litVirtual += dv[0] > 0;
        continue;
      }
      const cv::Vec3f p = onPlane(cam, x, y);
      const cv::Vec3f toLight = cv::Vec3f(0.8f, 0, 2) - p;
      const float E = 4.f * toLight[2] / static_cast<float>(std::pow(cv::norm(toLight), 3));
      if (dv[0] != 0.f) {
        ++shadowed;
        EXPECT_NEAR(dv[0], -a / kPi * E, 1e-5);
      }
    }
  EXPECT_GT(virtualPixels, 10);
  EXPECT_GT(litVirtual, virtualPixels / 2);
  EXPECT_GT(shadowed, 5);
}

TEST(PathTracer, PartlyVirtualPixelsAreTheObjectsSilhouetteAndOnlyIt) {
  // A sphere of radius 0.1 seen from 0.7 m straight above over a plane: the pixels it covers in part form a
  // ring along its silhouette, as long as its perimeter (2 pi r, r in pixels: one pixel wide), every one of
  // them on the edge of the centre rays' mask (within one pixel of a pixel on the other side); nothing else.
  Scene with;
  const int floor = with.addMaterial({"floor", {0.5f, 0.5f, 0.5f}});
  with.addQuad({-5, -5, 0}, {10, 0, 0}, {0, 10, 0}, floor);
  addVirtualSphere(with, 0.1, {0.0, 0.0, 0.3}, {0.8f, 0.8f, 0.8f});
  const PinholeCamera cam = downCamera(1.0, 120, 90);
  const RayCaster rc(with);
  const cv::Mat centre = virtualMask(rc, cam), partly = partlyVirtualMask(rc, cam, 4);
  const double rPixels = cam.intrinsics.fx * 0.1 / 0.7;
  const int n = cv::countNonZero(partly);
  EXPECT_GT(n, 0.8 * 2 * kPi * rPixels);
  EXPECT_LT(n, 1.5 * 2 * kPi * rPixels);
  cv::Mat inside, outside;
  cv::dilate(centre, inside, cv::Mat::ones(3, 3, CV_8U));
  cv::erode(centre, outside, cv::Mat::ones(3, 3, CV_8U));
  const cv::Mat edge = inside - outside;  // pixels within one pixel of the mask's boundary
  EXPECT_EQ(cv::countNonZero(partly & ~edge), 0);
  // Limited to a region, nothing outside it; the objects' focus holds the whole ring.
  const cv::Rect focus = virtualFocus(with, cam, 0.1);
  EXPECT_EQ(cv::countNonZero(partlyVirtualMask(rc, cam, 4, focus)), n);
  EXPECT_EQ(cv::countNonZero(partlyVirtualMask(rc, cam, 4, {0, 0, 10, 10})), 0);
}

TEST(PathTracer, TheFocusAroundTheObjectsTakesItsOwnSamples) {
  // Pixels in the focus box take focusSpp samples: the same values as a render at focusSpp there, and as
  // one at spp elsewhere (each sample draws from its own stream). The focus holds the object's box grown by
  // three radii; nothing outside its grown sphere's projected box.
  Scene real;
  const int floor = real.addMaterial({"floor", {0.5f, 0.5f, 0.5f}});
  real.addQuad({-5, -5, 0}, {10, 0, 0}, {0, 10, 0}, floor);
  real.lights.push_back({{0.8f, 0, 2}, {4, 4, 4}, 0.0f});
  Scene with = real;
  addVirtualSphere(with, 0.05, {0.0, 0.0, 0.1}, {0.8f, 0.8f, 0.8f});
  const PinholeCamera cam = downCamera(1.5, 60, 40);
  const cv::Rect focus = virtualFocus(with, cam);
  ASSERT_FALSE(focus.empty());
  EXPECT_LT(focus.area(), 60 * 40 * 3 / 4);
  const cv::Mat mask = virtualMask(RayCaster(with), cam);
  EXPECT_EQ(cv::countNonZero(mask(focus)), cv::countNonZero(mask)) << "the object lies inside its focus";
  const RayCaster rc(with);
  PathTraceOptions o;
  o.spp = 2;
  o.bounces = 1;
  o.threads = 1;
  const cv::Mat low = PathTracer(rc, o).render(cam);
  o.spp = 8;
  const cv::Mat high = PathTracer(rc, o).render(cam);
  o.spp = 2;
  o.focus = focus;
  o.focusSpp = 8;
  const cv::Mat both = PathTracer(rc, o).render(cam);
  cv::Mat inside(both.size(), CV_8U, cv::Scalar(0));
  inside(focus).setTo(255);
  cv::Mat outside;
  cv::bitwise_not(inside, outside);
  EXPECT_EQ(cv::norm(both, high, cv::NORM_INF, inside), 0.0);
  EXPECT_EQ(cv::norm(both, low, cv::NORM_INF, outside), 0.0);
  EXPECT_GT(cv::norm(high, low, cv::NORM_INF, inside), 0.0);
  // No virtual material: no focus.
  EXPECT_TRUE(virtualFocus(real, cam).empty());
}

namespace env {
/// A 2:1 map: a dim uniform sky above the horizon, black below, and a small hot "sun" of `sun` radiance
/// over texels [x0, x0 + 2) x [y0, y0 + 2).
cv::Mat skyWithSun(int W, float sky, float sun, int x0, int y0) {
  cv::Mat m(W / 2, W, CV_32FC3, cv::Scalar::all(0));
  m(cv::Rect(0, 0, W, W / 4)).setTo(cv::Scalar::all(sky));
  m(cv::Rect(x0, y0, 2, 2)).setTo(cv::Scalar(sun, 0.9f * sun, 0.8f * sun));
  return m;
}
}  // namespace env

TEST(EnvironmentMap, SamplesInProportionToLuminanceAndItsPdfIsNormalised) {
  cv::Mat img(32, 64, CV_32FC3);
  cv::RNG rng(7);
  rng.fill(img, cv::RNG::UNIFORM, 0.01, 1.0);
  img.at<cv::Vec3f>(5, 9) = {500, 400, 300};
  img.at<cv::Vec3f>(3, 3) = {NAN, -1, INFINITY};  // cleaned to 0
  const EnvironmentMap map(img, 2.f);
  EXPECT_EQ(map.image().at<cv::Vec3f>(3, 3), cv::Vec3f(0, 0, 0));
  // The pdf integrates to 1 over the sphere (midpoint rule on a grid 8x finer than the texels).
  double sum = 0;
  const int nu = 512, nv = 256;
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const float u = (i + 0.5f) / nu, v = (j + 0.5f) / nv;
      const cv::Vec3f d = EnvironmentMap::directionOf(u, v);
      const cv::Vec2f uv = EnvironmentMap::uvOf(d);
      ASSERT_NEAR(uv[0], u, 1e-4);
      ASSERT_NEAR(uv[1], v, 1e-4);
      sum += map.pdf(d) * (2 * kPi * kPi * std::sin(kPi * v)) / (nu * nv);
    }
  EXPECT_NEAR(sum, 1.0, 2e-3);
  // Texels are chosen in proportion to luminance x solid angle and sampled uniformly in (u, v) within: each
  // sample's luminance / pdf is the map's integral up to sin(theta) / sin(theta at the texel's centre).
  cv::RNG r(11);
  int hot = 0;
  for (int i = 0; i < 2000; ++i) {
    const auto s = map.sample(r.uniform(0.f, 1.f), r.uniform(0.f, 1.f), r.uniform(0.f, 1.f));
    ASSERT_GT(s.pdf, 0.f);
    const double v = EnvironmentMap::uvOf(s.direction)[1];
    const double centre = kPi * (std::floor(v * map.height()) + 0.5) / map.height();
    const double expected = map.integral() * std::sin(kPi * v) / std::sin(centre);
    EXPECT_NEAR(capture::luminance(cv::Vec3d(s.radiance)) / s.pdf, expected, 1e-3 * expected);
    EXPECT_EQ(map.radiance(s.direction), s.radiance);
    hot += s.radiance[0] > 900.f;
  }
  EXPECT_GT(hot, 200);  // the hot texel holds a large share of the power
  const EnvironmentMap black(cv::Mat(8, 16, CV_32FC3, cv::Scalar::all(0)));
  EXPECT_EQ(black.sample(0.5f, 0.5f, 0.5f).pdf, 0.f);
  EXPECT_EQ(black.integral(), 0.0);
}

TEST(PathTracer, PlaneUnderAnHdrSunMatchesItsTexelIrradianceWithLowNoise) {
  // A plane facing up (+y) under a dim sky and a 2x2-texel sun 10^5 times brighter: the irradiance is the
  // sum over texels of L * integral(cos theta dw) = L * dphi * (sin^2 theta1 - sin^2 theta0) / 2.
  const int W = 128;
  const float sky = 0.2f, sun = 2e4f;
  const int x0 = 40, y0 = 9;
  Scene s;
  const float a = 0.5f;
  const int m = s.addMaterial({"ground", {a, a, a}});
  s.addQuad({-50, 0, -50}, {0, 0, 100}, {100, 0, 0}, m);
  s.environmentMap = std::make_shared<EnvironmentMap>(env::skyWithSun(W, sky, sun, x0, y0));
  const double dphi = 2 * kPi / W, dtheta = kPi / (W / 2);
  double E = sky * kPi;  // green channel: the uniform upper hemisphere, then the sun's texels replacing sky
  for (int y = y0; y < y0 + 2; ++y) {
    const double s0 = std::sin(y * dtheta), s1 = std::sin((y + 1) * dtheta);
    E += 2 * (0.9 * sun - sky) * dphi * (s1 * s1 - s0 * s0) / 2;
  }
  const double expected = a / kPi * E;
  for (int bounces : {0, 2}) {  // 2: BRDF-sampled rays escape too and are weighted against the samples
    PathTraceOptions o;
    o.spp = 16;
    o.bounces = bounces;
    PinholeCamera cam;
    cam.intrinsics = {24, 16, 20, 20, 11.5, 7.5};
    cam.T_world_camera = capture::lookAtPose({0, 2, 0.01}, {0, 0, 0});
    const cv::Mat img = PathTracer(RayCaster(s), o).render(cam);
    cv::Mat green;
    cv::extractChannel(img, green, 1);
    cv::Scalar mean, dev;
    cv::meanStdDev(green, mean, dev);
    EXPECT_NEAR(mean[0], expected, 0.01 * expected) << bounces;
    EXPECT_LT(dev[0] / mean[0], 0.05) << bounces;  // importance sampling: no fireflies from the sun
  }
}

}  // namespace
}  // namespace mrgi::groundtruth
