// Technique outputs at a reduced resolution (lighting/upsample.h): a smooth field comes back within bilinear
// interpolation's error, an edge in depth or between surfaces keeps each side's values, the GLSL twin and the
// shading pass agree with the C++ per pixel, and the frame's reduced G-buffer is the C++ one.
#include "lighting/upsample.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "gl/error.h"
#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/frame/mesh.h"
#include "test_scene.h"

namespace mrgi::lighting {
namespace {

constexpr float kFocal = 80.f;  // pixels: the synthetic camera's focal length

/// A synthetic G-buffer: a pinhole at the origin looking along +z; `surface` gives, for a view ray, the hit's
/// distance along it (<= 0: none), its normal and its class (the normal's w).
struct Synthetic {
  cv::Mat position, normal, value;
};
using Surface = std::function<bool(const cv::Vec3f& ray, int x, int y, float& t, cv::Vec3f& n, float& cls, float& v)>;

Synthetic makeGBuffer(int w, int h, const Surface& surface) {
  Synthetic s{cv::Mat(h, w, CV_32FC4, cv::Scalar::all(0)), cv::Mat(h, w, CV_32FC4, cv::Scalar::all(0)),
              cv::Mat(h, w, CV_32FC4, cv::Scalar::all(0))};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const cv::Vec3f ray((x + 0.5f - 0.5f * w) / kFocal, (y + 0.5f - 0.5f * h) / kFocal, 1.f);
      float t = 0, cls = 0, v = 0;
      cv::Vec3f n;
      if (!surface(ray, x, y, t, n, cls, v) || !(t > 0)) continue;
      const cv::Vec3f p = t * ray;
      s.position.at<cv::Vec4f>(y, x) = {p[0], p[1], p[2], 1.f};
      s.normal.at<cv::Vec4f>(y, x) = {n[0], n[1], n[2], cls};
      s.value.at<cv::Vec4f>(y, x) = {v, 0.5f * v, 2.f * v, 1.f};
    }
  return s;
}

/// A plane through `point` with unit normal `n` (facing the camera), hit by a ray at t.
float planeHit(const cv::Vec3f& ray, const cv::Vec3f& point, const cv::Vec3f& n) {
  const float d = ray.dot(n);
  return std::abs(d) < 1e-6f ? -1.f : point.dot(n) / d;
}

TEST(Upsample, ASmoothFieldComesBackWithinItsInterpolationError) {
  // A tilted plane, a smooth value over it: at 1/2, 1/3 and 1/4 the interior pixels are within the bilinear
  // interpolation bound h^2/8 (max|g_xx| + max|g_yy|) of the field in pixel space, h the factor.
  const int w = 96, h = 72;
  const cv::Vec3f n = cv::normalize(cv::Vec3f(0.f, -0.6f, -1.f));
  const auto field = [](const cv::Vec3f& p) { return 1.f + 0.5f * std::sin(3.f * p[0]) * std::cos(2.f * p[1]); };
  const Synthetic s =
      makeGBuffer(w, h, [&](const cv::Vec3f& ray, int, int, float& t, cv::Vec3f& nn, float& cls, float& v) {
        t = planeHit(ray, {0, 0, 2}, n);
        nn = n;
        cls = 0;
        v = field(t * ray);
        return true;
      });
  // The field's second differences in pixel space, measured.
  double gxx = 0, gyy = 0;
  for (int y = 1; y + 1 < h; ++y)
    for (int x = 1; x + 1 < w; ++x) {
      const auto g = [&](int xx, int yy) { return double(s.value.at<cv::Vec4f>(yy, xx)[0]); };
      gxx = std::max(gxx, std::abs(g(x + 1, y) - 2 * g(x, y) + g(x - 1, y)));
      gyy = std::max(gyy, std::abs(g(x, y + 1) - 2 * g(x, y) + g(x, y - 1)));
    }
  for (int factor : {2, 3, 4}) {
    const cv::Mat up = upsample(reduceGBuffer(s.value, factor), reduceGBuffer(s.position, factor),
                                reduceGBuffer(s.normal, factor), s.position, s.normal, factor);
    const double bound =
        factor * factor / 8.0 * (gxx + gyy) * 1.1 + 1e-6;  // 10 %: the measured derivatives are discrete
    double worst = 0, sum = 0;
    int count = 0;
    for (int y = factor; y < h - 2 * factor; ++y)  // the border extrapolates (clamped texels)
      for (int x = factor; x < w - 2 * factor; ++x)
        for (int c = 0; c < 3; ++c) {
          const double e = std::abs(up.at<cv::Vec4f>(y, x)[c] - s.value.at<cv::Vec4f>(y, x)[c]) / (c == 1   ? 0.5
                                                                                                   : c == 2 ? 2.0
                                                                                                            : 1.0);
          worst = std::max(worst, e);
          sum += e;
          ++count;
        }
    EXPECT_LT(worst, bound) << "factor " << factor;
    EXPECT_GT(sum / count, 1e-5) << "factor " << factor;  // it interpolated (the field is not linear)
  }
}

TEST(Upsample, AStepEdgeInDepthKeepsItsIrradianceEdge) {
  // Left: a near wall (z = 1) with value 1; right: the far wall (z = 2), 0.2, the same normal, so only the
  // depth tells them apart; a virtual object (class 1) on the far wall's plane, 5, and a second object's
  // strip two pixels wide (class 2), 3, narrower than a block at 1/4. Each pixel keeps its own side's value;
  // plain bilinear upsampling blurs the edges.
  const int w = 64, h = 48;
  const Synthetic s =
      makeGBuffer(w, h, [&](const cv::Vec3f& ray, int x, int y, float& t, cv::Vec3f& n, float& cls, float& v) {
        n = {0, 0, -1};
        if (x >= 42 && x < 44) {
          t = 1.9f;
          cls = 2;
          v = 3.f;
        } else if (x < 29) {
          t = 1.f;
          cls = 0;
          v = 1.f;
        } else if (y > 30 && x > 45 && x < 57) {
          t = 2.f;
          cls = 1;
          v = 5.f;
        } else {
          t = 2.f;
          cls = 0;
          v = 0.2f;
        }
        t /= ray[2];
        return true;
      });
  for (int factor : {2, 3, 4}) {
    const cv::Mat lowValue = reduceGBuffer(s.value, factor), lowPosition = reduceGBuffer(s.position, factor),
                  lowNormal = reduceGBuffer(s.normal, factor);
    const cv::Mat up = upsample(lowValue, lowPosition, lowNormal, s.position, s.normal, factor);
    double worst = 0, worstBilinear = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float truth = s.value.at<cv::Vec4f>(y, x)[0];
        worst = std::max(worst, double(std::abs(up.at<cv::Vec4f>(y, x)[0] - truth)));
        cv::Mat one;
        cv::Vec4f b;
        // Plain bilinear: the same reduced grid, every texel's surface taken as the pixel's.
        const float u = float(x - factor / 2) / factor, v = float(y - factor / 2) / factor;
        const int i0 = int(std::floor(u)), j0 = int(std::floor(v));
        float acc = 0;
        for (int dj = 0; dj < 2; ++dj)
          for (int di = 0; di < 2; ++di) {
            const int i = std::clamp(i0 + di, 0, lowValue.cols - 1), j = std::clamp(j0 + dj, 0, lowValue.rows - 1);
            acc += (di ? u - i0 : 1 - (u - i0)) * (dj ? v - j0 : 1 - (v - j0)) * lowValue.at<cv::Vec4f>(j, i)[0];
          }
        worstBilinear = std::max(worstBilinear, double(std::abs(acc - truth)));
      }
    EXPECT_LT(worst, 1e-4) << "factor " << factor;  // float rounding of a weighted mean of equal values
    EXPECT_GT(worstBilinear, 1.0) << "factor " << factor;
  }
}

TEST(Upsample, EveryWeightIsFiniteAndBoundedAtTheExtremes) {
  const cv::Vec4f p(0, 0, 1, 1), n(0, 0, -1, 0);
  for (const cv::Vec4f& q : {cv::Vec4f(0, 0, 1, 1), cv::Vec4f(1e30f, 0, 1, 1), cv::Vec4f(0, 0, 1e-30f, 1),
                             cv::Vec4f(NAN, 0, 1, 1), cv::Vec4f(INFINITY, 0, 1, 1)})
    for (const cv::Vec4f& m : {n, cv::Vec4f(0, 0, 1, 0), cv::Vec4f(NAN, 0, 0, 0), cv::Vec4f(0, 0, 0, 0)}) {
      const float w = upsampleWeight(p, n, q, m);
      EXPECT_TRUE(std::isfinite(w) && w >= 0.f && w <= 1.f) << q << m << " " << w;
    }
  EXPECT_FLOAT_EQ(upsampleWeight(p, n, p, n), 1.f);                 // the pixel's own sample
  EXPECT_EQ(upsampleWeight(p, n, p, cv::Vec4f(0, 0, -1, 1)), 0.f);  // another class
  EXPECT_EQ(renderFactor(1.0), 1);
  EXPECT_EQ(renderFactor(0.5), 2);
  EXPECT_EQ(renderFactor(0.25), 4);
  EXPECT_EQ(renderFactor(0.0), 1);
  EXPECT_EQ(renderFactor(NAN), 1);
}

TEST(Upsample, GlslTwinMatchesTheCppPerPixel) {
  auto ctx = test::makeContext();
  const int w = 61, h = 47;  // odd sizes: the last block is partial
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Synthetic s =
      makeGBuffer(w, h, [&](const cv::Vec3f& ray, int x, int y, float& t, cv::Vec3f& n, float& cls, float& v) {
        // A sphere (object 1) in front of a tilted floor, a hole in the floor (no surface).
        const cv::Vec3f c(0.1f, 0.05f, 1.5f);
        const float b = ray.dot(c) / ray.dot(ray), disc = b * b - (c.dot(c) - 0.09f) / ray.dot(ray);
        if (disc > 0) {
          t = b - std::sqrt(disc);
          n = cv::normalize(t * ray - c);
          cls = 1;
        } else {
          if (x > 50 && y < 8) return false;
          n = cv::normalize(cv::Vec3f(0.1f, -0.7f, -1.f));
          t = planeHit(ray, {0, 0, 2.2f}, n);
          // A speckle of another surface class (object 2) over one corner: pixels whose four reduced texels
          // are all of the floor, and the 4 x 4 search around them.
          cls = x < 20 && y > 30 && (x * 5 + y * 11) % 7 < 2 ? 2 : 0;
        }
        v = u(rng);
        // On one plane the texels a search finds tie in weight (to the rounding, which the GPU and the C++ may
        // break differently): one value per class there, whichever wins.
        if (x < 20 && y > 30) v = cls == 2 ? 0.5f : 0.25f;
        return true;
      });
  for (int factor : {2, 3, 4}) {
    const cv::Mat lowValue = reduceGBuffer(s.value, factor), lowPosition = reduceGBuffer(s.position, factor),
                  lowNormal = reduceGBuffer(s.normal, factor);
    const cv::Mat expected = upsample(lowValue, lowPosition, lowNormal, s.position, s.normal, factor);
    const auto texture = [](const cv::Mat& m) {
      gl::Texture t(GL_TEXTURE_2D, GL_RGBA32F, m.cols, m.rows);
      t.setFilter(GL_NEAREST, GL_NEAREST);
      t.upload(GL_RGBA, GL_FLOAT, m.ptr(), 4);
      return t;
    };
    // A second output of the same reduced view for upsampledPair(): the first's values reversed.
    cv::Mat lowValue2 = cv::Scalar(1, 1, 1, 1) - lowValue;
    const cv::Mat expected2 = upsample(lowValue2, lowPosition, lowNormal, s.position, s.normal, factor);
    gl::Texture tp = texture(s.position), tn = texture(s.normal), tlp = texture(lowPosition), tln = texture(lowNormal),
                tv = texture(lowValue), tv2 = texture(lowValue2);
    gl::Buffer out(static_cast<GLsizeiptr>(size_t(w) * h * sizeof(cv::Vec4f)), nullptr);
    gl::Buffer pairsOut(static_cast<GLsizeiptr>(2 * size_t(w) * h * sizeof(cv::Vec4f)), nullptr);
    gl::Program prog = gl::Program::compute("lighting/shaders/upsample_eval.comp");
    prog.use();
    prog.set("uFactor", factor);
    tp.bind(0);
    tn.bind(1);
    tlp.bind(2);
    tln.bind(3);
    tv.bind(4);
    tv2.bind(5);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, out.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, pairsOut.id());
    glDispatchCompute((w + 7) / 8, (h + 7) / 8, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    cv::Mat gpu(h, w, CV_32FC4), pairs(h, 2 * w, CV_32FC4);
    out.download(0, static_cast<GLsizeiptr>(gpu.total() * gpu.elemSize()), gpu.ptr());
    pairsOut.download(0, static_cast<GLsizeiptr>(pairs.total() * pairs.elemSize()), pairs.ptr());
    gl::checkGlError("upsample_eval");
    double worst = 0, pairWorst = 0, pairWorst2 = 0;
    int fallback = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        if (s.position.at<cv::Vec4f>(y, x)[3] < 0.5f) continue;
        for (int c = 0; c < 3; ++c) {
          worst = std::max(worst, double(std::abs(gpu.at<cv::Vec4f>(y, x)[c] - expected.at<cv::Vec4f>(y, x)[c])));
          // The pair: the first output exactly as upsampled() gives it, the second as its C++ twin.
          pairWorst =
              std::max(pairWorst, double(std::abs(pairs.at<cv::Vec4f>(y, 2 * x)[c] - gpu.at<cv::Vec4f>(y, x)[c])));
          pairWorst2 = std::max(
              pairWorst2, double(std::abs(pairs.at<cv::Vec4f>(y, 2 * x + 1)[c] - expected2.at<cv::Vec4f>(y, x)[c])));
        }
        // Where the four texels around the pixel give no weight, the search of the 4 x 4 around them.
        const float ux = static_cast<float>(x - factor / 2) / factor, uy = static_cast<float>(y - factor / 2) / factor;
        const int bx = static_cast<int>(std::floor(ux)), by = static_cast<int>(std::floor(uy));
        float total = 0;
        for (int dj = 0; dj < 2; ++dj)
          for (int di = 0; di < 2; ++di) {
            const int qx = std::clamp(bx + di, 0, lowPosition.cols - 1),
                      qy = std::clamp(by + dj, 0, lowPosition.rows - 1);
            const float b = (di ? ux - bx : 1 - (ux - bx)) * (dj ? uy - by : 1 - (uy - by));
            total += b * upsampleWeight(s.position.at<cv::Vec4f>(y, x), s.normal.at<cv::Vec4f>(y, x),
                                        lowPosition.at<cv::Vec4f>(qy, qx), lowNormal.at<cv::Vec4f>(qy, qx));
          }
        fallback += total <= 1e-4f && expected.at<cv::Vec4f>(y, x)[0] != 0.f;
      }
    EXPECT_LT(worst, 1e-5) << "factor " << factor;  // float exp() on llvmpipe against the C++'s, values O(1)
    EXPECT_EQ(pairWorst, 0.0) << "factor " << factor;
    EXPECT_LT(pairWorst2, 1e-5) << "factor " << factor;
    EXPECT_GT(fallback, 0) << "factor " << factor << ": the 4 x 4 search is held to its twin too";
  }
}

class ShadingPassUpsample : public ::testing::TestWithParam<const char*> {};

TEST_P(ShadingPassUpsample, ATechniquesReducedOutputAsTheCppDoes) {
  // A technique at render_scale 1 and 1/2 on the floor, wall and cube: the frame's reduced G-buffer is the C++
  // reduction of its G-buffer, the object's indirect irradiance is the C++ upsampling of the technique's
  // reduced output, and a real pixel's delta differs from the full-resolution run's by exactly the difference
  // between the two technique outputs (the shading pass's direct shadow runs at the frame's pixels in both;
  // with no ambient the objects hide nothing, so its reduced object terms, ObjectShadow.AtAReducedRenderScale…,
  // are zero). DLPV draws the objects' direct shadow itself; imperfect volumes leave it to the pass, whose real-pixel
  // delta and object terms then share their upsampling weights (shade.frag SHARED_UPSAMPLE) and the direct shadow
  // is added at the frame's pixels beside them.
  auto ctx = test::makeContext();
  const test::TestScene s = test::makeScene(true, 0.12, {-0.36, 0.0, 0.06});
  const CameraView camera = test::wallCamera();  // 96 x 72
  std::vector<cv::Mat> irradiance, delta, gbufferPos, gbufferNrm;
  cv::Mat lowDelta, lowVirtual, lowPos, lowNrm;
  for (double scale : {1.0, 0.5}) {
    PipelineConfig cfg = test::testConfig(96, 72, 16, 64, GetParam());
    cfg.set("frame", "render_scale", scale);
    LightingPipeline pipe = test::makePipeline(cfg, s);
    pipe.run(camera, test::wallLamp(), {0.0, 0.0, 0.0}, nullptr);
    irradiance.push_back(pipe.downloadIrradiance());
    gbufferPos.push_back(pipe.downloadGBuffer(0));
    gbufferNrm.push_back(pipe.downloadGBuffer(1));
    const TechniqueOutputs o = pipe.techniqueFor(Role::Real)->outputs();
    ASSERT_TRUE(o.realDelta && o.virtualIrradiance);
    delta.push_back(download4(*o.realDelta));
    if (scale < 1) {
      ASSERT_EQ(o.realDelta->width(), 48);
      ASSERT_EQ(o.realDelta->height(), 36);
      lowDelta = delta.back();
      lowVirtual = download4(*o.virtualIrradiance);
      lowPos = pipe.frame().downloadGBuffer(0, true);
      lowNrm = pipe.frame().downloadGBuffer(1, true);
      for (int c = 0; c < 3; ++c) {
        const cv::Mat expected = reduceGBuffer(pipe.downloadGBuffer(c), 2), got = pipe.frame().downloadGBuffer(c, true);
        EXPECT_EQ(cv::norm(expected, got, cv::NORM_INF), 0.0) << "channel " << c;
      }
    }
  }
  const cv::Mat upDelta = upsample(lowDelta, lowPos, lowNrm, gbufferPos[1], gbufferNrm[1], 2);
  const cv::Mat upVirtual = upsample(lowVirtual, lowPos, lowNrm, gbufferPos[1], gbufferNrm[1], 2);
  double worstReal = 0, worstVirtual = 0, moved = 0;
  int real = 0, virt = 0;
  for (int y = 0; y < 72; ++y)
    for (int x = 0; x < 96; ++x) {
      const cv::Vec4f n = gbufferNrm[1].at<cv::Vec4f>(y, x);
      if (gbufferPos[1].at<cv::Vec4f>(y, x)[3] < 0.5f) continue;
      for (int c = 0; c < 3; ++c) {
        if (n[3] > 0.5f) {
          worstVirtual = std::max(
              worstVirtual, double(std::abs(irradiance[1].at<cv::Vec4f>(y, x)[c] - upVirtual.at<cv::Vec4f>(y, x)[c])));
        } else {
          const double expected =
              irradiance[0].at<cv::Vec4f>(y, x)[c] - delta[0].at<cv::Vec4f>(y, x)[c] + upDelta.at<cv::Vec4f>(y, x)[c];
          worstReal = std::max(worstReal, std::abs(irradiance[1].at<cv::Vec4f>(y, x)[c] - expected));
          moved = std::max(
              moved, double(std::abs(irradiance[1].at<cv::Vec4f>(y, x)[c] - irradiance[0].at<cv::Vec4f>(y, x)[c])));
        }
      }
      (n[3] > 0.5f ? virt : real)++;
    }
  EXPECT_GT(real, 1000);
  EXPECT_GT(virt, 50);
  EXPECT_LT(worstVirtual, 1e-5);  // the GLSL twin against the C++ (its own test: 1e-5)
  EXPECT_LT(worstReal, 1e-4);     // and the full-resolution run's float sums beside it
  EXPECT_GT(moved, 1e-4);         // the reduced run differs: the comparison is not of one image with itself
}

INSTANTIATE_TEST_SUITE_P(Upsample, ShadingPassUpsample, ::testing::Values("dlpv", "imperfect-volumes"),
                         [](const auto& info) {
                           std::string name = info.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

}  // namespace
}  // namespace mrgi::lighting
