// Numerical extremes across every technique and its references: zero and huge flux, denormals, distances
// going to 0, grazing angles, Phong exponents 0 to 1e4, SH bands 1 to 8, vanishing cones, empty scenes and a
// virtual object outside the depth range. Every output must be finite and within a stated bound; some
// cases also have exact values (nothing lights it -> exactly 0, linear in the flux).
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

#include "groundtruth/path_tracer.h"
#include "lighting/sh.h"
#include "lighting/techniques/dlpv/lpv.h"
#include "lighting/techniques/kinect_val/val.h"
#include "test_scene.h"

namespace mrgi::lighting {
namespace {

using Outputs = std::vector<double>;

struct Extreme {
  Extreme(std::string n, double b, std::function<Outputs()> r, std::function<void(const Outputs&)> e = {})
      : name(std::move(n)), bound(b), run(std::move(r)), exact(std::move(e)) {}
  std::string name;
  double bound;  ///< every output's magnitude is at most this
  std::function<Outputs()> run;
  std::function<void(const Outputs&)> exact;  ///< optional further checks
};

constexpr float kDenormal = 1e-40f;

void append(Outputs& o, const cv::Vec3f& v) { o.insert(o.end(), {v[0], v[1], v[2]}); }
void append(Outputs& o, const cv::Mat& m) {
  cv::Mat f;
  m.convertTo(f, CV_64F);
  o.insert(o.end(), f.begin<double>(), f.end<double>());
}
void allZero(const Outputs& o) {
  for (double v : o) ASSERT_EQ(v, 0.0);
}

// --- SH -----------------------------------------------------------------------------------------------
Outputs shAt(int bands) {
  Outputs o;
  for (const cv::Vec3d& d : {cv::Vec3d(0, 0, 1), cv::Vec3d(0, 0, -1), cv::Vec3d(1, 0, 0), cv::Vec3d(0.6, -0.48, 0.64),
                             cv::Vec3d(1e-300, 0, 1), cv::Vec3d(std::sqrt(0.5), std::sqrt(0.5), 1e-300)}) {
    const auto y = sh::evaluate(d, bands);
    o.insert(o.end(), y.begin(), y.end());
  }
  return o;
}
double shBound(int bands) { return std::sqrt((2.0 * bands - 1) / (4 * CV_PI)) * 1.0001; }  // |Y_lm| ≤ sqrt((2l+1)/4π)

// --- LPV ----------------------------------------------------------------------------------------------
/// One RSM texel with the given flux at the centre of an 8³ grid, injected and propagated.
Outputs lpvWithFlux(float flux, int steps, bool negative) {
  const LpvGrid grid = fitGrid({-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}, 1.0, 8);
  RsmTexels t;
  t.position = cv::Mat(1, 1, CV_32FC4, cv::Scalar(0.01, 0.02, 0.0, 1));
  t.normal = cv::Mat(1, 1, CV_32FC4, cv::Scalar(0, 0, 1, 0));
  t.flux = cv::Mat(1, 1, CV_32FC4, cv::Scalar::all(flux));
  t.direct = cv::Mat(1, 1, CV_32FC4, cv::Scalar::all(flux));
  LpvVolumeCpu v(8);
  InjectParams p;
  p.sign = negative ? -1.f : 1.f;
  p.mode = kInjectIndirect | kInjectDirect;
  p.lightPosition = {0, 0, 2};
  injectReference(grid, t, nullptr, p, v);
  const LpvVolumeCpu out = propagateReference(grid, v, steps, 1.0f, !negative);
  Outputs o;
  for (const CellSh& c : out.cells)
    for (const auto& ch : c) o.insert(o.end(), ch.begin(), ch.end());
  // Read back at grazing and head-on normals, inside and on the grid's faces.
  for (const cv::Vec3f& n : {cv::Vec3f(0, 0, 1), cv::Vec3f(1, 0, 0), cv::Vec3f(0, 0, -1)})
    for (const cv::Vec3f& x : {cv::Vec3f(0, 0, 0.1f), cv::Vec3f(0.5f, 0.5f, 0.5f), cv::Vec3f(-0.5f, 0, 0)})
      append(o, irradianceReference(grid, out, x, n));
  return o;
}

// --- Kinect-VAL ---------------------------------------------------------------------------------------
Val valAt(cv::Vec3f p, cv::Vec3f n, float area, float flux) {
  Val v;
  v.position = p;
  v.normal = n;
  v.area = area;
  v.flux = cv::Vec3f::all(flux);
  return v;
}

Outputs gatherAndEvaluate(const Receiver& r, const std::vector<Val>& vals) {
  Outputs o;
  const ValGather g = gatherReference(r, vals);
  append(o, g.E);
  append(o, g.S);
  const SparseVpl vpl = normalizeReference(g, r);
  cv::Vec3f E, S;
  evaluateVpl(vpl, r, E, S);
  append(o, E);
  append(o, S);
  append(o, valRadiance(E, S, {0.5f, 0.5f, 0.5f}, {0.5f, 0.5f, 0.5f}, r.exponent));
  return o;
}

// --- Path tracer --------------------------------------------------------------------------------------
/// A plane z = 0 (albedo 0.5) seen from above by a 12 x 9 camera, with the given lights and sky.
Outputs planeImage(const std::vector<groundtruth::Light>& lights, cv::Vec3f sky, bool emptyScene = false,
                   float specular = 0, float exponent = 0) {
  groundtruth::Scene s;
  groundtruth::Material m{"plane", {0.5f, 0.5f, 0.5f}, -1, cv::Vec3f::all(specular), exponent};
  const int id = s.addMaterial(m);
  if (!emptyScene) s.addQuad({-5, -5, 0}, {10, 0, 0}, {0, 10, 0}, id);
  s.lights = lights;
  s.environment = sky;
  const groundtruth::RayCaster rc(s);
  groundtruth::PathTraceOptions o;
  o.spp = 4;
  o.bounces = 2;
  groundtruth::PinholeCamera cam;
  cam.intrinsics = {12, 9, 10, 10, 5.5, 4};
  cam.T_world_camera = capture::Pose(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 1, 0, 0, 0, 1);
  Outputs out;
  append(out, groundtruth::PathTracer(rc, o).render(cam));
  return out;
}

groundtruth::Light pointLight(cv::Vec3f p, float intensity) {
  groundtruth::Light l;
  l.position = p;
  l.intensity = cv::Vec3f::all(intensity);
  l.radius = 0;
  return l;
}

// --- GPU pipeline -------------------------------------------------------------------------------------
gl::Context& context() {
  static auto ctx = test::makeContext();
  return *ctx;
}

/// The floor + cube test scene through the GPU pipeline with one light; shade and irradiance targets.
Outputs pipelineRun(const std::string& technique, const SceneLight& light, cv::Vec3d cubeAt = {0.0, 0.0, 0.1},
                    double cube = 0.2, double ambient = 0.0) {
  context();
  test::TestScene s = test::makeScene(true, cube, cubeAt);
  PipelineConfig cfg = test::testConfig(48, 48, 16, 64, technique);
  cfg.set("val", "sparse_points", 64);
  LightingPipeline pipe = test::makePipeline(cfg, s);
  // Real surfaces as bright as the light (for techniques that take them as light sources).
  test::setTechniqueInputs(pipe, test::wallFrame(static_cast<float>(light.intensity[0] + light.irradiance[0])));
  pipe.run(test::topCamera(48, 48), {light}, cv::Vec3d::all(ambient), nullptr);
  Outputs o;
  append(o, pipe.downloadShade());
  append(o, pipe.downloadIrradiance());
  return o;
}

SceneLight spotWithHalfAngle(double deg, double intensity) {
  SceneLight l = test::pointAbove();
  l.type = LightType::Spot;
  l.direction = cv::normalize(cv::Vec3d(-0.3, -0.2, -1.2));
  l.spotHalfAngleDeg = deg;
  l.intensity = cv::Vec3d::all(intensity);
  return l;
}

std::vector<Extreme> cases() {
  std::vector<Extreme> c;
  // SH bands 1..8 at poles, axes and denormal components: |Y_lm| ≤ sqrt((2l+1)/4π).
  for (int bands = 1; bands <= 8; ++bands)
    c.push_back({"ShBands" + std::to_string(bands), shBound(bands), [bands] { return shAt(bands); }});
  for (const auto& [name, alpha] : {std::pair<const char*, double>{"ConeZonalAlphaE12", 1e-12},
                                    {"ConeZonalAlphaE6", 1e-6},
                                    {"ConeZonalFullSphere", CV_PI}})
    c.push_back({name, 4 * CV_PI, [alpha = alpha] { return sh::coneZonal(alpha, 8); }});
  for (double k : {0.0, 1e2, 1e4})
    c.push_back({"PhongFactorsExponent" + std::to_string(static_cast<int>(k)), 1.0,
                 [k] { return sh::phongLobeFactors(k, 8); }});
  // LPV: zero flux is exactly zero; 1e6 W stays finite (bounded by the flux × cells); denormals do not NaN.
  c.push_back({"LpvZeroFlux", 0.0, [] { return lpvWithFlux(0.f, 8, false); }, allZero});
  c.push_back({"LpvHugeFlux", 1e6 * 512 * 10, [] { return lpvWithFlux(1e6f, 8, false); }});
  c.push_back({"LpvDenormalFlux", 1e-30, [] { return lpvWithFlux(kDenormal, 8, false); }});
  c.push_back({"LpvNegativeDeltaManySteps", 1e6 * 512 * 10, [] { return lpvWithFlux(-1e6f, 64, true); }});
  c.push_back({"LpvNoSteps", 1e3 * 512 * 10, [] { return lpvWithFlux(1e3f, 0, false); }});
  c.push_back(
      {"LpvDampingOfAnEmptyCell", 1.0, [] {
         Outputs o;
         for (float d : {0.f, 0.5f, 1.f})
           for (const cv::Vec3f& dir : {cv::Vec3f(1, 0, 0), cv::Vec3f(0, 0, -1)})
             o.push_back(dampingFactor({0, 0, 0, 0}, dir, d)), o.push_back(dampingFactor({kDenormal, 1, 0, 0}, dir, d));
         return o;
       }});
  c.push_back({"LpvGridOfAPoint", 1.0, [] {
                 const LpvGrid g = fitGrid({0.2, 0.2, 0.2}, {0.2, 0.2, 0.2}, 4.0, 32);
                 EXPECT_GT(g.cellSize, 0.0);
                 return Outputs{g.cellSize, g.origin[0], g.origin[1], g.origin[2]};
               }});
  // Kinect-VAL: d -> 0, grazing, huge/denormal flux, exponents up to 1e4.
  c.push_back({"ValDiscFormFactorDistanceToZero", 1.0, [] {
                 const Val v = valAt({0, 0, 0}, {0, 0, 1}, 1e-4f, 1);
                 Outputs o;
                 for (float d : {1.f, 1e-3f, 1e-6f, 1e-20f, 0.f}) o.push_back(discFormFactor(v, {0, 0, d}));
                 return o;
               }});
  c.push_back({"ValDiscFormFactorGrazing", 1.0, [] {
                 const Val v = valAt({0, 0, 0}, {0, 0, 1}, 1e-2f, 1);
                 Outputs o;
                 for (float z : {0.f, 1e-7f, -1e-7f}) o.push_back(discFormFactor(v, {0.3f, 0, z}));
                 return o;
               }});
  c.push_back({"ValTouchingHugeFluxSharpLobe", 1e6 / 1e-4 * (1 / CV_PI + 0.5 * phongNorm(kMaxPhongExponent)) * 2, [] {
                 const Receiver r{{0, 0, 0}, {0, 0, 1}, cv::normalize(cv::Vec3f(1, 0, 1)), kMaxPhongExponent};
                 return gatherAndEvaluate(r, {valAt({0, 0, 0}, {0, 0, -1}, 1e-4f, 1e6f),
                                              valAt(cv::normalize(cv::Vec3f(-1, 0, 1)) * 0.1f,
                                                    cv::normalize(cv::Vec3f(1, 0, -1)), 1e-4f, 1e6f)});
               }});
  c.push_back({"ValDenormalAndZeroArea", 1.0, [] {
                 const Receiver r{{0, 0, 0}, {0, 0, 1}, {0, 0, 1}, 0.f};
                 return gatherAndEvaluate(
                     r, {valAt({0, 0, 0.1f}, {0, 0, -1}, 0.f, kDenormal), valAt({0, 0, 0.f}, {0, 0, -1}, 0.f, 0.f)});
               }});
  c.push_back({"ValNoValsIsExactlyZero", 0.0,
               [] {
                 return gatherAndEvaluate({{0, 0, 0}, {0, 0, 1}, {0, 0, 1}, 10.f}, {});
               },
               allZero});
  c.push_back({"ValGrazingReceiver", 1e3, [] {
                 // The VAL lies in the receiver's tangent plane, facing it: cos θ_i = 0.
                 return gatherAndEvaluate({{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, 100.f},
                                          {valAt({0.2f, 0, 0}, {-1, 0, 0}, 1e-3f, 1.f)});
               }});
  c.push_back({"PhongExponentFromRoughness", kMaxPhongExponent, [] {
                 return Outputs{phongExponent(0.f),  phongExponent(1e-30f), phongExponent(1.f),
                                phongExponent(-1.f), phongExponent(2.f),    phongLobe(1.f, kMaxPhongExponent),
                                phongLobe(0.f, 0.f)};
               }});
  // Path tracer: empty scene, huge and zero intensity, a light on the surface, grazing sun, sharp lobes.
  c.push_back({"PathTracerEmptySceneIsTheSky", 0.25,
               [] {
                 return planeImage({}, {0.25f, 0.25f, 0.25f}, true);
               },
               [](const Outputs& o) {
                 for (double v : o) ASSERT_FLOAT_EQ(v, 0.25);
               }});
  c.push_back({"PathTracerZeroIntensityIsBlack", 0.0,
               [] {
                 return planeImage({pointLight({0, 0, 0.5f}, 0.f)}, {0, 0, 0});
               },
               allZero});
  c.push_back({"PathTracerHugeIntensityScalesLinearly", 1e6, [] {
                 const Outputs a = planeImage({pointLight({0.1f, 0, 0.5f}, 1e6f)}, {0, 0, 0});
                 const Outputs b = planeImage({pointLight({0.1f, 0, 0.5f}, 1.f)}, {0, 0, 0});
                 for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], 1e6 * b[i], 1e-3 * a[i] + 1e-9);
                 return a;
               }});
  c.push_back({"PathTracerLightOnTheSurface", 1e-4, [] {
                 return planeImage({pointLight({0, 0, 0}, 5.f)}, {0, 0, 0});
               }});
  c.push_back({"PathTracerGrazingSunIsBlack", 0.0,
               [] {
                 groundtruth::Light sun;
                 sun.type = groundtruth::LightType::Directional;
                 sun.direction = {1, 0, 0};
                 sun.irradiance = {100, 100, 100};
                 return planeImage({sun}, {0, 0, 0});
               },
               allZero});
  c.push_back({"PathTracerSharpestLobeUnderASky", 1.0, [] {
                 return planeImage({}, {1, 1, 1}, false, 0.5f, kMaxPhongExponent);
               }});
  // GPU pipeline, every technique: nothing lit -> exactly 0; 1e6 W; an α -> 0 spot; a grazing sun; an
  // object outside the camera's depth range; a scene without a virtual object.
  for (const std::string& t : test::allTechniqueSpellings()) {
    const std::string n = "_" + test::testName(t) + "_";
    c.push_back({"GL" + n + "ZeroLightIsExactlyZero", 0.0,
                 [t] {
                   SceneLight l = test::pointAbove();
                   l.intensity = {0, 0, 0};
                   return pipelineRun(t, l);
                 },
                 allZero});
    c.push_back({"GL" + n + "HugeFlux", 1e9, [t] {
                   SceneLight l = test::pointAbove();
                   l.intensity = cv::Vec3d::all(1e6);
                   return pipelineRun(t, l);
                 }});
    c.push_back({"GL" + n + "VanishingSpotCone", 1e3, [t] { return pipelineRun(t, spotWithHalfAngle(1e-4, 5)); }});
    c.push_back({"GL" + n + "GrazingSun", 1e3, [t] {
                   SceneLight l = test::sunDown(10);
                   l.direction = cv::normalize(cv::Vec3d(1, 0, -1e-7));
                   return pipelineRun(t, l);
                 }});
    c.push_back({"GL" + n + "ObjectBeyondTheDepthRange", 1e3, [t] {
                   return pipelineRun(t, test::pointAbove(), {0, 0, -50});
                 }});
    c.push_back({"GL" + n + "NoVirtualObject", 1e3,
                 [t] {
                   return pipelineRun(t, test::pointAbove(), {0, 0, 0}, 0.0);
                 },
                 [t](const Outputs& o) {
                   // Real pixels: without an object there is nothing to add or remove (every 4th value is alpha).
                   PipelineConfig cfg;
                   cfg.technique = parseTechniqueChoice(t, &cfg.knobs);
                   if (cfg.knobs["lpv"]["naive_difference"] != 0 && cfg.technique.real == "dlpv")
                     return;  // the naive difference keeps its two volumes' noise
                   for (size_t i = 0; i + 3 < o.size() / 2; i += 4)
                     for (int ch = 0; ch < 3; ++ch) ASSERT_EQ(o[i + ch], 0.0) << "pixel " << i / 4;
                 }});
  }
  return c;
}

class Extremes : public ::testing::TestWithParam<Extreme> {};

TEST_P(Extremes, FiniteAndBounded) {
  const Extreme& e = GetParam();
  const Outputs out = e.run();
  ASSERT_FALSE(out.empty());
  for (size_t i = 0; i < out.size(); ++i) {
    ASSERT_TRUE(std::isfinite(out[i])) << e.name << " output " << i;
    ASSERT_LE(std::abs(out[i]), e.bound) << e.name << " output " << i;
  }
  if (e.exact) e.exact(out);
}

INSTANTIATE_TEST_SUITE_P(AllTechniques, Extremes, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<Extreme>& info) { return info.param.name; });

TEST(ExtremesSuite, HasAtLeastThirtyCases) { EXPECT_GE(cases().size(), 30u); }

}  // namespace
}  // namespace mrgi::lighting
