// Precomputed illuminance composition, the C++ reference (pic.h): surfels, hierarchy, links and the runtime
// against analytic results.
#include "lighting/techniques/pic/pic.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "lighting/sh.h"
#include "reconstruction/mesh_rays.h"

namespace mrgi::lighting::pic {
namespace {

/// An n x n grid of quads spanning `origin` + [0, 1] u + [0, 1] v, normal u x v, constant albedo.
void addGrid(SurfaceMesh& m, const cv::Vec3f& origin, const cv::Vec3f& u, const cv::Vec3f& v, int n,
             const cv::Vec3f& albedo) {
  const auto base = static_cast<uint32_t>(m.positions.size());
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      m.positions.push_back(origin + u * (static_cast<float>(i) / n) + v * (static_cast<float>(j) / n));
      m.albedo.push_back(albedo);
    }
  const auto at = [&](int i, int j) { return base + static_cast<uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      m.indices.insert(m.indices.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      m.indices.insert(m.indices.end(), {at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
}

/// A closed cube of side `side` centred at the origin, faces pointing inwards.
SurfaceMesh inwardBox(float side, int n, const cv::Vec3f& albedo) {
  SurfaceMesh m;
  const float h = side / 2;
  const cv::Vec3f X(side, 0, 0), Y(0, side, 0), Z(0, 0, side);
  addGrid(m, {-h, -h, -h}, X, Y, n, albedo);  // z = -h, normal +z
  addGrid(m, {-h, -h, h}, Y, X, n, albedo);   // z = +h, -z
  addGrid(m, {-h, -h, -h}, Z, X, n, albedo);  // y = -h, +y
  addGrid(m, {-h, h, -h}, X, Z, n, albedo);   // y = +h, -y
  addGrid(m, {-h, -h, -h}, Y, Z, n, albedo);  // x = -h, +x
  addGrid(m, {h, -h, -h}, Z, Y, n, albedo);   // x = +h, -x
  return m;
}

reconstruction::MeshRays raysOf(const SurfaceMesh& m) { return reconstruction::MeshRays(m.positions, m.indices); }

TEST(PicSurfels, TotalAreaIsTheMeshAreaAndEverySurfelLiesOnIt) {
  SurfaceMesh m;
  addGrid(m, {0, 0, 0}, {2, 0, 0}, {0, 1, 0}, 8, {0.5f, 0.4f, 0.3f});  // 2 m^2 on z = 0
  addGrid(m, {0, 0, 0}, {0, 0, 1}, {2, 0, 0}, 3, {0.2f, 0.2f, 0.2f});  // 2 m^2 on y = 0 (normal -y... u x v)
  const auto rays = raysOf(m);
  EXPECT_NEAR(meshArea(m), 4.0, 1e-5);
  for (int relax : {0, 3}) {
    const auto s = placeSurfels(m, {1000, relax}, &rays);
    ASSERT_EQ(s.size(), 1000u);
    double total = 0;
    int onFloor = 0;
    for (const Surfel& x : s) {
      total += x.area;
      const bool floor = std::abs(x.position[2]) < 1e-5f, wall = std::abs(x.position[1]) < 1e-5f;
      EXPECT_TRUE(floor || wall) << x.position;
      onFloor += floor && !wall;
      if (floor && !wall) {
        EXPECT_NEAR(x.albedo[0], 0.5f, 1e-5f);
      }
    }
    EXPECT_NEAR(total, 4.0, 1e-3);
    EXPECT_NEAR(onFloor, 500, 5);  // area-proportional
  }
}

TEST(PicSurfels, RelaxationEvensOutTheSpacing) {
  SurfaceMesh m;
  addGrid(m, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 40, {0.5f, 0.5f, 0.5f});
  const auto rays = raysOf(m);
  const auto halton = nearestNeighbourSpread(placeSurfels(m, {900, 0}, &rays));
  const auto relaxed = nearestNeighbourSpread(placeSurfels(m, {900, 4}, &rays));
  // 900 surfels of 1/900 m^2: a hexagonal packing spaces them 1.07 / 30 m apart.
  EXPECT_LT(relaxed.second, 0.8 * halton.second)
      << "coefficient of variation " << halton.second << " -> " << relaxed.second;
  EXPECT_GT(relaxed.first, halton.first);
  EXPECT_LT(relaxed.first, 1.1 / 30.0);
}

TEST(PicHierarchy, NodesSumTheirChildrenAndOppositeFacesMergeLast) {
  // A thin slab: two 1 x 1 faces 1 cm apart, facing away from each other.
  SurfaceMesh m;
  addGrid(m, {0, 0, 0}, {0, 1, 0}, {1, 0, 0}, 10, {0.5f, 0.5f, 0.5f});      // z = 0, normal -z
  addGrid(m, {0, 0, 0.01f}, {1, 0, 0}, {0, 1, 0}, 10, {0.5f, 0.5f, 0.5f});  // z = 0.01, normal +z
  const auto s = placeSurfels(m, {512, 0});
  const Hierarchy h = buildHierarchy(s);
  ASSERT_EQ(h.leaves, 512u);
  ASSERT_EQ(h.nodes.size(), 2 * 512u - 1);
  ASSERT_GE(h.root, 0);
  EXPECT_NEAR(h.nodes[static_cast<size_t>(h.root)].area, 2.0, 1e-3);
  std::set<int32_t> seen;
  for (size_t k = h.leaves; k < h.nodes.size(); ++k) {
    const Node& n = h.nodes[k];
    ASSERT_LT(n.child[0], static_cast<int32_t>(k));
    ASSERT_LT(n.child[1], static_cast<int32_t>(k));
    EXPECT_NEAR(n.area, h.nodes[static_cast<size_t>(n.child[0])].area + h.nodes[static_cast<size_t>(n.child[1])].area,
                1e-5);
    EXPECT_TRUE(seen.insert(n.child[0]).second && seen.insert(n.child[1]).second);  // a tree
    // Every node except the root holds surfels of one face only: its normal is still +-z.
    if (static_cast<int32_t>(k) != h.root) {
      EXPECT_GT(std::abs(n.normal[2]), 0.999f) << "node " << k << " area " << n.area;
    }
  }
  EXPECT_LE(h.levels(), 2 * 9 + 2);  // balanced: log2(512) = 9
}

TEST(PicLinks, OneSurfelFacingACacheGivesTheAnalyticIrradiance) {
  // One surfel of 4 cm^2 facing a cache at distance d along +z, radiance L = Phi / (pi A).
  SurfaceMesh m;
  addGrid(m, {-0.01f, -0.01f, 0}, {0, 0.02f, 0}, {0.02f, 0, 0}, 1, {1, 1, 1});  // normal -z, towards the cache below
  const auto rays = raysOf(m);
  const auto s = placeSurfels(m, {1, 0});
  ASSERT_EQ(s.size(), 1u);
  const Hierarchy h = buildHierarchy(s);
  const double A = 4e-4, flux = 2.0, L = flux / (CV_PI * A);
  for (int bands : {1, 2, 3, 4, 6, 8}) {
    for (double d : {0.05, 0.3, 1.0}) {
      const cv::Vec3f cache(s[0].position[0], s[0].position[1], static_cast<float>(-d));
      const CacheLinks links = linkCaches(h, s, rays, {cache}, {bands, 4, 1});
      const auto sh = gatherCaches(links, pullUp(h, {cv::Vec3f(flux, flux, flux)}), {});
      const double omega = A / (d * d + A / CV_PI);  // surfelSolidAngle at normal incidence
      // Band-limited: E_B(n) = L omega sum_l<B pi s_l(1) (2l+1)/(4 pi) P_l(cos theta), theta between n and +z.
      const std::vector<double> s1 = sh::phongLobeFactors(1.0, bands);
      for (double theta : {0.0, 0.5, 1.2, 2.5}) {
        const cv::Vec3f n(static_cast<float>(std::sin(theta)), 0, static_cast<float>(std::cos(theta)));
        double expect = 0;
        for (int l = 0; l < bands; ++l)
          expect += CV_PI * s1[static_cast<size_t>(l)] * (2 * l + 1) / (4 * CV_PI) * sh::legendre(l, std::cos(theta));
        expect *= L * omega;
        const cv::Vec3f e = shIrradiance(sh.data(), bands, n);
        EXPECT_NEAR(e[1], expect, 1e-4 * L * omega) << "bands " << bands << " d " << d << " theta " << theta;
      }
      if (bands >= 5) {
        // Enough bands: the true irradiance L omega cos(theta) at normal incidence within 4 %.
        EXPECT_NEAR(shIrradiance(sh.data(), bands, {0, 0, 1})[0], L * omega, 0.04 * L * omega);
      }
    }
  }
}

TEST(PicLinks, ACacheBehindAnOccluderSeesNothingThroughIt) {
  SurfaceMesh senders;
  addGrid(senders, {-0.5f, -0.5f, 1}, {0, 1, 0}, {1, 0, 0}, 4, {1, 1, 1});  // z = 1, facing -z
  SurfaceMesh all = senders;
  // An occluder at z = 0.5 larger than the senders seen from the cache.
  addGrid(all, {-2, -2, 0.5f}, {4, 0, 0}, {0, 4, 0}, 1, {0, 0, 0});
  const auto s = placeSurfels(senders, {64, 0});
  const Hierarchy h = buildHierarchy(s);
  const auto open = raysOf(senders), blocked = raysOf(all);
  const std::vector<cv::Vec3f> caches{{0, 0, 0}};
  const Ambient ambient{{0.3f, 0.3f, 0.3f}, {}, nullptr};
  const auto flux = pullUp(h, std::vector<cv::Vec3f>(64, cv::Vec3f(1, 1, 1)));
  const CacheLinks seen = linkCaches(h, s, open, caches, {3, 16, 1});
  const CacheLinks hidden = linkCaches(h, s, blocked, caches, {3, 16, 1});
  EXPECT_GT(shIrradiance(gatherCaches(seen, flux, {}).data(), 3, {0, 0, 1})[0], 0.1f);
  for (int32_t k : hidden.node) EXPECT_EQ(k, -1);
  const auto sh = gatherCaches(hidden, flux, ambient);
  for (const cv::Vec3f& c : sh) EXPECT_EQ(c, cv::Vec3f(0, 0, 0));  // neither light nor hidden ambient through it
}

TEST(PicRuntime, AFloorHidesTheAmbientBelowAndSendsBackItsReflection) {
  // Uniform ambient L over a large floor of albedo rho: a cache just above it sees the floor's radiance
  // rho L instead of L below: the irradiance about -z changes by -pi L (1 - rho), about +z by nothing.
  SurfaceMesh m;
  const float rho = 0.4f;
  addGrid(m, {-10, -10, 0}, {20, 0, 0}, {0, 20, 0}, 20, {rho, rho, rho});
  const auto rays = raysOf(m);
  const auto s = placeSurfels(m, {20000, 0});
  const Hierarchy h = buildHierarchy(s);
  const Ambient ambient{{0.5f, 0.5f, 0.5f}, {}, nullptr};
  const CacheLinks links = linkCaches(h, s, rays, {{0, 0, 0.3f}}, {4, 256, 1});
  const auto flux = pullUp(h, surfelFlux(s, {}, {}, ambient));
  const auto sh = gatherCaches(links, flux, ambient);
  const double L = 0.5;
  // The floor is 20 m wide: from 0.3 m it covers all but 0.1 % of the lower hemisphere (cosine-weighted).
  EXPECT_NEAR(shIrradiance(sh.data(), 4, {0, 0, -1})[0], -CV_PI * L * (1 - rho), 0.03 * CV_PI * L);
  EXPECT_NEAR(shIrradiance(sh.data(), 4, {0, 0, 1})[0], 0.0, 0.03 * CV_PI * L);
  EXPECT_LT(links.backFraction[0], 1e-6f);
  // The same cache below the floor sees its back: all of it is behind geometry.
  const CacheLinks below = linkCaches(h, s, rays, {{0, 0, -0.3f}}, {4, 256, 1});
  EXPECT_GT(below.backFraction[0], 0.999f);
}

TEST(PicRuntime, ClosedFurnaceConvergesToTheGeometricSeries) {
  // A closed box, albedo a everywhere, every surfel receiving E0: after k bounces every surfel receives
  // E0 (1 + a + ... + a^k), converging to E0 / (1 - a).
  const float a = 0.6f;
  const SurfaceMesh m = inwardBox(1.0f, 4, {a, a, a});
  const auto rays = raysOf(m);
  const auto s = placeSurfels(m, {1536, 0});
  const Hierarchy h = buildHierarchy(s);
  const Receivers r = bounceReceivers(h, 96);
  ASSERT_EQ(r.positions.size(), 96u);
  for (int32_t k : r.ofSurfel) ASSERT_GE(k, 0);
  const int bands = 3;
  const CacheLinks links = linkCaches(h, s, rays, r.positions, {bands, 192, 1});
  const float e0 = 1.0f;
  std::vector<cv::Vec3f> bounce(s.size(), cv::Vec3f(0, 0, 0));
  for (int k = 1; k <= 12; ++k) {
    std::vector<cv::Vec3f> e = bounce;
    for (cv::Vec3f& x : e) x += cv::Vec3f(e0, e0, e0);
    const auto flux = pullUp(h, surfelFlux(s, {}, {}, {}, e));
    bounce = bounceIrradiance(s, r, gatherCaches(links, flux, {}), bands);
    double mean = 0;
    for (const cv::Vec3f& b : bounce) mean += b[0];
    mean /= static_cast<double>(bounce.size());
    const double series = e0 * (1 - std::pow(a, k + 1)) / (1 - a);  // E0 + what came back after k bounces
    EXPECT_NEAR(e0 + mean, series, 0.025 * series) << "bounce " << k;
  }
}

TEST(PicCompression, FullChromaIsExactAndRgb9e5IsBounded) {
  std::vector<cv::Vec3f> sh;
  for (int i = 0; i < 3 * 16; ++i) sh.push_back({0.1f * i - 1.0f, std::sin(0.3f * i), 0.5f - 0.02f * i});
  const auto same = compressChroma(sh, 4, 4);
  for (size_t i = 0; i < sh.size(); ++i)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(same[i][c], sh[i][c], 1e-6f);
  // Fewer chroma bands: the luma of every coefficient stays, the chroma of the higher bands goes.
  const auto luma = compressChroma(sh, 4, 2);
  for (size_t i = 0; i < sh.size(); ++i) {
    EXPECT_NEAR(toYCoCg(luma[i])[0], toYCoCg(sh[i])[0], 1e-5f);
    if (i % 16 >= 4) {
      EXPECT_NEAR(luma[i][0], luma[i][2], 1e-5f);  // grey
    }
  }
  // RGB9E5: each channel within half a step of the shared exponent (max channel / 512).
  for (const cv::Vec3f& v : {cv::Vec3f(1, 0.5f, 0.25f), cv::Vec3f(1e-3f, 2e-3f, 3e-3f), cv::Vec3f(1000, 1, 0),
                             cv::Vec3f(60000, 3, 7), cv::Vec3f(0, 0, 0)}) {
    const cv::Vec3f u = unpackRgb9e5(packRgb9e5(v));
    const float step = std::max({v[0], v[1], v[2]}) / 256.0f;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(u[c], v[c], step + 1e-30f) << v;
  }
  EXPECT_EQ(unpackRgb9e5(packRgb9e5({-1, NAN, 2})), unpackRgb9e5(packRgb9e5({0, 0, 2})));
  EXPECT_NEAR(unpackRgb9e5(packRgb9e5({1e30f, 0, 0}))[0], 65408.0f, 1.0f);
}

TEST(PicExtremes, BandsOneToEightExponentsAndFluxesStayFinite) {
  SurfaceMesh m;
  addGrid(m, {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, 2, {0.8f, 0.8f, 0.8f});
  const auto rays = raysOf(m);
  const auto s = placeSurfels(m, {64, 1}, &rays);
  const Hierarchy h = buildHierarchy(s);
  for (int bands = 1; bands <= 8; ++bands) {
    // Caches on the floor itself (d -> 0 to a surfel), just above and far away.
    const CacheLinks links =
        linkCaches(h, s, rays, {s[0].position, {0, 0, 1e-6f}, {0, 0, 0.1f}, {0, 0, 1e4f}}, {bands, 8, 2});
    for (float f : {0.0f, 1.0f, 1e20f}) {
      const auto sh = gatherCaches(links, pullUp(h, std::vector<cv::Vec3f>(s.size(), cv::Vec3f(f, f, f))),
                                   {{1, 1, 1}, {}, nullptr});
      for (size_t c = 0; c < links.caches(); ++c)
        for (double p : {0.0, 1.0, 10.0, 1e4})
          for (const cv::Vec3f& n : {cv::Vec3f(0, 0, 1), cv::Vec3f(0, 0, -1), cv::Vec3f(1, 0, 0)}) {
            const cv::Vec3f e = shIrradiance(&sh[c * static_cast<size_t>(bands * bands)], bands, n);
            const cv::Vec3f g = shLobeRadiance(&sh[c * static_cast<size_t>(bands * bands)], bands, n, p);
            for (int k = 0; k < 3; ++k) {
              ASSERT_TRUE(std::isfinite(e[k]) && std::isfinite(g[k])) << bands << " " << f << " " << p;
              ASSERT_LT(std::abs(g[k]), 1e30f);
            }
          }
    }
  }
  // Empty geometry: nothing to place, cluster or link.
  EXPECT_TRUE(placeSurfels({}, {}).empty());
  const Hierarchy none = buildHierarchy({});
  EXPECT_EQ(none.root, -1);
  const CacheLinks nothing = linkCaches(none, {}, rays, {{0, 0, 1}}, {});
  EXPECT_EQ(gatherCaches(nothing, {}, {})[0], cv::Vec3f(0, 0, 0));
}

}  // namespace
}  // namespace mrgi::lighting::pic
