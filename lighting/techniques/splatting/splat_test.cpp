// Splatting's reference math (splat.h): pixel-light lobes conserve their flux, the irradiance is finite at
// every extreme, the splat bounds never cut more than I_low of a light, the hierarchical warping is
// unbiased and samples in proportion to the importance, and a sharp glossy light focuses where its mirror
// direction says.
#include "lighting/techniques/splatting/splat.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mrgi::lighting::splat {
namespace {

float lum(const cv::Vec3f& c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

PixelLight diffuseLight(cv::Vec3f at = {0, 0, 0}, cv::Vec3f n = {0, 0, 1}, float flux = 1.0f, float area = 1e-4f) {
  PixelLight l;
  l.position = at;
  l.normal = n;
  l.axis = n;
  l.flux = {flux, flux, flux};
  l.area = area;
  return l;
}

PixelLight glossyLight(float exponent, cv::Vec3f axis, float widen = 0.0f) {
  PixelLight l = diffuseLight();
  l.exponent = exponent;
  l.axis = cv::normalize(axis);
  l.widen = widen;
  return l;
}

// ∫ I(ω) dω over the sphere by a fine midpoint rule in (cos θ, φ) about the z axis (a lobe about z needs
// one φ and many cos θ: at P = 1000 it is 0.002 wide in cos θ).
double emitted(const PixelLight& l, float d = 1.0f, int nt = 2000, int np = 400) {
  double sum = 0;
  for (int i = 0; i < nt; ++i) {
    const double c = -1 + 2 * (i + 0.5) / nt, s = std::sqrt(1 - c * c);
    for (int j = 0; j < np; ++j) {
      const double ph = 2 * CV_PI * (j + 0.5) / np;
      const cv::Vec3f w(static_cast<float>(s * std::cos(ph)), static_cast<float>(s * std::sin(ph)),
                        static_cast<float>(c));
      sum += intensity(l, w, d)[0];
    }
  }
  return sum * (2.0 / nt) * (2 * CV_PI / np);
}

TEST(SplatLobes, SendOutTheirFlux) {
  EXPECT_NEAR(emitted(diffuseLight()), 1.0, 1e-3);
  for (float P : {1.0f, 10.0f, 100.0f, 1000.0f, 1e4f})
    EXPECT_NEAR(emitted(glossyLight(P, {0, 0, 1}), 1.0f, 2000000, 1), 1.0, 2e-3) << P;
  // A lobe tilted 60° loses what falls below the surface, never more than its flux.
  const double tilted = emitted(glossyLight(10, {std::sin(1.047f), 0, std::cos(1.047f)}));
  EXPECT_LT(tilted, 1.0);
  EXPECT_GT(tilted, 0.8);
  // Fully widened at the light (d = 0): uniform over the hemisphere, still the flux.
  EXPECT_NEAR(emitted(glossyLight(100, {0, 0, 1}, 0.05f), 0.0f), 1.0, 2e-3);
}

TEST(SplatIrradiance, IsTheInverseSquareLawFarAwayAndBoundedNearTheLight) {
  const PixelLight l = diffuseLight({0, 0, 0}, {0, 0, 1}, 2.0f, 1e-4f);
  // Straight above at 1 m, facing down: E = Φ/π / d².
  const cv::Vec3f e = irradiance(l, {0, 0, 1}, {0, 0, -1});
  EXPECT_NEAR(e[0], 2.0 / CV_PI, 2.0 / CV_PI * 1e-4);
  // At 45°, tilted receiver: cos at both ends over d².
  const cv::Vec3f x(0.5f, 0, 0.5f);
  const float d2 = x.dot(x);
  const cv::Vec3f n = cv::normalize(cv::Vec3f(-1, 0, -2));
  const float expect = 2.0f / static_cast<float>(CV_PI) * (x[2] / std::sqrt(d2)) * (-n.dot(x) / std::sqrt(d2)) / d2;
  EXPECT_NEAR(irradiance(l, x, n)[0], expect, expect * 1e-3);
  // d -> 0: never above Φ / A (the disc's exitance), finite, and 0 on the light itself.
  for (float d : {1e-2f, 1e-4f, 1e-8f, 1e-20f}) {
    const float v = irradiance(l, {0, 0, d}, {0, 0, -1})[0];
    EXPECT_TRUE(std::isfinite(v)) << d;
    EXPECT_LE(v, 2.0f / 1e-4f * 1.0001f) << d;
  }
  EXPECT_EQ(irradiance(l, {0, 0, 0}, {0, 0, -1}), cv::Vec3f(0, 0, 0));
  // Behind the light or facing away: nothing.
  EXPECT_EQ(irradiance(l, {0, 0, -1}, {0, 0, 1}), cv::Vec3f(0, 0, 0));
  EXPECT_EQ(irradiance(l, {0, 0, 1}, {0, 0, 1}), cv::Vec3f(0, 0, 0));
}

TEST(SplatIrradiance, StaysFiniteAtTheExtremes) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1, 1);
  for (float P : {0.0f, 1.0f, 10.0f, 100.0f, 1000.0f, 1e4f})
    for (float flux : {0.0f, 1e-30f, 1.0f, 1e20f})
      for (float area : {0.0f, 1e-12f, 1e-4f})
        for (float widen : {0.0f, 0.05f}) {
          PixelLight l = glossyLight(P, {0.3f, 0.1f, 1.0f}, widen);
          if (P == 0) l = diffuseLight({0, 0, 0}, {0, 0, 1}, flux, area);
          l.flux = {flux, flux, flux};
          l.area = area;
          for (int k = 0; k < 200; ++k) {
            const float s = std::pow(10.0f, -6.0f * std::abs(u(rng)));  // distances 1e-6 .. 1 m
            const cv::Vec3f x = cv::normalize(cv::Vec3f(u(rng), u(rng), std::abs(u(rng)) + 0.01f)) * s;
            const cv::Vec3f n = cv::normalize(cv::Vec3f(u(rng), u(rng), -1.0f));
            const cv::Vec3f e = irradiance(l, x, n);
            ASSERT_TRUE(std::isfinite(e[0]) && e[0] >= 0) << P << " " << flux << " " << area << " " << s;
            const cv::Vec3f b = splatIrradiance(l, x, n, 1e-3f);
            ASSERT_TRUE(std::isfinite(b[0]) && b[0] >= 0);
          }
        }
}

TEST(SplatBounds, TheEllipseHoldsTheSignificantRegion) {
  for (float n : {0.5f, 1.0f, 2.0f, 10.0f, 100.0f, 1000.0f, 1e4f}) {
    const Ellipse e = boundingEllipse(n);
    EXPECT_NEAR(e.centre, std::pow(n / (n + 2), (n + 2) / 4), 1e-6);
    for (int i = 1; i < 20000; ++i) {
      const float x = i / 20000.0f, y = outline(x, n);
      const float q = (x - e.centre) / e.halfWidth, r = y / e.halfHeight;
      ASSERT_LE(q * q + r * r, 1.0f + 1e-3f) << "n " << n << " x " << x;
    }
  }
}

// Every light cut by its box sends less than I_low to any receiver outside it; so a pixel's bounded sum is
// within (lights) x I_low of the unbounded gather.
TEST(SplatBounds, NeverCutMoreThanILow) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  const float iLow = 0.01f;
  std::vector<PixelLight> lights;
  for (int i = 0; i < 64; ++i) {
    const cv::Vec3f n = cv::normalize(cv::Vec3f(u(rng), u(rng), 1.5f));
    PixelLight l = diffuseLight({0.2f * u(rng), 0.2f * u(rng), 0.05f * u(rng)}, n, 0.02f + 0.02f * u(rng), 1e-4f);
    if (i % 2) {
      const float P = std::pow(10.0f, 2.0f + 2.0f * u(rng));  // 1 .. 10^4
      l.exponent = P;
      l.axis = cv::normalize(cv::Vec3f(u(rng), u(rng), 2.0f));
      l.widen = i % 4 == 1 ? 0.02f : 0.0f;
    }
    lights.push_back(l);
  }
  int outside = 0;
  double worst = 0;
  for (int k = 0; k < 20000; ++k) {
    const cv::Vec3f x(1.5f * u(rng), 1.5f * u(rng), 1.5f * u(rng));
    const cv::Vec3f n = cv::normalize(cv::Vec3f(u(rng), u(rng), u(rng)));
    for (const PixelLight& l : lights) {
      if (insideBox(splatBox(l, iLow), x)) continue;
      ++outside;
      const float e = lum(irradiance(l, x, n));
      worst = std::max(worst, static_cast<double>(e));
      ASSERT_LT(e, iLow) << "light exponent " << l.exponent << " at " << x;
    }
    const float cut = lum(gather(lights, x, n)) - lum(gatherBounded(lights, x, n, iLow));
    ASSERT_LE(cut, lights.size() * iLow);
  }
  EXPECT_GT(outside, 100000);
  EXPECT_GT(worst, 0.2 * iLow);  // the boxes are not needlessly loose
}

TEST(SplatBounds, FarLevelsSplatTheOutermostBoxInExpectation) {
  // A light's n samples over L far levels sum to n times its splat over the outermost box (I_low / 16^L),
  // whatever n: each shell is splatted by ceil(n / 16^k) samples weighted n / that.
  EXPECT_EQ(farSamples(512, 0), 512);
  EXPECT_EQ(farSamples(512, 1), 32);
  EXPECT_EQ(farSamples(512, 2), 2);
  EXPECT_EQ(farSamples(512, 3), 1);
  EXPECT_EQ(farSamples(0, 2), 0);
  EXPECT_FLOAT_EQ(farWeight(1000, 1), 1000.0f / 63.0f);
  EXPECT_EQ(farWeight(0, 1), 0.0f);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  const float iLow = 0.05f;
  const PixelLight lights[] = {diffuseLight({0, 0, 0}, {0, 0, 1}, 0.02f),
                               glossyLight(200.0f, {0.3f, 0.0f, 1.0f}, 0.02f)};
  for (const PixelLight& l : lights)
    for (int levels : {0, 1, 2, 3})
      for (int n : {1, 7, 512, 1000}) {
        float deepest = iLow;
        for (int k = 0; k < levels; ++k) deepest /= kFarStride;
        int inFar = 0;
        for (int s = 0; s < 300; ++s) {
          const cv::Vec3f x(2.0f * u(rng), 2.0f * u(rng), 2.0f * u(rng));
          const cv::Vec3f nn = cv::normalize(cv::Vec3f(u(rng), u(rng), -1.0f));
          cv::Vec3f sum(0, 0, 0);
          for (int i = 0; i < n; ++i) sum += splatFar(l, x, nn, iLow, i, n, levels);
          const cv::Vec3f want = static_cast<float>(n) * splatIrradiance(l, x, nn, deepest);
          inFar += levels > 0 && !insideBox(splatBox(l, iLow), x) && want[0] > 0;
          // Float sums of up to 1000 weighted cross-faded samples.
          ASSERT_NEAR(sum[0], want[0], 3e-4f * std::abs(want[0]) + 1e-12f) << n << " samples, " << levels << " levels";
        }
        if (levels > 0) {
          EXPECT_GT(inFar, 0) << "no receiver in the far shells";
        }
      }
  // Each level reaches 4x as far: the diffuse box's extent along the normal.
  const PixelLight d = diffuseLight({0, 0, 0}, {0, 0, 1}, 0.02f);
  const float reach0 = splatBox(d, iLow).half[0], reach2 = splatBox(d, iLow / (kFarStride * kFarStride)).half[0];
  EXPECT_NEAR(reach2 / reach0, 16.0f, 1e-3f);
}

TEST(SplatBounds, AFarRepresentativeRampsInAcrossItsBoxInsteadOfASeam) {
  // The first of a light's 16 samples splats its own light inside its level-0 box and the whole light's
  // (x 16) in level 1's shell beyond it: across that face its contribution was a step of 15 times its own
  // light, a circle drawn on whatever the face crosses (the object). Cross-faded, it ramps over the fade band:
  // no step between points 1/2000 of the box apart is more than a few hundredths of the largest value.
  const float iLow = 0.05f;
  for (const PixelLight& l :
       {diffuseLight({0, 0, 0}, {0, 0, 1}, 0.02f), glossyLight(200.0f, {0.3f, 0.0f, 1.0f}, 0.02f)}) {
    const SplatBox b = splatBox(l, iLow);
    float largest = 0, step = 0, previous = -1;
    for (int i = 0; i <= 4000; ++i) {
      const float t = (0.5f + 1.0f * i / 4000.0f) * b.half[1];  // from inside the box to past its fade band
      const cv::Vec3f x = b.centre + t * b.axes[1];
      const cv::Vec3f n = cv::normalize(l.position - x);
      const float e = lum(splatFar(l, x, n, iLow, 0, 16, 1));
      largest = std::max(largest, e);
      if (previous >= 0) step = std::max(step, std::abs(e - previous));
      previous = e;
    }
    ASSERT_GT(largest, 0.f);
    EXPECT_LT(step, 0.02f * largest) << "exponent " << l.exponent;
  }
}

TEST(SplatBounds, FarLevelsCutLessOfADiffuseLightOnAPlane) {
  // A diffuse light 2 cm over a floor, its flux reaching the floor within 4 m: the fraction the splat misses
  // falls with each far level (in expectation over the samples: the outermost box's splat, as the test above
  // holds).
  PixelLight l = diffuseLight({0, 0, 0.02f}, {0.6f, 0.0f, -0.8f}, 1.0f, 1e-4f);
  const float iLow = 16.0f * lum(l.flux) / (CV_PI * 0.3f * 0.3f);  // the technique's default over a 30 cm region
  double missed[4] = {0, 0, 0, 0}, total = 0;
  const float step = 0.01f;
  for (float y = -4; y < 4; y += step)
    for (float x = -4; x < 4; x += step) {
      const cv::Vec3f p(x + step / 2, y + step / 2, 0), up(0, 0, 1);
      const float full = irradiance(l, p, up)[0];
      total += full;
      float cut = iLow;
      for (int levels = 0; levels < 4; ++levels, cut /= kFarStride)
        missed[levels] += full - splatIrradiance(l, p, up, cut)[0];
    }
  for (int k = 0; k < 4; ++k) missed[k] /= total;
  EXPECT_GT(missed[0], 0.1) << missed[0];  // a quarter of the region's side cuts a good part of a low light's bounce
  EXPECT_LT(missed[1], 0.3 * missed[0]) << missed[1];  // measured 0.17, 0.036, 0.007
  EXPECT_LT(missed[2], 0.3 * missed[1]) << missed[2];
  EXPECT_GE(missed[2], -1e-6);
}

TEST(SplatWarping, IsUnbiasedAndSamplesInProportionToTheImportance) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  cv::Mat f(48, 64, CV_64F), p(48, 64, CV_64F);  // not a power of two: padded
  double total = 0;
  for (int y = 0; y < f.rows; ++y)
    for (int x = 0; x < f.cols; ++x) {
      const double v = (x < 20 && y < 10) ? 0.0 : std::pow(u(rng), 3.0);
      f.at<double>(y, x) = v;
      p.at<double>(y, x) = v * (0.1 + 0.9 * u(rng));  // importance ∝ flux × (1 − AO)
      total += v;
    }
  // Importance equal to f: every sample returns the total exactly (zero variance).
  const Pyramid exact = buildPyramid(f);
  EXPECT_NEAR(warpedEstimate(exact, f, 7), total, total * 1e-9);
  // Importance unlike f: unbiased, within 1 % at 4096 samples.
  const Pyramid pyr = buildPyramid(p);
  EXPECT_NEAR(warpedEstimate(pyr, f, 4096), total, total * 0.01);
  // Sample counts follow the importance: texel frequencies over 2^18 samples against p / Σp.
  const int n = 1 << 18;
  cv::Mat count = cv::Mat::zeros(f.size(), CV_64F);
  double weightError = 0;
  const double sumP = cv::sum(p)[0];
  for (int i = 0; i < n; ++i) {
    const Warped s = warp(pyr, samplePoint(i));
    ASSERT_GE(s.texel.x, 0);
    ASSERT_LT(s.texel.x, f.cols);
    ASSERT_LT(s.texel.y, f.rows);
    ASSERT_GT(p.at<double>(s.texel), 0.0);  // never a texel of zero importance
    count.at<double>(s.texel) += 1;
    const double pdf = p.at<double>(s.texel) / sumP;
    weightError = std::max(weightError, std::abs(s.weight * 64.0 * 64.0 * pdf - 1.0));
  }
  EXPECT_LT(weightError, 1e-9);  // weight = 1 / (texels x pdf), texels of the padded 64 x 64 map
  double tv = 0;                 // total variation distance between the sampled and the intended distribution
  for (int y = 0; y < f.rows; ++y)
    for (int x = 0; x < f.cols; ++x) tv += std::abs(count.at<double>(y, x) / n - p.at<double>(y, x) / sumP);
  EXPECT_LT(0.5 * tv, 0.01);
  // An all-zero map gives no sample.
  const Warped none = warp(buildPyramid(cv::Mat::zeros(4, 4, CV_32F)), {0.3, 0.7});
  EXPECT_EQ(none.weight, 0.0);
  EXPECT_EQ(none.texel, cv::Point(-1, -1));
}

TEST(SplatWarping, ImportanceIsDefinedForEveryInput) {
  EXPECT_EQ(importance({1, 1, 1}, 1.0f, 0.0f), 0.0);
  EXPECT_NEAR(importance({1, 1, 1}, 0.5f, 0.0f), 0.5, 1e-6);
  EXPECT_NEAR(importance({1, 1, 1}, 0.0f, 99.0f), 100.0, 1e-4);
  EXPECT_EQ(importance({NAN, 1, 1}, 0.0f, 0.0f), 0.0);
  EXPECT_EQ(importance({INFINITY, 1, 1}, 0.0f, 0.0f), 0.0);
  EXPECT_GT(importance({-1, -1, -1}, 0.0f, 0.0f), 0.0);  // a subtracted light weighs by its magnitude
}

// A texel's occlusion in its RSM: 0 on an open plane, an empty texel or a zero reach; at the bottom of a pit
// (every neighbour raised above its tangent plane) it reaches its cap of 0.9, so it never leaves the sampling.
TEST(SplatOcclusion, IsZeroInTheOpenAndCappedInAPit) {
  cv::Mat pos(16, 16, CV_32FC4), nrm(16, 16, CV_32FC4, cv::Scalar(0, 0, 1, 0));
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) pos.at<cv::Vec4f>(y, x) = {0.01f * x, 0.01f * y, 0.0f, 1.0f};
  EXPECT_EQ(rsmOcclusion(pos, nrm, {8, 8}, 0.1f), 0.0f);
  // A pit: every other texel 5 cm above the centre.
  cv::Mat pit = pos.clone();
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x)
      if (x != 8 || y != 8) pit.at<cv::Vec4f>(y, x)[2] = 0.05f;
  const float deep = rsmOcclusion(pit, nrm, {8, 8}, 1.0f);
  EXPECT_GT(deep, 0.8f);
  EXPECT_LE(deep, 0.9f);
  EXPECT_EQ(rsmOcclusion(pit, nrm, {8, 8}, 0.0f), 0.0f);
  EXPECT_EQ(rsmOcclusion(pit, nrm, {8, 8}, 0.01f), 0.0f) << "all beyond reach";
  cv::Mat empty = pos.clone();
  empty.at<cv::Vec4f>(8, 8)[3] = 0.0f;
  EXPECT_EQ(rsmOcclusion(empty, nrm, {8, 8}, 1.0f), 0.0f);
  // At the map's corner half the neighbours are missing: finite, defined.
  EXPECT_TRUE(std::isfinite(rsmOcclusion(pit, nrm, {0, 0}, 1.0f)));
}

// A sharp glossy light 20 cm over a plane, its mirror direction 30° off the vertical: the brightest point
// of the plane is where that direction meets it.
TEST(SplatCaustic, ASharpLobeFocusesWhereItsMirrorDirectionMeetsThePlane) {
  const float a = 30.0f * static_cast<float>(CV_PI) / 180.0f;
  PixelLight l = glossyLight(1000.0f, {std::sin(a), 0, -std::cos(a)}, 0.01f);
  l.position = {0, 0, 0.2f};
  l.normal = cv::normalize(cv::Vec3f(0.3f, 0, -1));
  const cv::Vec3f want(0.2f * std::tan(a), 0, 0);
  float best = -1;
  cv::Vec3f at;
  for (int j = -100; j <= 100; ++j)
    for (int i = -100; i <= 100; ++i) {
      const cv::Vec3f x(0.002f * i, 0.002f * j, 0);
      const float e = irradiance(l, x, {0, 0, 1})[0];
      if (e > best) best = e, at = x;
    }
  EXPECT_LT(cv::norm(at - want), 0.006) << at;  // within a few grid steps (the receiver cosine pulls it in)
  // ... and it is focused: a lobe of exponent 10 spreads the same flux far wider.
  PixelLight wide = l;
  wide.exponent = 10.0f;
  EXPECT_GT(best, 20.0f * irradiance(wide, want, {0, 0, 1})[0]);
}

}  // namespace
}  // namespace mrgi::lighting::splat
