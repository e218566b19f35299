// Kinect-VAL inside the lighting pipeline: the sparse method against the per-pixel brute force, the brute
// force against the C++ reference, the standalone technique's real pixels (the object's direct shadow only),
// and its composition with DLPV.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "lighting/frame/light_view.h"
#include "lighting/object_shadow.h"
#include "lighting/pipeline.h"
#include "lighting/techniques/kinect_val/kinect_val.h"
#include "lighting/techniques/kinect_val/val.h"
#include "tests/lighting/test_scene.h"

using namespace mrgi;
using namespace mrgi::lighting;
using namespace mrgi::test;

namespace {

/// Hands Kinect-VAL these real VALs (its own input), as its builder would from a frame.
void setRealVals(LightingPipeline& pipe, std::vector<Val> vals) {
  auto input = std::make_shared<RealVals>();
  input->vals = std::move(vals);
  pipe.setTechniqueInput("kinect-val", input);
}

/// VALs tiling the quad p0 + [0,1] e1 + [0,1] e2 (n x n cells, normal e1 x e2) with a uniform exitance M:
/// the real surfaces as the depth sensor would hand them over, without the sensor.
void addQuadVals(std::vector<Val>& vals, cv::Vec3f p0, cv::Vec3f e1, cv::Vec3f e2, cv::Vec3f exitance, int n) {
  const cv::Vec3f normal = cv::normalize(e1.cross(e2));
  const float area = static_cast<float>(cv::norm(e1.cross(e2))) / static_cast<float>(n * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      Val v;
      v.position = p0 + e1 * ((i + 0.5f) / n) + e2 * ((j + 0.5f) / n);
      v.normal = normal;
      v.area = area;
      v.flux = exitance * area;
      vals.push_back(v);
    }
}

/// The floor (lit grey) and the red wall of makeScene as VALs.
std::vector<Val> roomVals() {
  std::vector<Val> vals;
  addQuadVals(vals, {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, {2.0f, 2.0f, 2.0f}, 48);
  addQuadVals(vals, {-0.5f, -1, 0}, {0, 2, 0}, {0, 0, 1.5f}, {3.0f, 0.3f, 0.3f}, 48);
  return vals;
}

/// A glossy white sphere of radius r at `at`, next to the red wall.
TestScene sphereScene(cv::Vec3d at, double r, float roughness = 1.0f, float specular = 0.0f) {
  TestScene s = makeScene(true, 0.0, {0, 0, 0});
  VirtualObject o;
  o.mesh = loadMesh(std::string(MRGI_SOURCE_DIR) + "/recordings/models/sphere.ply");
  for (auto& p : o.mesh.positions) p *= static_cast<float>(r);
  o.mesh.computeBounds();
  o.material.albedo = {0.6f, 0.6f, 0.6f};
  o.material.roughness = roughness;
  o.material.specular = specular;
  o.T_marker_object = capture::makePose(cv::Matx33d::eye(), at);
  s.objects.push_back(std::move(o));
  return s;
}

/// The pipeline's Kinect-VAL instance.
const KinectValTechnique& kval(const LightingPipeline& pipe) {
  return dynamic_cast<const KinectValTechnique&>(*pipe.technique("kinect-val"));
}

PipelineConfig valConfig(const std::string& t, int sparse, bool bruteForce, bool occlusion = false) {
  PipelineConfig cfg = testConfig(128, 96, 16, 128, t);
  cfg.set("val", "sparse_points", sparse);
  cfg.set("val", "brute_force", bruteForce);
  cfg.set("val", "occlusion", occlusion);
  return cfg;
}

CameraView sideCamera() {
  CameraView c;
  const int w = 128, h = 96;
  c.intrinsics = {w, h, 1.4 * w, 1.4 * w, 0.5 * w - 0.5, 0.5 * h - 0.5};
  c.T_world_camera = capture::lookAtPose({0.3, -0.9, 0.5}, {-0.3, 0.0, 0.12});
  return c;
}

/// Shades the scene without lights or ambient: virtual pixels then carry the Kinect-VAL radiance alone.
cv::Mat bounceOnly(const PipelineConfig& cfg, const TestScene& s, const std::vector<Val>& vals) {
  LightingPipeline pipe = makePipeline(cfg, s);
  setRealVals(pipe, vals);
  pipe.run(sideCamera(), {}, {0, 0, 0}, nullptr);
  return pipe.downloadShade();
}

/// Mean |a - b| over b's virtual pixels, relative to b's mean (luminance).
double relativeError(const cv::Mat& a, const cv::Mat& b, int* pixels = nullptr) {
  double diff = 0, ref = 0;
  int n = 0;
  for (int i = 0; i < static_cast<int>(b.total()); ++i) {
    const cv::Vec4f x = a.at<cv::Vec4f>(i), y = b.at<cv::Vec4f>(i);
    if (y[3] < 0.5f) continue;
    diff += std::abs(lum(x) - lum(y));
    ref += lum(y);
    ++n;
  }
  if (pixels) *pixels = n;
  return ref > 0 ? diff / ref : 1e30;
}

}  // namespace

TEST(GL, KinectValSparseConvergesToTheBruteForceOnTheVirtualObject) {
  auto ctx = makeContext();
  const TestScene s = sphereScene({-0.3, 0.0, 0.12}, 0.1);
  const auto vals = roomVals();
  const cv::Mat brute = bounceOnly(valConfig("kinect-val", 256, true), s, vals);
  int pixels = 0;
  double prev = 1e30;
  for (int sparse : {64, 256, 1024, 4096}) {
    const cv::Mat sp = bounceOnly(valConfig("kinect-val", sparse, false), s, vals);
    const double err = relativeError(sp, brute, &pixels);
    std::printf("sparse points %5d: %.2f %% mean relative error vs brute force over %d pixels\n", sparse, 100 * err,
                pixels);
    EXPECT_LT(err, prev * 1.05) << sparse;  // more points never make it clearly worse
    prev = err;
  }
  ASSERT_GT(pixels, 500);
  EXPECT_LT(prev, 0.03);  // 4096 sparse points: within 3 % of the per-pixel gather
  // The bounce is red on the side facing the red wall (-x) and grey-white from the floor below.
  bool sawRed = false;
  for (int i = 0; i < static_cast<int>(brute.total()); ++i) {
    const cv::Vec4f v = brute.at<cv::Vec4f>(i);
    if (v[3] < 0.5f) continue;
    EXPECT_TRUE(std::isfinite(v[0]) && v[0] >= 0 && v[1] >= 0 && v[2] >= 0);
    sawRed |= v[0] > 2.0f * v[1];
  }
  EXPECT_TRUE(sawRed);
}

TEST(GL, KinectValBruteForceMatchesTheCppReferencePerPixel) {
  auto ctx = makeContext();
  const TestScene s = sphereScene({-0.3, 0.0, 0.12}, 0.1, 0.3f, 0.3f);  // glossy: k = 2/0.09 - 2
  const auto vals = roomVals();
  const PipelineConfig cfg = valConfig("kinect-val", 256, true);
  LightingPipeline pipe = makePipeline(cfg, s);
  setRealVals(pipe, vals);
  const CameraView cam = sideCamera();
  pipe.run(cam, {}, {0, 0, 0}, nullptr);
  const cv::Mat shade = pipe.downloadShade(), pos = pipe.downloadGBuffer(0), nrm = pipe.downloadGBuffer(1);
  std::vector<Val> weighted = vals;
  setValWeights(weighted);
  const cv::Vec3f eye(capture::translationOf(cam.T_world_camera));
  const float k = phongExponent(0.3f);
  int checked = 0;
  for (int i = 0; i < static_cast<int>(shade.total()); i += 7) {
    const cv::Vec4f v = shade.at<cv::Vec4f>(i);
    if (v[3] < 0.5f) continue;
    const cv::Vec4f p = pos.at<cv::Vec4f>(i), n = nrm.at<cv::Vec4f>(i);
    EXPECT_EQ(n[3], 1.0f);  // object index 0 + 1
    Receiver r;
    r.position = {p[0], p[1], p[2]};
    r.normal = {n[0], n[1], n[2]};
    r.view = cv::normalize(eye - r.position);
    r.exponent = k;
    const ValGather g = gatherReference(r, weighted);
    const cv::Vec3f L = valRadiance(g.E, g.S, {0.6f, 0.6f, 0.6f}, cv::Vec3f::all(0.3f), k);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], L[c], 2e-3 * L[c] + 1e-6) << "pixel " << i << " channel " << c;
    ++checked;
  }
  EXPECT_GT(checked, 50);
}

TEST(GL, KinectValAloneDarkensRealPixelsAndRealValsOnlyInTheObjectsShadow) {
  auto ctx = makeContext();
  const double cube = 0.16;
  const cv::Vec3d centre(0.0, 0.0, 0.2);
  const TestScene s = makeScene(false, cube, centre);
  PipelineConfig cfg = testConfig(160, 120, 16, 256, "kinect-val");
  cfg.set("frame", "object_terms_scale", 1.0);  // each pixel's own terms, held to 1e-5 below
  LightingPipeline pipe = makePipeline(cfg, s);
  const std::vector<Val> original = roomVals();
  setRealVals(pipe, original);
  SceneLight sun = sunDown(10.0);
  sun.direction = {0.6, 0.0, -0.8};
  const double ambient = 0.1;  // W/m^2/sr: pi * 0.1 W/m^2 still reach the shadow
  pipe.run(topCamera(160, 120), {sun}, cv::Vec3d::all(ambient), nullptr);
  // Real VALs in the shadow reflect only the ambient: exitance x pi a / (E cos + pi a); the rest unchanged.
  const std::vector<Val> used = kval(pipe).downloadVals();
  ASSERT_EQ(used.size(), original.size() + kval(pipe).valStats().virtualVals);
  const double ratio = CV_PI * ambient / (8.0 + CV_PI * ambient);
  int dimmed = 0;
  for (size_t i = 0; i < original.size(); ++i) {
    const cv::Vec3d p(original[i].position);
    if (original[i].normal[2] < 0.5f) continue;  // the floor
    if (inShadow(p, sun.direction, centre, 0.5 * cube - 0.01)) {
      EXPECT_NEAR(used[i].flux[0], original[i].flux[0] * ratio, 1e-4 * original[i].flux[0]) << i;
      ++dimmed;
    } else if (!inShadow(p, sun.direction, centre, 0.5 * cube + 0.01)) {
      EXPECT_EQ(used[i].flux, original[i].flux) << i;
    }
  }
  EXPECT_GT(dimmed, 20);
  EXPECT_GE(kval(pipe).valStats().shadowedVals, static_cast<size_t>(dimmed));
  const cv::Mat shade = pipe.downloadShade(), pos = pipe.downloadGBuffer(0), nrm = pipe.downloadGBuffer(1);
  // Exact loss in the shadow: E cos(theta) albedo / pi with E cos = 8 W/m^2 on the grey floor, plus the
  // ambient the cube hides net of what it reflects of it, lit as the floor around is, and the sun it reflects
  // (the shading pass's, lighting/object_shadow.h) everywhere: the technique alone has no bounce of its own.
  const float lost = 8.0f * kFloorAlbedo[0] / static_cast<float>(CV_PI);
  Ambient sky;
  sky.uniform = cv::Vec3f::all(static_cast<float>(ambient));
  const std::vector<OccluderSphere> spheres{occluderSphere(s.objects[0])};
  int inside = 0, outside = 0, wrong = 0;
  for (int i = 0; i < static_cast<int>(shade.total()); ++i) {
    const cv::Vec4f v = shade.at<cv::Vec4f>(i), p = pos.at<cv::Vec4f>(i), n = nrm.at<cv::Vec4f>(i);
    if (p[3] < 0.5f || v[3] > 0.5f) continue;
    const cv::Vec3d pw(p[0], p[1], p[2]);
    // Shadow of a slightly smaller / larger box: the map's texels blur the exact edge.
    auto shadowed = [&](double h) { return inShadow(pw, sun.direction, centre, h); };
    const cv::Vec3f x(p[0], p[1], p[2]), nn(n[0], n[1], n[2]);
    const cv::Vec3f without(unshadowedIrradiance(sun, pw, cv::Vec3d(nn))),
        with = shadowed(0.5 * cube) ? cv::Vec3f(0, 0, 0) : without;
    // The ground under the cube's face turned towards x (lighting::facedGround), lit as x is by the sun's shadow.
    const FacedGround g = facedGround(x, nn, spheres);
    const cv::Vec3d gw(g.point);
    const cv::Vec3f groundWithout(unshadowedIrradiance(sun, gw, cv::Vec3d(nn))),
        groundWith = inShadow(gw, sun.direction, centre, 0.5 * cube) ? cv::Vec3f(0, 0, 0) : groundWithout;
    const cv::Vec3f lit = blendLit(litFraction(sky, x, nn, spheres, without, with),
                                   litFraction(sky, g.point, nn, spheres, groundWithout, groundWith), g.weight);
    const float hidden = (ambientShadow(sky, x, nn, spheres, lit)[0] - reflectedLight(x, nn, spheres, {sun})[0]) *
                         kFloorAlbedo[0] / static_cast<float>(CV_PI);
    if (shadowed(0.5 * cube - 0.01)) {
      ++inside;
      if (std::abs(v[0] + lost + hidden) > 1e-4f) ++wrong;
    } else if (!shadowed(0.5 * cube + 0.01)) {
      ++outside;
      if (std::abs(v[0] + hidden) > 1e-5f) ++wrong;
    }
  }
  EXPECT_GT(inside, 100);
  EXPECT_GT(outside, 5000);
  EXPECT_EQ(wrong, 0);
}

TEST(GL, KinectValBuildsItsValsOnTheGpuAsTheCppReferenceDoes) {
  // The frame path builds the VAL set on the GPU (val_rsm.comp, val_dim.comp, val_weights.comp) and reads
  // nothing back. The same set from the downloaded RSM and shadow maps by the C++ reference (valsFromRsm,
  // dimShadowedVals, setValWeights): same VALs in the same order, the same ones dimmed.
  auto ctx = makeContext();
  const double cube = 0.16;
  const cv::Vec3d centre(0.0, 0.0, 0.2);
  SceneLight sun = sunDown(10.0);
  sun.direction = cv::normalize(cv::Vec3d(0.6, 0.1, -0.8));
  SceneLight lamp;
  lamp.type = LightType::Point;
  lamp.position = {-0.4, 0.2, 0.9};
  lamp.intensity = {3.0, 2.5, 2.0};
  for (const SceneLight& light : {sun, lamp})
    for (int stride : {1, 2, 3}) {
      const TestScene s = makeScene(false, cube, centre);
      PipelineConfig cfg = testConfig(160, 120, 16, 128, "kinect-val");
      cfg.set("val", "rsm_stride", stride);
      LightingPipeline pipe = makePipeline(cfg, s);
      const std::vector<Val> real = roomVals();
      setRealVals(pipe, real);
      const cv::Vec3d ambient = cv::Vec3d::all(0.1);
      pipe.run(topCamera(160, 120), {light}, ambient, nullptr);
      const KinectValTechnique& k = kval(pipe);
      const std::vector<Val> gpu = k.downloadVals();

      std::vector<Val> ref = real;
      const size_t dimmed = dimShadowedVals(
          ref, {{light, pipe.frame().lightViews().at(0), pipe.frame().downloadShadowTexels(0)}}, ambient);
      const std::vector<Val> virt = valsFromRsm(pipe.downloadRsm(true), light, stride);
      ref.insert(ref.end(), virt.begin(), virt.end());
      setValWeights(ref);

      const std::string at =
          (light.type == LightType::Point ? "point light, stride " : "sun, stride ") + std::to_string(stride);
      ASSERT_EQ(gpu.size(), ref.size()) << at;
      EXPECT_GT(virt.size(), 20u) << at;  // the cube's lit texels
      EXPECT_GT(dimmed, 20u) << at;       // floor VALs in its shadow
      const KinectValTechnique::Stats st = k.valStats();
      EXPECT_EQ(st.virtualVals, virt.size()) << at;
      EXPECT_EQ(st.shadowedVals, dimmed) << at;
      const auto near = [](float a, float b) {
        return std::abs(a - b) <= 1e-5f * std::max(std::abs(a), std::abs(b)) + 1e-12f;
      };
      int wrong = 0;
      for (size_t i = 0; i < ref.size(); ++i) {
        const Val &g = gpu[i], &r = ref[i];
        bool same =
            g.position == r.position && g.normal == r.normal && near(g.area, r.area) && near(g.weight, r.weight);
        for (int c = 0; c < 3; ++c) same = same && near(g.flux[c], r.flux[c]);
        if (!same && ++wrong <= 3)
          ADD_FAILURE() << at << ", VAL " << i << (i < real.size() ? " (real)" : " (virtual)") << ": gpu area "
                        << g.area << " flux " << g.flux << " weight " << g.weight << ", reference area " << r.area
                        << " flux " << r.flux << " weight " << r.weight;
      }
      EXPECT_EQ(wrong, 0) << at;
    }
}

TEST(GL, DlpvPlusKinectValKeepsDlpvsRealPixelsAndReplacesTheObjectsBounce) {
  auto ctx = makeContext();
  const TestScene s = sphereScene({-0.3, 0.0, 0.12}, 0.1);
  SceneLight sun = sunDown(10.0);
  sun.direction = {-0.6, 0.0, -0.8};  // from +x: the wall behind the sphere does not shade it
  auto render = [&](const std::string& t) {
    PipelineConfig cfg = valConfig(t, 512, false, true);
    LightingPipeline pipe = makePipeline(cfg, s);
    setRealVals(pipe, roomVals());
    pipe.run(sideCamera(), {sun}, {0, 0, 0}, nullptr);
    const bool hasVal = pipe.technique("kinect-val") != nullptr;
    return std::pair{pipe.downloadShade(), hasVal ? kval(pipe).valStats() : KinectValTechnique::Stats{}};
  };
  const auto [dlpv, st0] = render("dlpv");
  const auto [both, st] = render("dlpv+kinect-val");
  EXPECT_EQ(st.receivers, 512u);
  EXPECT_EQ(st.realVals, roomVals().size());
  EXPECT_GT(st.virtualVals, 10u);  // the sphere's lit texels of the RSM
  int real = 0, virt = 0, differ = 0;
  for (int i = 0; i < static_cast<int>(dlpv.total()); ++i) {
    const cv::Vec4f a = dlpv.at<cv::Vec4f>(i), b = both.at<cv::Vec4f>(i);
    ASSERT_EQ(a[3], b[3]);
    if (a[3] > 0.5f) {
      ++virt;
      differ += std::abs(lum(a) - lum(b)) > 1e-3f;
    } else {
      ++real;
      for (int c = 0; c < 3; ++c) ASSERT_EQ(a[c], b[c]) << "real pixel " << i;
    }
  }
  EXPECT_GT(real, 5000);
  EXPECT_GT(differ, virt / 2);
}

TEST(GL, KinectValExtremesStayFiniteAndBounded) {
  auto ctx = makeContext();
  // A VAL touching the sphere's surface with 1e6 W, denormal and zero VALs, and no VALs at all.
  const cv::Vec3d at(-0.3, 0.0, 0.12);
  const double r = 0.1;
  for (bool bruteForce : {false, true})
    for (int variant = 0; variant < 4; ++variant) {
      const TestScene s = sphereScene(at, r, 0.01f, 0.5f);  // k = 1e4 (clamped)
      std::vector<Val> vals;
      if (variant == 0 || variant == 1) {
        Val v;
        v.position = cv::Vec3f(at) + cv::Vec3f(0, 0, -static_cast<float>(r));  // on the sphere's bottom
        v.normal = {0, 0, 1};
        v.area = variant == 0 ? 1e-4f : 1e-30f;
        v.flux = cv::Vec3f::all(variant == 0 ? 1e6f : 1e-38f);
        vals.push_back(v);
      } else if (variant == 2) {
        vals = roomVals();
        for (auto& v : vals) v.flux = {0, 0, 0};
      }
      const cv::Mat shade = bounceOnly(valConfig("kinect-val", 256, bruteForce, true), s, vals);
      for (int i = 0; i < static_cast<int>(shade.total()); ++i) {
        const cv::Vec4f v = shade.at<cv::Vec4f>(i);
        for (int c = 0; c < 3; ++c) {
          ASSERT_TRUE(std::isfinite(v[c])) << "variant " << variant << " brute " << bruteForce;
          ASSERT_GE(v[c], 0.0f);
          // Bounded by the exitance the VAL can deliver: phi / a (1e10) times (albedo/pi + specular c_k).
          ASSERT_LE(v[c], 1e10f * (0.6f / CV_PI + 0.5f * phongNorm(kMaxPhongExponent)) * 1.01f);
          if (variant >= 2) {
            ASSERT_EQ(v[c], 0.0f) << "nothing lights the object";
          }
        }
      }
    }
}

TEST(GL, KinectValPixelPassMatchesTheCppInterpolationAndEvaluation) {
  // A virtual quad (two triangles) facing the camera: each pixel's VPL pair is the barycentric blend of its
  // triangle's per-vertex pairs (eq. 13 on the sparse points' VPLs), evaluated at the pixel (eq. 10).
  auto ctx = makeContext();
  TestScene s = makeScene(true, 0.0, {0, 0, 0});
  VirtualObject o;
  o.mesh.positions = {{-0.15f, -0.15f, 0.f}, {0.15f, -0.15f, 0.f}, {0.15f, 0.15f, 0.f}, {-0.15f, 0.15f, 0.f}};
  o.mesh.normals.assign(4, cv::Vec3f(0.3f, 0.f, 0.954f));
  for (auto& n : o.mesh.normals) n = cv::normalize(n);
  o.mesh.indices = {0, 1, 2, 0, 2, 3};
  o.mesh.computeBounds();
  o.material.albedo = {0.6f, 0.6f, 0.6f};
  o.material.roughness = 0.4f;
  o.material.specular = 0.3f;
  o.T_marker_object = capture::makePose(cv::Matx33d::eye(), {-0.2, 0.0, 0.3});
  s.objects.push_back(o);
  PipelineConfig cfg = valConfig("kinect-val", 64, false, true);
  LightingPipeline pipe = makePipeline(cfg, s);
  setRealVals(pipe, roomVals());
  CameraView cam;
  cam.intrinsics = {128, 96, 120, 120, 63.5, 47.5};
  cam.T_world_camera = capture::lookAtPose({-0.1, -0.2, 1.2}, {-0.2, 0.0, 0.3});
  pipe.run(cam, {}, {0, 0, 0}, nullptr);
  const cv::Mat shade = pipe.downloadShade(), pos = pipe.downloadGBuffer(0);
  const auto vpls = kval(pipe).downloadSparseVpls();
  SparsePoints points = sampleSparsePoints(o.mesh, 64);
  const VertexWeights w = vertexWeights(o.mesh, points);
  ASSERT_EQ(vpls.size(), points.positions.size());
  std::vector<SparseVpl> perVertex;
  for (size_t v = 0; v < 4; ++v) perVertex.push_back(interpolateVpl(w, v, vpls));
  const cv::Vec3f eye(capture::translationOf(cam.T_world_camera)), offset(-0.2f, 0.f, 0.3f);
  const float k = phongExponent(0.4f);
  int checked = 0;
  for (int i = 0; i < static_cast<int>(shade.total()); ++i) {
    const cv::Vec4f v = shade.at<cv::Vec4f>(i);
    if (v[3] < 0.5f) continue;
    const cv::Vec4f p4 = pos.at<cv::Vec4f>(i);
    const cv::Vec3f x(p4[0], p4[1], p4[2]), m = x - offset;  // model frame (translation only)
    // Which triangle, and the barycentrics in the quad's plane (z = 0 in the model frame).
    const bool first = m[0] >= m[1];  // triangle 0-1-2 lies below the diagonal x = y
    const int a = 0, b = first ? 1 : 2, c = first ? 2 : 3;
    const cv::Vec3f pa = o.mesh.positions[a], pb = o.mesh.positions[b], pc = o.mesh.positions[c];
    const float area = (pb - pa).cross(pc - pa)[2];
    const float wb = (m - pa).cross(pc - pa)[2] / area, wc = (pb - pa).cross(m - pa)[2] / area, wa = 1 - wb - wc;
    if (std::min({wa, wb, wc}) < 0.02f) continue;  // keep off the diagonal and the edges
    SparseVpl blend;
    blend.Ld = wa * perVertex[a].Ld + wb * perVertex[b].Ld + wc * perVertex[c].Ld;
    blend.ld = wa * perVertex[a].ld + wb * perVertex[b].ld + wc * perVertex[c].ld;
    blend.Ls = wa * perVertex[a].Ls + wb * perVertex[b].Ls + wc * perVertex[c].Ls;
    blend.ls = wa * perVertex[a].ls + wb * perVertex[b].ls + wc * perVertex[c].ls;
    Receiver r;
    r.position = x;
    r.view = cv::normalize(eye - x);
    r.normal = o.mesh.normals[0];
    if (r.normal.dot(r.view) < 0) r.normal = -r.normal;
    r.exponent = k;
    cv::Vec3f E, S;
    evaluateVpl(blend, r, E, S);
    const cv::Vec3f L = valRadiance(E, S, o.material.albedo, cv::Vec3f::all(o.material.specular), k);
    for (int ch = 0; ch < 3; ++ch)
      EXPECT_NEAR(v[ch], L[ch], 2e-3f * L[ch] + 1e-6f) << "pixel " << i << " channel " << ch;
    ++checked;
  }
  EXPECT_GT(checked, 300);
}

TEST(GL, KinectValAssemblesItsValsOnceWhileOnlyTheCameraMoves) {
  // The VAL set (real VALs up, dimmed by the objects' shadows, the RSM's virtual VALs, weights) depends on the
  // world, not the view: with the room, the objects and the lights still, a moving camera only gathers and
  // shades again. A new light assembles it anew.
  auto ctx = makeContext();
  const TestScene s = sphereScene({-0.3, 0.0, 0.12}, 0.1, 0.3f, 0.3f);
  LightingPipeline pipe = makePipeline(valConfig("kinect-val", 256, false), s);
  setRealVals(pipe, roomVals());
  auto stages = [&](const CameraView& cam, const std::vector<SceneLight>& lights) {
    gl::Profiler profiler;
    pipe.run(cam, lights, {0, 0, 0}, &profiler);
    std::set<std::string> names;
    for (const auto& [name, t] : profiler.resolve()) names.insert(name);
    return names;
  };
  CameraView cam = sideCamera();
  const std::vector<SceneLight> lamp = {pointAbove()};
  EXPECT_TRUE(stages(cam, lamp).count("val.upload"));
  cam.T_world_camera = capture::lookAtPose({0.2, -0.9, 0.7}, {0, 0, 0.1});
  const auto moved = stages(cam, lamp);
  EXPECT_TRUE(moved.count("val.gather"));
  EXPECT_FALSE(moved.count("val.upload"));
  EXPECT_TRUE(stages(cam, {sunDown(8.0)}).count("val.upload"));
}
