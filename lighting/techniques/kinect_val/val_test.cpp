// Kinect-VAL reference math (lighting/val.h): analytic disc lights, guards, renormalisation, sparse vs brute
// force, occlusion, sparse sampling, k-d tree weights, RGB-D VALs and surfel fusion.
#include "lighting/techniques/kinect_val/val.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lighting/techniques/kinect_val/real_vals.h"

using namespace mrgi;
using lighting::Val;

namespace {

Val disc(const cv::Vec3f& p, const cv::Vec3f& n, float radius, const cv::Vec3f& flux) {
  Val v;
  v.position = p;
  v.normal = cv::normalize(n);
  v.area = static_cast<float>(CV_PI) * radius * radius;
  v.flux = flux;
  return v;
}

lighting::Receiver receiver(const cv::Vec3f& p, const cv::Vec3f& n, const cv::Vec3f& view = {0, 0, 1}, float k = 0) {
  return {p, cv::normalize(n), cv::normalize(view), k};
}

bool finite(const cv::Vec3f& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

/// A flat square grid (z = 0, normal +z) of n×n vertices over [-s, s]².
lighting::Mesh grid(int n, float s) {
  lighting::Mesh m;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      m.positions.emplace_back(-s + 2 * s * x / (n - 1), -s + 2 * s * y / (n - 1), 0.f);
      m.normals.emplace_back(0.f, 0.f, 1.f);
    }
  for (int y = 0; y + 1 < n; ++y)
    for (int x = 0; x + 1 < n; ++x) {
      const uint32_t a = y * n + x, b = a + 1, c = a + n, d = c + 1;
      m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
    }
  m.computeBounds();
  return m;
}

}  // namespace

TEST(Val, OnAxisDiscIrradianceIsExact) {
  // Lambertian disc of exitance M: on its axis at distance d, E = M r² / (d² + r²) exactly.
  for (float d : {1e-4f, 0.01f, 0.1f, 1.f, 10.f})
    for (float r : {0.001f, 0.05f, 0.5f}) {
      const Val v = disc({0, 0, d}, {0, 0, -1}, r, {2, 1, 0.5f});
      const auto g = lighting::gatherReference(receiver({0, 0, 0}, {0, 0, 1}), {v});
      const float M = 2.f / v.area;
      EXPECT_NEAR(g.E[0], M * r * r / (d * d + r * r), 1e-5 * M) << d << " " << r;
      EXPECT_NEAR(g.E[1] / g.E[0], 0.5f, 1e-6);
      EXPECT_NEAR(lighting::discFormFactor(v, {0, 0, 0}), r * r / (d * d + r * r), 1e-6);
    }
}

TEST(Val, FarDiscIsAPointLightAndNearDiscIsBounded) {
  // Far field: E = φ cos ϑ_j cos ϑ_i / (π d²).
  const Val v = disc({0.3f, 0.f, 2.f}, {0.2f, 0.1f, -1.f}, 0.001f, {1, 1, 1});
  const cv::Vec3f n = cv::normalize(cv::Vec3f(0.1f, 0.f, 1.f));
  const auto g = lighting::gatherReference(receiver({0, 0, 0}, n), {v});
  const cv::Vec3f dir = v.position;
  const float d = static_cast<float>(cv::norm(dir));
  const float expected = v.normal.dot(-dir / d) * n.dot(dir / d) / (static_cast<float>(CV_PI) * d * d);
  EXPECT_NEAR(g.E[0] / expected, 1.f, 1e-5);
  // A disc touching the receiver: finite and at most its exitance, also at the exact centre.
  for (float d0 : {1e-3f, 1e-6f, 1e-12f, 0.f}) {
    const Val t = disc({0, 0, d0}, {0, 0, -1}, 0.01f, {1, 1, 1});
    for (float k : {0.f, 1.f, 100.f, 1e4f}) {
      const auto h = lighting::gatherReference(receiver({0, 0, 0}, {0, 0, 1}, {0, 0, 1}, k), {t});
      EXPECT_TRUE(finite(h.E) && finite(h.S) && finite(h.ld) && finite(h.ls));
      EXPECT_LE(h.E[0], 1.f / t.area * 1.0001f);
      EXPECT_LE(h.S[0], 1.f / t.area * 1.0001f);
    }
  }
}

TEST(Val, NothingReachesThePoint) {
  // Lights behind the receiver, or facing away: zero light, finite VPLs, no NaN anywhere.
  const std::vector<Val> vals = {disc({0, 0, -1}, {0, 0, 1}, 0.1f, {5, 5, 5}),
                                 disc({0, 0, 1}, {0, 0, 1}, 0.1f, {5, 5, 5})};
  for (const auto& set : {vals, std::vector<Val>{}}) {
    const auto r = receiver({0, 0, 0}, {0, 0, 1}, {0, 0, 1}, 50);
    const auto g = lighting::gatherReference(r, set);
    EXPECT_EQ(g.E, cv::Vec3f(0, 0, 0));
    EXPECT_EQ(g.S, cv::Vec3f(0, 0, 0));
    const auto vpl = lighting::normalizeReference(g, r);
    EXPECT_TRUE(finite(vpl.ld) && finite(vpl.ls) && std::isfinite(vpl.radiusD));
    EXPECT_EQ(vpl.Ld, cv::Vec3f(0, 0, 0));
    cv::Vec3f E, S;
    lighting::evaluateVpl(vpl, receiver({0.1f, 0, 0}, {0, 0, 1}), E, S);
    EXPECT_EQ(E, cv::Vec3f(0, 0, 0));
    EXPECT_EQ(S, cv::Vec3f(0, 0, 0));
  }
}

TEST(Val, RenormalisedVplsReproduceTheGatherAtThePoint) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<Val> vals;
    for (int i = 0; i < 50; ++i)
      vals.push_back(disc({u(rng), u(rng), 1.f + 0.5f * u(rng)}, {0.3f * u(rng), 0.3f * u(rng), -1.f}, 0.02f,
                          {1.f + u(rng), 1.f, 0.5f}));
    lighting::setValWeights(vals);
    const float k = trial < 10 ? 0.f : 8.f;
    const auto r =
        receiver({0.2f * u(rng), 0.2f * u(rng), 0}, {0.2f * u(rng), 0.2f * u(rng), 1.f}, {u(rng), u(rng), 1.f}, k);
    const auto g = lighting::gatherReference(r, vals);
    const auto vpl = lighting::normalizeReference(g, r);
    cv::Vec3f E, S;
    lighting::evaluateVpl(vpl, r, E, S);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(E[c], g.E[c], 1e-4 * g.E[c]) << trial;
    if (g.S[0] > 0) {
      // Exact whenever the averaged glossy light is inside the lobe by more than the guard.
      const cv::Vec3f ds = cv::normalize(vpl.ls - r.position);
      const cv::Vec3f refl = 2.f * r.normal.dot(r.view) * r.normal - r.view;
      if (std::pow(refl.dot(ds), k) > lighting::kValMinLobe) {
        EXPECT_NEAR(S[0], g.S[0], 1e-4 * g.S[0]) << trial;
      }
    }
  }
}

TEST(Val, SparseEqualsBruteForceWhenEveryVertexIsASparsePoint) {
  const lighting::Mesh mesh = grid(9, 0.2f);
  lighting::SparsePoints pts;
  pts.positions = mesh.positions;
  pts.normals = mesh.normals;
  pts.discRadius.assign(pts.positions.size(), 0.01f);
  const auto w = lighting::vertexWeights(mesh, pts);
  std::vector<Val> one = {disc({0.05f, -0.1f, 0.3f}, {0.1f, 0.2f, -1.f}, 0.03f, {0.7f, 0.5f, 0.2f})};
  lighting::setValWeights(one);
  const cv::Vec3f eye(0.4f, 0.3f, 1.f);
  std::vector<lighting::SparseVpl> sparse;
  for (size_t i = 0; i < pts.positions.size(); ++i) {
    const auto r = receiver(pts.positions[i], pts.normals[i], eye - pts.positions[i], 20.f);
    sparse.push_back(lighting::normalizeReference(lighting::gatherReference(r, one), r));
  }
  float maxS = 0;
  for (const auto& p : mesh.positions)
    maxS = std::max(maxS, lighting::gatherReference(receiver(p, {0, 0, 1}, eye - p, 20.f), one).S[0]);
  ASSERT_GT(maxS, 0.f);
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    const auto r = receiver(mesh.positions[v], mesh.normals[v], eye - mesh.positions[v], 20.f);
    const auto brute = lighting::gatherReference(r, one);
    cv::Vec3f E, S;
    lighting::evaluateVpl(lighting::interpolateVpl(w, v, sparse), r, E, S);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(E[c], brute.E[c], 1e-5 * brute.E[0]) << v;
      // Exact where the light is inside the lobe by more than the guard (kValMinLobe); outside it the VPL is
      // damped, never brightened, and off by < 1 % of the highlight.
      EXPECT_LE(S[c], brute.S[c] * 1.0001f + 1e-12f) << v;
      EXPECT_NEAR(S[c], brute.S[c], 1e-2 * maxS) << v;
    }
  }
}

TEST(Val, PhongExponentsFromOneToTenThousandStayFiniteAndBounded) {
  std::vector<Val> vals = {disc({0, 0, 0.5f}, {0, 0, -1}, 0.05f, {1, 1, 1}),
                           disc({0.3f, 0, 0.01f}, {-1, 0, 0}, 0.05f, {1, 1, 1})};
  lighting::setValWeights(vals);
  for (float k : {0.f, 1.f, 10.f, 100.f, 1000.f, 1e4f}) {
    for (const cv::Vec3f& view : {cv::Vec3f(0, 0, 1), cv::Vec3f(1, 0, 0.01f), cv::Vec3f(0.3f, 0.2f, 1)}) {
      const auto r = receiver({0, 0, 0}, {0, 0, 1}, view, k);
      const auto g = lighting::gatherReference(r, vals);
      const auto vpl = lighting::normalizeReference(g, r);
      cv::Vec3f E, S;
      lighting::evaluateVpl(vpl, receiver({0.01f, 0, 0}, {0, 0, 1}, view, k), E, S);
      const cv::Vec3f L = lighting::valRadiance(E, S, {0.8f, 0.8f, 0.8f}, {0.5f, 0.5f, 0.5f}, k);
      EXPECT_TRUE(finite(g.S) && finite(vpl.Ls) && finite(vpl.ls) && finite(E) && finite(S) && finite(L)) << k;
      // Bounded: the glossy sum never exceeds the exitance sum, the VPL reproduces at most 1/kValMinCos of it.
      EXPECT_LE(g.S[0], 2.f / vals[0].area * 1.0001f);
      EXPECT_LE(S[0], g.S[0] / lighting::kValMinLobe * 1.01f + 1e-6f);
    }
  }
  EXPECT_EQ(lighting::phongExponent(1.f), 0.f);
  EXPECT_EQ(lighting::phongExponent(0.f), lighting::kMaxPhongExponent);
  EXPECT_NEAR(lighting::phongExponent(0.5f), 6.f, 1e-5);
}

TEST(Val, WallOfPixelVALsGivesPiTimesRadiance) {
  // A camera 1 m in front of a wide wall of uniform radiance L: the pixel VALs, summed at a receiver 10 cm in
  // front of the wall's centre and facing it, give E = π L F (F: the rectangle's form factor).
  const capture::Intrinsics k{320, 240, 80.0, 80.0, 159.5, 119.5};  // wide view: ±2 m at 1 m
  cv::Mat depth(240, 320, CV_32FC3), normals(240, 320, CV_32FC3),
      colour(240, 320, CV_32FC3, cv::Scalar(0.2, 0.1, 0.05));
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x) {
      depth.at<cv::Vec3f>(y, x) =
          cv::Vec3f(static_cast<float>((x - k.cx) / k.fx), static_cast<float>((y - k.cy) / k.fy), 1.f);
      normals.at<cv::Vec3f>(y, x) = cv::Vec3f(0, 0, -1);
    }
  const auto vals = lighting::valsFromRgbd(depth, normals, colour, k, capture::identityPose(), 1);
  ASSERT_EQ(vals.size(), 320u * 240u);
  double area = 0;
  for (const auto& v : vals) area += v.area;
  EXPECT_NEAR(area, (320 / 80.0) * (240 / 80.0), 1e-3);  // the wall's seen area, m²
  const auto g = lighting::gatherReference(receiver({0, 0, 0.9f}, {0, 0, 1}), vals);
  // Analytic: point-to-parallel-rectangle form factor, 4 quarters of 2 m × 1.5 m at h = 0.1 m.
  const double a = 2.0 / 0.1, b = 1.5 / 0.1;
  const double F = 4 *
                   (a / std::sqrt(1 + a * a) * std::atan(b / std::sqrt(1 + a * a)) +
                    b / std::sqrt(1 + b * b) * std::atan(a / std::sqrt(1 + b * b))) /
                   (2 * CV_PI);
  EXPECT_NEAR(g.E[0] / (CV_PI * 0.2 * F), 1.0, 0.01);
  EXPECT_NEAR(g.E[2] / g.E[0], 0.25, 1e-4);
  // Stride 4: the same light from 16× fewer VALs.
  const auto sparse = lighting::valsFromRgbd(depth, normals, colour, k, capture::identityPose(), 4);
  EXPECT_EQ(sparse.size(), 80u * 60u);
  const auto g4 = lighting::gatherReference(receiver({0, 0, 0.8f}, {0, 0, 1}), sparse);
  const auto g1 = lighting::gatherReference(receiver({0, 0, 0.8f}, {0, 0, 1}), vals);
  EXPECT_NEAR(g4.E[0] / g1.E[0], 1.0, 0.02);  // 5 cm VALs 20 cm away
}

TEST(Val, TheRoomsValsCarryItsFluxAndLightAReceiverAsTheWallDoes) {
  // The fused room as a wall 4 m x 3 m (a 2 cm grid mesh at z = 1, normals towards -z) of radiance L, with
  // a saturated patch (a lamp): the room's VALs (4 cm cells) hold π L A of the rest, and light a receiver
  // 20 cm in front of the wall's centre as the wall does (E = π L F).
  reconstruction::RoomMesh room;
  const int nx = 200, ny = 150;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      room.positions.emplace_back(-2.f + 0.02f * i, -1.5f + 0.02f * j, 1.f);
      room.normals.emplace_back(0.f, 0.f, -1.f);
      room.radiance.emplace_back(0.2f, 0.1f, 0.05f);
      room.confidence.push_back(1.f);
      const bool lamp = i >= 180 && j >= 130;  // a corner 40 cm x 40 cm, seen only clipped
      room.saturated.push_back(lamp ? 1 : 0);
      if (lamp) room.radiance.back() = {5.f, 5.f, 5.f};
    }
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const uint32_t a = static_cast<uint32_t>(j * (nx + 1) + i), b = a + 1, c = a + nx + 2, d = a + nx + 1;
      room.indices.insert(room.indices.end(), {a, c, b, a, d, c});
    }
  const auto vals = lighting::valsFromRoom(room);
  double area = 0;
  cv::Vec3d flux(0, 0, 0);
  for (const auto& v : vals) {
    area += v.area, flux += cv::Vec3d(v.flux);
    ASSERT_NEAR(v.normal[2], -1.f, 1e-5f);
  }
  // The saturated vertices and half the area of the triangles touching them are left out.
  EXPECT_LT(area, 12.0 - 0.38 * 0.38);
  EXPECT_GT(area, 12.0 - 0.42 * 0.42);
  EXPECT_NEAR(flux[0] / (CV_PI * 0.2 * area), 1.0, 1e-4);
  EXPECT_NEAR(flux[2] / flux[0], 0.25, 1e-5);
  const auto g = lighting::gatherReference(receiver({0, 0, 0.8f}, {0, 0, 1}), vals);
  const double a = 2.0 / 0.2, b = 1.5 / 0.2;
  const double F = 4 *
                   (a / std::sqrt(1 + a * a) * std::atan(b / std::sqrt(1 + a * a)) +
                    b / std::sqrt(1 + b * b) * std::atan(a / std::sqrt(1 + b * b))) /
                   (2 * CV_PI);
  EXPECT_NEAR(g.E[0] / (CV_PI * 0.2 * F), 1.0, 0.02);  // the lamp corner is 2 m off, a sliver of F
  // At most maxVals: the cells grow; the flux stays.
  const auto few = lighting::valsFromRoom(room, 0.04f, 100);
  EXPECT_LE(few.size(), 100u);
  cv::Vec3d fewFlux(0, 0, 0);
  for (const auto& v : few) fewFlux += cv::Vec3d(v.flux);
  EXPECT_NEAR(fewFlux[0] / flux[0], 1.0, 1e-4);
  // Triangles cleared around a light give none; an empty room gives none.
  const std::vector<uint32_t> none;
  EXPECT_TRUE(lighting::valsFromRoom(room, 0.04f, 16384, &none).empty());
  EXPECT_TRUE(lighting::valsFromRoom(reconstruction::RoomMesh{}).empty());
}

TEST(Val, SparsePointsAreAreaUniformOnTheSurface) {
  // Two triangles of areas 1 and 3 (z = 0): points split 1 : 3, all on the plane, inside the triangles.
  lighting::Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}, {0, 0, 0}, {3, 0, 0}, {0, -2, 0}};
  m.normals.assign(6, cv::Vec3f(0, 0, 1));
  m.indices = {0, 1, 2, 3, 5, 4};
  m.computeBounds();
  const auto pts = lighting::sampleSparsePoints(m, 400);
  ASSERT_EQ(pts.positions.size(), 400u);
  int upper = 0;
  for (const auto& p : pts.positions) {
    EXPECT_EQ(p[2], 0.f);
    upper += p[1] > 0;
    if (p[1] > 0)
      EXPECT_LE(p[0] + p[1] / 2, 1.0001f);
    else
      EXPECT_LE(p[0] / 3 - p[1] / 2, 1.0001f);
  }
  EXPECT_EQ(upper, 100);
  // Low discrepancy: no two points closer than a fraction of the mean spacing on this plane.
  float closest = 1e9f;
  for (size_t i = 0; i < pts.positions.size(); ++i)
    for (size_t j = i + 1; j < pts.positions.size(); ++j)
      closest = std::min(closest, static_cast<float>(cv::norm(pts.positions[i] - pts.positions[j])));
  EXPECT_GT(closest, 0.1f * std::sqrt(4.f / 400.f));
}

TEST(Val, KdTreeNeighboursMatchABruteForceSearch) {
  const lighting::Mesh mesh = grid(21, 1.f);
  auto pts = lighting::sampleSparsePoints(mesh, 64);
  const auto w = lighting::vertexWeights(mesh, pts);
  for (size_t v = 0; v < mesh.positions.size(); v += 7) {
    std::vector<std::pair<float, int>> all;
    for (size_t j = 0; j < pts.positions.size(); ++j)
      all.emplace_back(static_cast<float>(cv::norm(pts.positions[j] - mesh.positions[v])), static_cast<int>(j));
    std::sort(all.begin(), all.end());
    float sum = 0;
    for (int j = 0; j < 8; ++j) {
      EXPECT_NEAR(cv::norm(pts.positions[w.index[v * 8 + j]] - mesh.positions[v]), all[j].first, 1e-6) << v;
      sum += w.weight[v * 8 + j];
      EXPECT_GE(w.weight[v * 8 + j], 0.f);
    }
    EXPECT_NEAR(sum, 1.f, 1e-5);
    EXPECT_EQ(w.weight[v * 8 + 7], 0.f);  // the farthest of the eight has weight 1 - d/d_max = 0
  }
  for (float r : pts.discRadius) EXPECT_GT(r, 0.f);
}

TEST(Val, DiscOccludersShadowTheLightBetweenThemOnly) {
  // Receiver point at the origin facing up; the averaged light 1 m above with spread 0.1 m.
  auto occluded = [](const cv::Vec3f& occ, float radius) {
    std::vector<cv::Vec3f> pos = {{0, 0, 0}, occ}, nrm = {{0, 0, 1}, {0, 0, -1}};
    std::vector<float> rad = {0.01f, radius};
    std::vector<lighting::SparseVpl> vpl(2);
    vpl[0].ld = vpl[0].ls = {0, 0, 1};
    vpl[0].radiusD = vpl[0].radiusS = 0.1f;
    vpl[0].Ld = vpl[0].Ls = {1, 1, 1};
    vpl[1].ld = vpl[1].ls = {0, 0, 2};
    lighting::occludeReference(pos, nrm, rad, vpl);
    return vpl[0].Ld[0];
  };
  EXPECT_NEAR(occluded({0, 0, 0.5f}, 0.3f), 0.f, 1e-6);  // a big disc halfway: fully occluded
  EXPECT_NEAR(occluded({0, 0, 0.5f}, 0.0f), 1.f, 1e-6);  // a zero disc: nothing
  const float partial = occluded({0, 0, 0.5f}, 0.03f);   // a small disc: partly
  EXPECT_GT(partial, 0.05f);
  EXPECT_LT(partial, 0.95f);
  EXPECT_NEAR(occluded({0, 0, 1.5f}, 0.3f), 1.f, 1e-6);     // beyond the light: nothing
  EXPECT_NEAR(occluded({2.f, 0, 0.5f}, 0.05f), 1.f, 1e-6);  // off to the side: nothing
  EXPECT_NEAR(occluded({0, 0, -0.5f}, 0.3f), 1.f, 1e-6);    // below the receiver: nothing
  const float inside = occluded({0, 0, 0.95f}, 0.3f);       // inside the light sphere: faded
  EXPECT_GT(inside, 0.f);
  EXPECT_LT(inside, 1.f);
}

TEST(Val, SurfelFusionKeepsUnseenSurfacesAndAveragesNoise) {
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.f, 0.1f);
  auto frame = [&](float n) {
    std::vector<Val> v;
    for (int i = 0; i < 10; ++i)
      v.push_back(
          disc({0.1f * i + 0.05f, 0.05f, 0.05f}, {0, 0, 1}, 0.01f, cv::Vec3f(1, 1, 1) * (1.f + n * noise(rng))));
    return v;
  };
  lighting::SurfelOptions o;
  o.voxel = 0.1f;
  lighting::SurfelMap map(o);
  double rawVar = 0, fusedVar = 0;
  float prevRaw = 0, prevFused = 0;
  for (int f = 0; f < 40; ++f) {
    const auto v = frame(1.f);
    map.integrate(v);
    const auto fused = map.vals();
    ASSERT_EQ(fused.size(), 10u);
    if (f > 10) {
      rawVar += std::pow(v[0].flux[0] - prevRaw, 2);
      float fv = 0;
      for (const auto& s : fused)
        if (s.position[0] < 0.1f) fv = s.flux[0];
      fusedVar += std::pow(fv - prevFused, 2);
    }
    prevRaw = v[0].flux[0];
    for (const auto& s : fused)
      if (s.position[0] < 0.1f) prevFused = s.flux[0];
  }
  EXPECT_LT(fusedVar, 0.2 * rawVar);  // frame-to-frame change of the fused light is far smaller
  // The camera turns away (the surfels project outside the image): they keep their light.
  const capture::Intrinsics k{64, 48, 50, 50, 31.5, 23.5};
  const cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(1.f));
  const capture::Pose away = capture::lookAtPose({0, 0, 0.05f}, {0, -5, 0.05f});
  for (int f = 0; f < 100; ++f) map.integrate({}, depth, k, away);
  EXPECT_EQ(map.vals().size(), 10u);
  // The camera looks at them and they are gone (depth valid behind them): they fade out.
  const capture::Pose at = capture::lookAtPose({0.5f, 0.05f, 1.0f}, {0.5f, 0.05f, 0.f});
  const cv::Mat far(48, 64, CV_32FC1, cv::Scalar(2.f));
  map.integrate({}, far, k, at);
  EXPECT_EQ(map.vals().size(), 0u);  // decay 0: one frame that should have seen them removes them

  // Depth noise moves the same surface across a voxel boundary between two frames: its light counts once.
  lighting::SurfelMap jitter(o);
  const cv::Mat seen(48, 64, CV_32FC1, cv::Scalar(1.f));  // the surface 1 m in front of `at2`
  const capture::Pose at2 = capture::lookAtPose({0.1f, 0.05f, 1.05f}, {0.1f, 0.05f, 0.f});
  jitter.integrate({disc({0.099f, 0.05f, 0.05f}, {0, 0, 1}, 0.01f, {1, 1, 1})}, seen, k, at2);
  jitter.integrate({disc({0.101f, 0.05f, 0.05f}, {0, 0, 1}, 0.01f, {1, 1, 1})}, seen, k, at2);
  float area = 0;
  for (const auto& v : jitter.vals()) area += v.area;
  EXPECT_FLOAT_EQ(area, disc({0, 0, 0}, {0, 0, 1}, 0.01f, {1, 1, 1}).area);
}

// ------------------------------------------------------------------------------------------- GPU twin

#include "gl/context.h"
#include "lighting/techniques/kinect_val/val_gpu.h"

namespace {
std::unique_ptr<gl::Context> smallContext() {
  gl::ContextConfig cfg;
  cfg.width = 16, cfg.height = 16;
  return gl::createContext(cfg);
}

std::vector<Val> randomVals(int n, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Val> vals;
  for (int i = 0; i < n; ++i)
    vals.push_back(disc({u(rng), u(rng), 0.6f + 0.5f * u(rng)}, {0.4f * u(rng), 0.4f * u(rng), -1.f},
                        0.005f + 0.02f * (u(rng) + 1), {0.5f + 0.5f * u(rng), 0.4f, 0.3f + 0.2f * u(rng)}));
  // A few touching the receivers' plane and one far away.
  vals.push_back(disc({0.01f, 0.f, 1e-4f}, {0, 0, -1}, 0.01f, {1, 1, 1}));
  vals.push_back(disc({50.f, 3.f, 20.f}, {-1, 0, -0.3f}, 0.5f, {2, 2, 2}));
  lighting::setValWeights(vals);
  return vals;
}
}  // namespace

TEST(GL, ValGatherMatchesTheCpuReference) {
  auto ctx = smallContext();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  const auto vals = randomVals(700, rng);
  std::vector<lighting::Receiver> rec;
  for (int i = 0; i < 150; ++i) {
    const float k = std::pow(10.f, 4.f * i / 150.f) - 1.f;  // 0 .. 1e4
    rec.push_back(receiver({0.5f * u(rng), 0.5f * u(rng), 0.1f * u(rng)}, {0.3f * u(rng), 0.3f * u(rng), 1.f},
                           {u(rng), u(rng), 1.f}, k));
  }
  for (int kCache : {16, 128, 512}) {
    lighting::ValGpu gpu(kCache);
    gpu.setVals(vals);
    gpu.gather(rec);
    const auto vpls = gpu.downloadVpls();
    std::vector<cv::Vec3f> E, S;
    gpu.downloadSums(E, S);
    ASSERT_EQ(vpls.size(), rec.size());
    for (size_t i = 0; i < rec.size(); ++i) {
      const auto g = lighting::gatherReference(rec[i], vals);
      const auto ref = lighting::normalizeReference(g, rec[i]);
      auto near = [&](const cv::Vec3f& a, const cv::Vec3f& b, double rel, const char* what) {
        EXPECT_LE(cv::norm(a - b), rel * std::max(cv::norm(b), 1e-12)) << what << " receiver " << i << " K " << kCache;
      };
      near(E[i], g.E, 1e-4, "E");
      // cos^k = exp(k log cos) in float on both sides: the relative error grows with k (≈ k · 1e-7).
      const double lobeTol = 3e-7 * rec[i].exponent;
      near(S[i], g.S, 1e-3 + lobeTol, "S");
      near(vpls[i].Ld, ref.Ld, 1e-3, "Ld");
      near(vpls[i].ld, ref.ld, 1e-4, "ld");
      near(vpls[i].Ls, ref.Ls, 2e-3 + 2 * lobeTol, "Ls");
      near(vpls[i].ls, ref.ls, 1e-4, "ls");
      EXPECT_NEAR(vpls[i].radiusD, ref.radiusD, 1e-3 * std::max(ref.radiusD, 1e-3f));
    }
  }
  // Occlusion: receivers as disc occluders of each other.
  lighting::ValGpu gpu(64);
  gpu.setVals(vals);
  std::vector<lighting::Receiver> pts;
  std::vector<cv::Vec3f> pos, nrm;
  std::vector<float> rad;
  for (int i = 0; i < 200; ++i) {  // two facing plates: floor z = 0 and a lid z = 0.3 with a hole
    const bool lid = i >= 120;
    const cv::Vec3f p(0.6f * u(rng), 0.6f * u(rng), lid ? 0.3f : 0.f);
    pts.push_back(receiver(p, {0, 0, lid ? -1.f : 1.f}, {0.1f, 0.f, 1.f}, 5.f));
    pos.push_back(p);
    nrm.push_back(pts.back().normal);
    rad.push_back(0.06f);
  }
  gpu.gather(pts);
  auto ref = gpu.downloadVpls();
  lighting::occludeReference(pos, nrm, rad, ref);
  gpu.occlude(pos, nrm, rad);
  const auto got = gpu.downloadVpls();
  int partly = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    EXPECT_NEAR(got[i].occlusionD, ref[i].occlusionD, 1e-4) << i;
    EXPECT_NEAR(got[i].occlusionS, ref[i].occlusionS, 1e-4) << i;
    EXPECT_LE(cv::norm(got[i].Ld - ref[i].Ld), 1e-4 * std::max(cv::norm(ref[i].Ld), 1e-12));
    partly += ref[i].occlusionD < 0.99f;
  }
  EXPECT_GT(partly, 20);  // the lid shadows the floor's light
}

TEST(GL, ValGatherHandlesAQuarterMillionVals) {
  // The bench's largest VAL count (a full 640x480 frame): every VAL must reach the gather.
  auto ctx = smallContext();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Val> vals;
  for (int i = 0; i < 262144; ++i)
    vals.push_back(disc({u(rng), u(rng), 0.8f}, {0, 0, -1}, 0.001f, {1e-4f, 1e-4f, 1e-4f}));
  // One bright VAL at the end: missed if the gather stops early.
  vals.back() = disc({0.f, 0.f, 0.5f}, {0, 0, -1}, 0.01f, {1.f, 1.f, 1.f});
  lighting::setValWeights(vals);
  std::vector<lighting::Receiver> rec;
  for (int i = 0; i < 32; ++i) rec.push_back(receiver({0.3f * u(rng), 0.3f * u(rng), 0.f}, {0, 0, 1}, {0, 0, 1}, 10.f));
  lighting::ValGpu gpu(128);
  gpu.setVals(vals);
  gpu.gather(rec);
  std::vector<cv::Vec3f> E, S;
  gpu.downloadSums(E, S);
  for (size_t i = 0; i < rec.size(); ++i) {
    const auto g = lighting::gatherReference(rec[i], vals);
    EXPECT_LE(cv::norm(E[i] - g.E), 1e-3 * cv::norm(g.E)) << i;
  }
}
