// Precomputed illuminance composition on the lighting pipeline (llvmpipe): the GPU's surfel flux, caches and
// read-out against the C++ reference (pic.h), chroma compression on the GPU, a white cube next to a red
// wall receiving red bounce, and a moving light rerunning only the runtime stages.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>

#include "lighting/pipeline.h"
#include "lighting/techniques/pic/pic.h"
#include "lighting/techniques/pic/pic_technique.h"
#include "reconstruction/mesh_rays.h"
#include "tests/lighting/test_scene.h"

using namespace mrgi;
using namespace mrgi::lighting;
using namespace mrgi::test;

namespace {

PipelineConfig picConfig(int chroma, bool rgb9e5, int receivers = 64) {
  PipelineConfig cfg = testConfig(96, 72, 16, 64, "pic");
  cfg.set("pic", "surfels", 1024);
  cfg.set("pic", "bands", 3);
  cfg.set("pic", "chroma_bands", chroma);
  cfg.set("pic", "links", 64);
  cfg.set("pic", "grid", 4);
  cfg.set("pic", "receivers", receivers);
  cfg.set("pic", "bounces", 1);
  cfg.set("pic", "rgb9e5", rgb9e5 ? 1 : 0);
  return cfg;
}

const PicTechnique& picOf(const LightingPipeline& pipe) {
  return dynamic_cast<const PicTechnique&>(*pipe.technique("pic"));
}

pic::Ambient ambientOf(const LightingPipeline& pipe) {
  pic::Ambient a;
  a.uniform = cv::Vec3f(pipe.frame().ambient());
  for (size_t k = 0; k < 9; ++k) a.sh[k] = cv::Vec3f(pipe.frame().ambientSh()[k]);
  return a;
}

float peakOf(const std::vector<cv::Vec3f>& v) {
  float p = 0;
  for (const cv::Vec3f& x : v) p = std::max({p, std::abs(x[0]), std::abs(x[1]), std::abs(x[2])});
  return p;
}

}  // namespace

TEST(GL, PicGpuMatchesTheCppReference) {
  auto ctx = makeContext();
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  for (const auto& [chroma, packed] : {std::pair{0, false}, std::pair{1, true}}) {
    LightingPipeline pipe = makePipeline(picConfig(chroma, packed), s);
    pipe.setAmbientSh({cv::Vec3d(0.05, 0.05, 0.05), {}, cv::Vec3d(0.03, 0.02, 0.01)});
    pipe.run(wallCamera(), wallLamp(), {0.1, 0.1, 0.12}, nullptr);
    const PicTechnique& t = picOf(pipe);
    const int bands = t.knobs().bands, cb = t.chromaBands();
    ASSERT_EQ(t.surfels().size(), 1024u);
    ASSERT_EQ(t.caches().caches(), 64u);

    // The reference's run: the surfels lit without bounce, the receivers gathered, the surfels lit again with
    // their receivers' bounce, the caches gathered (chroma compressed as the GPU stores it).
    pic::SurfaceMesh mesh;
    for (const MeshVertex& v : s.vertices) mesh.positions.push_back(v.position);
    mesh.indices = s.indices;
    const reconstruction::MeshRays rays(mesh.positions, mesh.indices);
    const pic::Ambient ambient = ambientOf(pipe);
    const auto vis = pic::surfelVisibility(t.surfels(), wallLamp(), rays);
    const auto flux0 = pic::pullUp(t.hierarchy(), pic::surfelFlux(t.surfels(), wallLamp(), vis, ambient));
    const auto recv = pic::compressChroma(pic::gatherCaches(t.receiverLinks(), flux0, ambient), bands, cb);
    const auto bounce = pic::bounceIrradiance(t.surfels(), t.receivers(), recv, bands);
    const auto flux1 = pic::pullUp(t.hierarchy(), pic::surfelFlux(t.surfels(), wallLamp(), vis, ambient, bounce));
    const auto caches = pic::compressChroma(pic::gatherCaches(t.caches(), flux1, ambient), bands, cb);

    // Flux: float or RGB9E5 (each node within 1 % of its largest channel: rounding compounds up the tree).
    const auto gpuFlux = t.downloadFlux();
    ASSERT_EQ(gpuFlux.size(), flux1.size());
    for (size_t k = 0; k < flux1.size(); ++k) {
      const float m = std::max({flux1[k][0], flux1[k][1], flux1[k][2]});
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(gpuFlux[k][c], flux1[k][c], (packed ? 0.01f : 1e-4f) * m + 1e-7f) << "node " << k;
    }
    // Caches within 1 % of the largest coefficient (0.1 % unpacked).
    const std::vector<float> stored = t.downloadCaches(false);
    const float peak = peakOf(caches);
    ASSERT_GT(peak, 0.0f);
    const auto b2 = static_cast<size_t>(bands * bands);
    for (size_t c = 0; c < t.caches().caches(); ++c) {
      const auto gpu = t.decodeCache(stored, c);
      for (size_t i = 0; i < b2; ++i)
        for (int ch = 0; ch < 3; ++ch)
          ASSERT_NEAR(gpu[i][ch], caches[c * b2 + i][ch], (packed ? 0.01f : 1e-3f) * peak)
              << "cache " << c << " coefficient " << i;
    }
    // Read-out: the object's pixels' irradiance from the interpolated caches about their normals.
    const cv::Mat pos = download4(pipe.frame().gPosition()), nrm = download4(pipe.frame().gNormal());
    const cv::Mat alb = download4(pipe.frame().gAlbedo()), out = download4(*t.outputs().virtualIrradiance);
    int pixels = 0;
    double worst = 0, scale = 0;
    std::vector<cv::Vec3f> gpuSh(stored.size() / (b2 + 2 * static_cast<size_t>(cb * cb)) * b2);
    for (size_t c = 0; c < t.caches().caches(); ++c) {
      const auto g = t.decodeCache(stored, c);
      std::copy(g.begin(), g.end(), gpuSh.begin() + static_cast<std::ptrdiff_t>(c * b2));
    }
    for (int y = 0; y < pos.rows; ++y)
      for (int x = 0; x < pos.cols; ++x) {
        const cv::Vec4f p = pos.at<cv::Vec4f>(y, x), n = nrm.at<cv::Vec4f>(y, x);
        if (p[3] < 0.5f || alb.at<cv::Vec4f>(y, x)[3] < 0.5f) continue;
        const auto sh =
            pic::interpolateGrid(gpuSh, t.caches(), t.gridCentre(), t.gridSide(), t.knobs().grid, {p[0], p[1], p[2]});
        const cv::Vec3f e = pic::shIrradiance(sh.data(), bands, cv::normalize(cv::Vec3f(n[0], n[1], n[2])));
        const cv::Vec4f g = out.at<cv::Vec4f>(y, x);
        for (int ch = 0; ch < 3; ++ch)
          worst = std::max(worst, std::abs(double(g[ch]) - e[ch])), scale = std::max(scale, std::abs(double(e[ch])));
        ++pixels;
      }
    EXPECT_GT(pixels, 100);
    EXPECT_LT(worst, 1e-3 * scale + 1e-6) << "of " << scale;
  }
}

TEST(GL, PicWhiteCubeNextToARedWallReceivesRedBounce) {
  auto ctx = makeContext();
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  LightingPipeline pipe = makePipeline(picConfig(0, true), s);
  pipe.run(wallCamera(), wallLamp(), {0, 0, 0}, nullptr);
  const PicTechnique& t = picOf(pipe);
  // The GPU's caches read as the object's pixels read them, at the middle of the cube's face towards the
  // wall (x = -0.42) and of its face away from it (x = -0.30).
  const std::vector<float> stored = t.downloadCaches(false);
  const auto b2 = static_cast<size_t>(t.knobs().bands * t.knobs().bands);
  std::vector<cv::Vec3f> sh;
  for (size_t c = 0; c < t.caches().caches(); ++c) {
    const auto g = t.decodeCache(stored, c);
    sh.insert(sh.end(), g.begin(), g.end());
  }
  ASSERT_EQ(sh.size(), t.caches().caches() * b2);
  const auto irradiance = [&](const cv::Vec3f& x, const cv::Vec3f& n) {
    const auto at = pic::interpolateGrid(sh, t.caches(), t.gridCentre(), t.gridSide(), t.knobs().grid, x);
    return pic::shIrradiance(at.data(), t.knobs().bands, n);
  };
  const cv::Vec3f towards = irradiance({-0.42f, 0, 0.06f}, {-1, 0, 0}),
                  away = irradiance({-0.30f, 0, 0.06f}, {1, 0, 0});
  ASSERT_GT(towards[0], 0.0f);
  EXPECT_GT(towards[0], 2.0f * towards[1]) << towards;  // red bounce from the wall (albedo 0.8 / 0.1)
  EXPECT_LT(away[0], 1.3f * away[1]) << away;           // the grey floor's, away from it
}

TEST(GL, PicMovingLightRerunsOnlyTheRuntimeStages) {
  auto ctx = makeContext();
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  LightingPipeline pipe = makePipeline(picConfig(0, true), s);
  gl::Profiler profiler;
  std::vector<SceneLight> lamp = wallLamp();
  pipe.run(wallCamera(), lamp, {0, 0, 0}, &profiler);
  const PicTechnique& t = picOf(pipe);
  EXPECT_EQ(t.precomputes(), 1);
  const std::vector<float> before = t.downloadCaches(false);
  for (int k = 1; k <= 3; ++k) {
    lamp[0].position += cv::Vec3d(0.1, 0.05, 0);
    pipe.run(wallCamera(), lamp, {0, 0, 0}, &profiler);
  }
  EXPECT_EQ(t.precomputes(), 1);  // the surfels, hierarchy and links stay
  const std::vector<float> after = t.downloadCaches(false);
  double change = 0;
  for (size_t i = 0; i < before.size(); ++i) change += std::abs(after[i] - before[i]);
  EXPECT_GT(change, 0.0);  // relit
  // A new real mesh (a surface scanned) precomputes again.
  TestScene grown = s;
  addQuad(grown.vertices, grown.indices, {-1, 1, 0}, {2, 0, 0}, {0, 0, 1}, kFloorAlbedo, 4);
  pipe.setRealMesh(grown.vertices, grown.indices);
  pipe.run(wallCamera(), lamp, {0, 0, 0}, &profiler);
  EXPECT_EQ(t.precomputes(), 2);
}

TEST(GL, PicKeepsItsPrecomputeInTheCacheFolder) {
  namespace fs = std::filesystem;
  auto ctx = makeContext();
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  const fs::path dir = fs::temp_directory_path() / ("mrgi_pic_cache_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::map<std::string, std::vector<double>> reported;
  const auto run = [&](int surfels) {
    PipelineConfig cfg = picConfig(0, true);
    cfg.set("pic", "surfels", surfels);
    cfg.cacheDir = dir.string();
    cfg.progress = [&](const std::string& what, double f) { reported[what].push_back(f); };
    auto pipe = std::make_unique<LightingPipeline>(cfg, s.objects);
    pipe->setRealMesh(s.vertices, s.indices);
    pipe->run(wallCamera(), wallLamp(), {0.1, 0.1, 0.1}, nullptr);
    return pipe;
  };
  const auto first = run(1024);
  EXPECT_EQ(picOf(*first).precomputes(), 1);
  EXPECT_EQ(picOf(*first).cacheLoads(), 0);
  // The precompute's progress: from 0 to 1, never backwards; the grid's links too.
  ASSERT_FALSE(reported["pic precompute"].empty());
  EXPECT_EQ(reported["pic precompute"].front(), 0.0);
  EXPECT_EQ(reported["pic precompute"].back(), 1.0);
  EXPECT_TRUE(std::is_sorted(reported["pic precompute"].begin(), reported["pic precompute"].end()));
  EXPECT_EQ(reported["pic caches"].back(), 1.0);
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) files.push_back(e.path());
  ASSERT_EQ(files.size(), 2u);  // the mesh's part and the grid's, no temporary left
  const std::vector<float> want = picOf(*first).downloadCaches(false);

  // A fresh pipeline over the same room reads both back: no precompute, the same caches to the bit.
  reported.clear();
  const auto second = run(1024);
  EXPECT_EQ(picOf(*second).precomputes(), 0);
  EXPECT_EQ(picOf(*second).cacheLoads(), 2);
  EXPECT_TRUE(reported["pic precompute"].empty());
  EXPECT_EQ(picOf(*second).downloadCaches(false), want);

  // A damaged file is computed again (and replaced); other knobs keep files of their own.
  for (const fs::path& f : files)
    if (f.filename().string().rfind("pic_mesh_", 0) == 0) fs::resize_file(f, fs::file_size(f) / 2);
  const auto third = run(1024);
  EXPECT_EQ(picOf(*third).precomputes(), 1);
  EXPECT_EQ(picOf(*third).downloadCaches(false), want);
  EXPECT_EQ(picOf(*run(1024)).cacheLoads(), 2);
  EXPECT_EQ(picOf(*run(512)).precomputes(), 1);
  size_t count = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++count;
  EXPECT_EQ(count, 4u);
  fs::remove_all(dir);
}
