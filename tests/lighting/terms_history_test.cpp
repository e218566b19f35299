// The object terms carried from frame to frame (lighting/terms_history.h, frame knob object_terms_history):
// the C++ twin's reprojection and agreement, and the pipeline's pass held to the twin texel by texel — a
// surface seen in both frames takes the blend, one the previous frame did not see (a disocclusion) the fresh
// terms, and a change of anything but the camera drops the history.
#include "lighting/terms_history.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "lighting/upsample.h"
#include "test_scene.h"

namespace mrgi::lighting {
namespace {

/// The world point on the plane z = 0 that pixel (u, v) of camera c sees.
cv::Vec3f floorPoint(const CameraView& c, double u, double v) {
  const capture::Intrinsics& k = c.intrinsics;
  const cv::Vec3d dir((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
  const cv::Matx33d R = c.T_world_camera.get_minor<3, 3>(0, 0);
  const cv::Vec3d o = capture::translationOf(c.T_world_camera), w = R * dir;
  return cv::Vec3f(o + (-o[2] / w[2]) * w);
}

TEST(TermsHistory, EachReducedTexelsSourcePointProjectsBackOntoItself) {
  const CameraView c = test::topCamera(64, 48);
  for (int factor : {1, 2, 3, 4}) {
    const HistoryCamera h = historyCamera(c, factor);
    for (int j = 0; j < h.grid.height; ++j)
      for (int i = 0; i < h.grid.width; ++i) {
        const cv::Vec3f x = floorPoint(c, reducedSource(i, factor, 64), reducedSource(j, factor, 48));
        const auto q = historyTexel(h, x);
        ASSERT_TRUE(q.has_value()) << factor << " " << i << " " << j;
        EXPECT_EQ(*q, cv::Point(i, j)) << factor;
        // Half a block over lands on the neighbour that is nearer, or stays.
        const auto r =
            historyTexel(h, floorPoint(c, reducedSource(i, factor, 64) + 0.45 * factor, reducedSource(j, factor, 48)));
        if (r) {
          EXPECT_LE(std::abs(r->x - i) + std::abs(r->y - j), 1);
        }
      }
  }
  const HistoryCamera h = historyCamera(c, 2);
  EXPECT_FALSE(historyTexel(h, floorPoint(c, -3.0, 10.0)).has_value()) << "left of the image";
  EXPECT_FALSE(historyTexel(h, floorPoint(c, 10.0, 50.5)).has_value()) << "below the image";
  EXPECT_FALSE(historyTexel(h, cv::Vec3f(0.0f, -0.25f, 2.0f)).has_value()) << "behind the camera";
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(historyTexel(h, cv::Vec3f(nan, 0.0f, 0.0f)).has_value());
}

TEST(TermsHistory, TheHistoryCountsOnlyOnTheSameSurfaceAndBlendsFiniteValues) {
  const cv::Vec3f x(0.1f, 0.2f, 0.0f), n(0, 0, 1), eye(0, 0, 2);  // 2.01 m away: reach 2 % + 2 mm = 42.2 mm
  const cv::Vec4f up(0, 0, 1, 0);
  EXPECT_TRUE(historyAgrees(x, n, eye, {0.1f, 0.2f, 0.0f, 1.0f}, up));
  EXPECT_TRUE(historyAgrees(x, n, eye, {0.1f + 0.041f, 0.2f, 0.0f, 1.0f}, up));
  EXPECT_FALSE(historyAgrees(x, n, eye, {0.1f, 0.2f, 0.044f, 1.0f}, up)) << "too far";
  EXPECT_FALSE(historyAgrees(x, n, eye, {0.1f, 0.2f, 0.0f, 0.0f}, up)) << "no real surface there";
  const float s = std::sqrt(1.0f - 0.89f * 0.89f), t = std::sqrt(1.0f - 0.91f * 0.91f);
  EXPECT_FALSE(historyAgrees(x, n, eye, {0.1f, 0.2f, 0.0f, 1.0f}, {s, 0, 0.89f, 0})) << "normal 27 degrees off";
  EXPECT_TRUE(historyAgrees(x, n, eye, {0.1f, 0.2f, 0.0f, 1.0f}, {t, 0, 0.91f, 0}));
  const cv::Vec4f fresh(1, 2, 3, 1), old(3, 2, 1, 1);
  EXPECT_EQ(blendHistory(fresh, old, 0.25f, true), cv::Vec4f(1.5f, 2.0f, 2.5f, 1.0f));
  EXPECT_EQ(blendHistory(fresh, old, 0.25f, false), fresh);
  EXPECT_EQ(blendHistory(fresh, old, 0.0f, true), fresh);
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(blendHistory(fresh, cv::Vec4f(inf, 0, 0, 1), 0.5f, true), fresh);
}

// The floor under a cube floating 25 cm above it, lit by an SH sky: the camera moves 30 cm sideways between two
// frames, so floor the cube hid in the first is seen in the second. A pipeline with object_terms_history 0.5
// and one without run the same frames: the second frame's terms are, texel by texel, the twin's blend of the
// fresh terms (the pipeline without) and the first frame's (the pipeline with, downloaded), to 1e-5.
TEST(TermsHistory, ThePassBlendsWhereTheSurfaceAgreesAndADisocclusionTakesFreshValues) {
  auto ctx = test::makeContext();
  const test::TestScene s = test::makeScene(false, 0.2, {0.0, 0.0, 0.25});
  PipelineConfig cfg = test::testConfig(96, 72, 16, 64, "none");
  PipelineConfig withHistory = cfg;
  withHistory.set("frame", "object_terms_history", 0.5);
  LightingPipeline fresh = test::makePipeline(cfg, s), carried = test::makePipeline(withHistory, s);
  std::array<cv::Vec3d, 9> sh{};
  sh[0] = {0.8, 0.7, 0.6};
  sh[2] = {0.5, 0.4, 0.3};
  CameraView a = test::topCamera(96, 72), b = a;
  a.T_world_camera = capture::lookAtPose({-0.15, -0.25, 1.2}, {0, 0, 0});
  b.T_world_camera = capture::lookAtPose({0.15, -0.25, 1.2}, {0, 0, 0});
  const cv::Vec3d uniform(0.1, 0.1, 0.1);
  for (LightingPipeline* p : {&fresh, &carried}) {
    p->setAmbientSh(sh);
    p->run(a, {}, uniform, nullptr);
  }
  const cv::Mat beforeTerms = carried.downloadObjectTerms(0), beforePos = carried.downloadObjectTerms(1),
                beforeNrm = carried.downloadObjectTerms(2);
  ASSERT_EQ(beforeTerms.cols, 48);
  EXPECT_LT(cv::norm(beforeTerms, fresh.downloadObjectTerms(0), cv::NORM_INF), 1e-7) << "no history yet";
  for (LightingPipeline* p : {&fresh, &carried}) p->run(b, {}, uniform, nullptr);
  const cv::Mat now = fresh.downloadObjectTerms(0), got = carried.downloadObjectTerms(0),
                pos = carried.downloadObjectTerms(1), nrm = carried.downloadObjectTerms(2);
  const HistoryCamera before = historyCamera(a, 2);
  const cv::Vec3f eye(capture::translationOf(b.T_world_camera));
  int blended = 0, moved = 0, disoccluded = 0, computed = 0;
  double worst = 0;
  for (int y = 0; y < now.rows; ++y)
    for (int x = 0; x < now.cols; ++x) {
      const cv::Vec4f f = now.at<cv::Vec4f>(y, x), p = pos.at<cv::Vec4f>(y, x), n = nrm.at<cv::Vec4f>(y, x);
      if (f[3] < 0.5f) continue;
      ++computed;
      const cv::Vec3f at(p[0], p[1], p[2]), nn(n[0], n[1], n[2]);
      const auto q = historyTexel(before, at);
      bool agrees = false;
      cv::Vec4f history;
      if (q) {
        history = beforeTerms.at<cv::Vec4f>(*q);
        agrees = historyAgrees(at, nn, eye, beforePos.at<cv::Vec4f>(*q), beforeNrm.at<cv::Vec4f>(*q));
        // The cube stood where this floor point lies in the first frame's view: what it hid.
        if (beforePos.at<cv::Vec4f>(*q)[3] < 0.5f && at[2] < 0.01f && std::abs(at[0]) < 0.4f && std::abs(at[1]) < 0.4f)
          ++disoccluded;
      }
      const cv::Vec4f want = blendHistory(f, history, 0.5f, agrees);
      blended += agrees;
      moved += agrees && cv::norm(history - f) > 1e-3 * cv::norm(f);
      worst = std::max(worst, cv::norm(got.at<cv::Vec4f>(y, x) - want) / std::max(cv::norm(want), 1e-3));
      if (!agrees) {
        EXPECT_EQ(got.at<cv::Vec4f>(y, x), f) << "fresh at " << x << ", " << y;
      }
    }
  EXPECT_GT(computed, 1200);
  EXPECT_GT(blended, computed / 2);
  EXPECT_GT(moved, 100) << "the history differs from the fresh terms where the blend is tested";
  EXPECT_GT(disoccluded, 20);
  EXPECT_LT(worst, 1e-5);
  // A change of the ambient drops the history: the same camera again gives the fresh terms.
  sh[2] = {0.2, 0.4, 0.6};
  for (LightingPipeline* p : {&fresh, &carried}) {
    p->setAmbientSh(sh);
    p->run(a, {}, uniform, nullptr);
  }
  EXPECT_LT(cv::norm(carried.downloadObjectTerms(0), fresh.downloadObjectTerms(0), cv::NORM_INF), 1e-7);
  // The estimate before allocating counts the history's targets: what they add at least.
  ASSERT_GT(carried.gpuBytes(), fresh.gpuBytes());
  EXPECT_GE(estimateGpuBytes(withHistory, 1) - estimateGpuBytes(cfg, 1), carried.gpuBytes() - fresh.gpuBytes());
}

}  // namespace
}  // namespace mrgi::lighting
