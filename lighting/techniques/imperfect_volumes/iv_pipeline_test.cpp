// Imperfect volumes inside the lighting pipeline (llvmpipe): the GPU passes against the C++ reference
// (voxelisation, gather with bounces, reconstruction per pixel), the ambient the object hides from the floor,
// and the red wall's bounce on a white object.
#include <gtest/gtest.h>

#include <cmath>

#include "lighting/pipeline.h"
#include "lighting/techniques/imperfect_volumes/imperfect_volumes.h"
#include "lighting/techniques/imperfect_volumes/iv.h"
#include "tests/lighting/test_scene.h"

using namespace mrgi;
using namespace mrgi::lighting;
using namespace mrgi::test;

namespace {

PipelineConfig ivConfig(const std::string& technique, int resolution, int bounces, int bands = 3) {
  PipelineConfig cfg = testConfig(96, 72, 16, 128, technique);
  cfg.set("iv", "resolution", resolution);
  cfg.set("iv", "bounces", bounces);
  cfg.set("iv", "bands", bands);
  cfg.set("iv", "rays", 64);
  cfg.set("iv", "range", 0.3);
  return cfg;
}

const ImperfectVolumesTechnique& ivOf(const LightingPipeline& pipe) {
  return dynamic_cast<const ImperfectVolumesTechnique&>(*pipe.technique("imperfect-volumes"));
}

}  // namespace

TEST(GL, ImperfectVolumesGpuPassesMatchTheCppReference) {
  auto ctx = makeContext();
  // A white cube 12 cm next to the red wall on the grey floor, a lamp, an ambient with a directional part.
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  for (int bounces : {1, 2}) {
    // One bounce: the object reads the voxels' SH; two: its pixels cast their own 64 rays (object_rays).
    const int objectRays = bounces == 1 ? 0 : 64;
    PipelineConfig cfg = ivConfig("imperfect-volumes", 16, bounces);
    cfg.set("iv", "object_rays", objectRays);
    LightingPipeline pipe = makePipeline(cfg, s);
    pipe.setAmbientSh({cv::Vec3d(0.05, 0.05, 0.05), {}, cv::Vec3d(0.03, 0.02, 0.01)});
    pipe.run(wallCamera(), wallLamp(), {0.1, 0.1, 0.12}, nullptr);
    const ImperfectVolumesTechnique& t = ivOf(pipe);
    ASSERT_TRUE(t.grid());
    const iv::Grid g = *t.grid();
    const iv::Volume vol = t.downloadVolume();

    // Voxelisation: the occupancy the CPU points give.
    const IvPoints pts = ivScenePoints(pipe.frame(), g, t.knobs().points);
    int occupied = 0, virtualVoxels = 0;
    for (size_t v = 0; v < g.count(); ++v) {
      const bool any = pts.offsets[v + 1] > pts.offsets[v];
      ASSERT_EQ(vol.occupancy[v] != iv::kEmpty, any) << v;
      occupied += any;
      virtualVoxels += (vol.occupancy[v] & iv::kVirtual) != 0;
    }
    EXPECT_GT(occupied, 100);
    EXPECT_GT(virtualVoxels, 10);
    // A floor voxel away from the cube and the wall, lit unshadowed: albedo / pi times the lamp's and the ambient's
    // irradiance.
    const cv::Vec3d floorPoint(-0.2, -0.18, 0.001);
    cv::Vec3i c;
    ASSERT_TRUE(g.voxelOf(floorPoint, c));
    // The floor lies on a voxel boundary: its points fall on either side of it.
    if (vol.exitantMu[g.index(c[0], c[1], c[2])][3] == 0.f) --c[2];
    const size_t fv = g.index(c[0], c[1], c[2]);
    ASSERT_GT(vol.exitantMu[fv][3], 0.f);
    const cv::Vec3f at(vol.normalMu[fv][0], vol.normalMu[fv][1], vol.normalMu[fv][2]);
    EXPECT_GT(at[2], 0.99f * static_cast<float>(cv::norm(at)));
    const cv::Vec3d centre = g.centre(c[0], c[1], c[2]);
    const cv::Vec3d toLamp = wallLamp()[0].position - cv::Vec3d(centre[0], centre[1], 0.0);
    // The lamp, and the ambient seen from a floor facing up: pi 0.1 + (pi y00 0.05 + (2 pi / 3) y10 0.03).
    const double ambientUp = CV_PI * 0.1 + CV_PI * 0.282094792 * 0.05 + 2.0 * CV_PI / 3.0 * 0.488602512 * 0.03;
    const double E = 2.0 * toLamp[2] / std::pow(cv::norm(toLamp), 3.0) + ambientUp;
    EXPECT_NEAR(vol.exitantMu[fv][0], 0.5 / CV_PI * E, 0.02 * 0.5 / CV_PI * E);
    EXPECT_EQ(vol.exitantRho[fv][0], vol.exitantMu[fv][0]) << "the cube does not shadow it";

    // Gather (and the further bounce): the GPU's incident SH against the reference on the GPU's voxels.
    iv::Options o;
    o.rays = 64;
    o.bands = 3;
    o.range = 0.3;
    o.bounces = bounces;
    iv::Ambient amb;
    amb.uniform = {0.1f, 0.1f, 0.12f};
    amb.sh[0] = {0.05f, 0.05f, 0.05f};
    amb.sh[2] = {0.03f, 0.02f, 0.01f};
    // Rho's incident light as the technique hands it out: with the objects' cone sampled from every voxel.
    const auto gatherOf = [&](bool rho) {
      iv::Incident in = iv::gather(vol, rho, o, amb);
      if (rho) {
        EXPECT_TRUE(t.coneBound());
        const std::vector<float> add =
            iv::coneCorrection(vol, in.computed, o, amb, iv::rayDirections(o.rays), *t.coneBound(), t.coneRays());
        for (size_t q = 0; q < in.sh.size(); ++q) in.sh[q] += add[q];
      }
      return in;
    };
    for (bool rho : {true, false}) {
      const iv::Incident gpu = t.downloadIncident(rho);
      const iv::Incident cpu = gatherOf(rho);
      ASSERT_EQ(gpu.computed, cpu.computed);
      double diff = 0, ref = 0;
      for (size_t k = 0; k < cpu.sh.size(); ++k) {
        diff += std::abs(gpu.sh[k] - cpu.sh[k]);
        ref += std::abs(cpu.sh[k]);
      }
      EXPECT_LT(diff, 1e-3 * ref) << (rho ? "rho" : "mu") << ", " << bounces << " bounces";
      int occlusionOff = 0;
      for (size_t v = 0; v < g.count(); ++v) occlusionOff += std::abs(gpu.occlusion[v] - cpu.occlusion[v]) > 1e-6f;
      EXPECT_LE(occlusionOff, static_cast<int>(g.count() / 1000)) << "rays that hit on one side only (float steps)";
    }

    // Reconstruction per pixel: the real-pixel delta the GPU hands out against the reference at the
    // G-buffer's points.
    const cv::Mat pos = pipe.frame().downloadGBuffer(0), nrm = pipe.frame().downloadGBuffer(1),
                  alb = pipe.frame().downloadGBuffer(2);
    const cv::Mat delta = download4(*t.outputs().realDelta), virt = download4(*t.outputs().virtualIrradiance);
    const iv::Incident rhoIn = gatherOf(true), muIn = gatherOf(false);
    const std::vector<cv::Vec3f> objectDirs = iv::rayDirections(std::max(objectRays, 1));
    // The ambient the cube hides from the real surfaces, GPU against the reference.
    const std::vector<cv::Vec3f> hidden = iv::ambientHiddenByObjects(vol, o, amb, iv::rayDirections(o.rays));
    if (objectRays > 0) {
      const std::vector<cv::Vec3f> gpuHidden = t.downloadHidden();
      ASSERT_EQ(gpuHidden.size(), hidden.size());
      int hiding = 0, off = 0;
      for (size_t v = 0; v < hidden.size(); ++v) {
        hiding += hidden[v][0] > 0.f;
        off += std::abs(gpuHidden[v][0] - hidden[v][0]) > 1e-4f + 1e-3f * hidden[v][0];
      }
      EXPECT_GT(hiding, 10) << "floor and wall voxels next to the cube";
      EXPECT_LE(off, static_cast<int>(g.count() / 1000));
    }
    int checked = 0, good = 0, virtualChecked = 0, virtualGood = 0, virtualHit = 0, outerHit = 0;
    // The outer volume the object's rays go on through (object rays only): its occupancy the CPU's points.
    const iv::Volume outerVol = t.downloadOuterVolume();
    if (objectRays > 0) {
      ASSERT_TRUE(t.outerGrid());
      const IvPoints op = ivOuterPoints(pipe.frame(), g, *t.outerGrid(), t.knobs().points);
      int outerOccupied = 0;
      for (size_t v = 0; v < t.outerGrid()->count(); ++v) {
        ASSERT_EQ(outerVol.occupancy[v] == iv::kReal, op.offsets[v + 1] > op.offsets[v]) << v;
        outerOccupied += outerVol.occupancy[v] == iv::kReal;
      }
      EXPECT_GT(outerOccupied, 100);
    } else {
      EXPECT_FALSE(t.outerGrid());
    }
    for (int i = 0; i < static_cast<int>(pos.total()); ++i) {
      const cv::Vec4f p = pos.at<cv::Vec4f>(i), n = nrm.at<cv::Vec4f>(i);
      if (p[3] < 0.5f) continue;
      const cv::Vec3f x(p[0], p[1], p[2]), nn(n[0], n[1], n[2]);
      const cv::Vec3f eRho = iv::irradiance(vol, rhoIn, x, nn), eMu = iv::irradiance(vol, muIn, x, nn);
      if (alb.at<cv::Vec4f>(i)[3] > 0.5f) {
        // The object: what the real surfaces hide and send (mu: its own voxels are not in the way).
        const cv::Vec3f expected =
            objectRays > 0 ? iv::pointGather(vol, false, muIn, o, amb, objectDirs, x, nn, &hidden, &outerVol)
                           : eMu - iv::unoccludedAmbient(amb, nn);
        if (objectRays > 0)
          outerHit += expected != iv::pointGather(vol, false, muIn, o, amb, objectDirs, x, nn, &hidden);
        virtualHit += objectRays > 0 && expected != cv::Vec3f(0, 0, 0);
        const cv::Vec4f got = virt.at<cv::Vec4f>(i);
        ++virtualChecked;
        virtualGood += std::abs(got[0] - expected[0]) <= 1e-3f + 2e-3f * std::abs(expected[0]);
        continue;
      }
      const cv::Vec3f expected = eRho - eMu;
      const cv::Vec4f got = delta.at<cv::Vec4f>(i);
      ++checked;
      good += std::abs(got[0] - expected[0]) <= 1e-4f + 2e-3f * std::abs(expected[0]);
    }
    EXPECT_GT(checked, 2000);
    EXPECT_GT(good, static_cast<int>(0.995 * checked)) << good << " of " << checked;
    EXPECT_GT(virtualChecked, 100);
    EXPECT_GT(virtualGood, static_cast<int>(0.99 * virtualChecked)) << virtualGood << " of " << virtualChecked;
    if (objectRays > 0) {
      EXPECT_GT(virtualHit, virtualChecked / 2) << "the object's rays reach the floor and the wall";
      EXPECT_GT(outerHit, 10) << "rays that go on past the grid";
    }
  }
}

TEST(GL, ImperfectVolumesLeaveTheAmbientTheObjectHidesToTheShadingPassAndTakeTheWallsRed) {
  auto ctx = makeContext();
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  const PipelineConfig cfg = ivConfig("imperfect-volumes", 32, 1);
  LightingPipeline pipe = makePipeline(cfg, s);
  // Ambient only: the floor next to the cube loses what the cube hides of the sky, in the frame's delta (the
  // shading pass's); the volumes' own delta holds none of it (in rho the cube hides nothing, and with no
  // light it reflects none): exactly 0.
  pipe.run(wallCamera(), {}, {0.2, 0.2, 0.2}, nullptr);
  const iv::Grid g = *ivOf(pipe).grid();
  const cv::Mat pos = pipe.frame().downloadGBuffer(0), alb = pipe.frame().downloadGBuffer(2);
  const cv::Mat own = download4(*ivOf(pipe).outputs().realDelta);
  const cv::Mat delta = pipe.downloadIrradiance();
  double nearSum = 0, farSum = 0;
  int nearN = 0, farN = 0, ownNonZero = 0;
  for (int i = 0; i < static_cast<int>(pos.total()); ++i) {
    const cv::Vec4f p = pos.at<cv::Vec4f>(i);
    if (p[3] < 0.5f || alb.at<cv::Vec4f>(i)[3] > 0.5f || p[2] > 0.01f) continue;  // the floor
    const double r = std::hypot(p[0] + 0.36, p[1]);
    const cv::Vec4f d = delta.at<cv::Vec4f>(i);
    ASSERT_TRUE(std::isfinite(d[0]));
    ownNonZero += own.at<cv::Vec4f>(i)[0] != 0.0f;
    if (r > 0.07 && r < 0.1) nearSum += d[0], ++nearN;
    if (r > 0.4 * g.resolution * g.voxel) farSum += d[0], ++farN;
  }
  ASSERT_GT(nearN, 20);
  EXPECT_EQ(ownNonZero, 0) << "the volumes' own delta on the floor";
  // Next to the cube the floor misses a good part of the sky: pi * 0.2 = 0.63 W/m^2 unoccluded.
  EXPECT_LT(nearSum / nearN, -0.05);
  if (farN > 0) {
    EXPECT_GT(farSum / farN, -0.02);  // far from it, little change
  }
  // With the lamp, the wall's red bounce reaches the cube's side facing it (-x; out of the camera's view:
  // read from the volume): red well above green.
  pipe.run(wallCamera(), wallLamp(), {0.0, 0.0, 0.0}, nullptr);
  const iv::Volume vol = ivOf(pipe).downloadVolume();
  const cv::Vec3f e = iv::irradiance(vol, ivOf(pipe).downloadIncident(false), {-0.42f, 0.0f, 0.06f}, {-1, 0, 0});
  EXPECT_GT(e[0], 3.0f * e[1]) << e;
  EXPECT_GT(e[0], 0.0f);
}

TEST(GL, ImperfectVolumesMarchEachRayOnceAndEveryPassReadsTheSameHits) {
  auto ctx = makeContext();
  // The rays' hits kept by iv_hits.comp (the default budget) against every pass marching its own rays (no
  // budget): the ambient the cube hides, both gathers over two bounces, the objects' cone and the read-outs
  // identical to the bit.
  const TestScene s = makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  PipelineConfig cfg = ivConfig("imperfect-volumes", 16, 2);
  cfg.set("iv", "object_rays", 32);
  struct Run {
    iv::Incident rho, mu;
    std::vector<cv::Vec3f> hidden;
    cv::Mat delta, virt;
    bool cached = false;
  };
  const auto run = [&](size_t budget) {
    LightingPipeline pipe = makePipeline(cfg, s);
    dynamic_cast<ImperfectVolumesTechnique&>(*pipe.technique("imperfect-volumes")).setHitsBudget(budget);
    pipe.setAmbientSh({cv::Vec3d(0.05, 0.05, 0.05), {}, cv::Vec3d(0.03, 0.02, 0.01)});
    pipe.run(wallCamera(), wallLamp(), {0.1, 0.1, 0.12}, nullptr);
    const ImperfectVolumesTechnique& t = ivOf(pipe);
    return Run{t.downloadIncident(true),
               t.downloadIncident(false),
               t.downloadHidden(),
               download4(*t.outputs().realDelta),
               download4(*t.outputs().virtualIrradiance),
               t.hitsCached()};
  };
  const Run kept = run(ImperfectVolumesTechnique::kDefaultHitsBudget), marched = run(0);
  EXPECT_TRUE(kept.cached);
  EXPECT_FALSE(marched.cached);
  EXPECT_EQ(kept.rho.sh, marched.rho.sh);
  EXPECT_EQ(kept.rho.occlusion, marched.rho.occlusion);
  EXPECT_EQ(kept.mu.sh, marched.mu.sh);
  EXPECT_EQ(kept.mu.occlusion, marched.mu.occlusion);
  EXPECT_EQ(kept.hidden, marched.hidden);
  int hiding = 0;
  for (const cv::Vec3f& h : kept.hidden) hiding += h[0] > 0.f;
  EXPECT_GT(hiding, 10);
  EXPECT_EQ(cv::norm(kept.delta, marched.delta, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(kept.virt, marched.virt, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(kept.delta, cv::NORM_INF), 0.0);
}
