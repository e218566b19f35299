// The light a room sends itself (reconstruction/room_bounce.h) and the albedo it gives (estimateRoomAlbedo).
#include "reconstruction/room_bounce.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "reconstruction/room_model.h"

using namespace mrgi;
using reconstruction::RoomMesh;

namespace {

/// The inside of a sphere of radius R about the origin: a latitude-longitude mesh, normals inwards.
RoomMesh insideSphere(double R, int rings = 48, int segments = 96) {
  RoomMesh m;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const double t = CV_PI * i / rings, p = 2 * CV_PI * j / segments;
      const cv::Vec3d d(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
      m.positions.emplace_back(R * d);
      m.normals.emplace_back(-d);
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = static_cast<uint32_t>(i * segments + j),
                     b = static_cast<uint32_t>(i * segments + (j + 1) % segments);
      const uint32_t c = a + static_cast<uint32_t>(segments), d = b + static_cast<uint32_t>(segments);
      m.indices.insert(m.indices.end(), {a, c, b, b, c, d});
    }
  const size_t n = m.positions.size();
  m.radiance.assign(n, cv::Vec3f(0, 0, 0));
  m.confidence.assign(n, 1.f);
  m.saturated.assign(n, 0);
  return m;
}

/// The part of `m` whose vertices `keep` (their triangles with all three corners kept): a room scanned in part.
RoomMesh keptPart(const RoomMesh& m, const std::function<bool(const cv::Vec3f&)>& keep) {
  RoomMesh kept;
  std::vector<int> map(m.positions.size(), -1);
  for (size_t i = 0; i < m.positions.size(); ++i)
    if (keep(m.positions[i])) {
      map[i] = static_cast<int>(kept.positions.size());
      kept.positions.push_back(m.positions[i]);
      kept.normals.push_back(m.normals[i]);
      kept.radiance.push_back(m.radiance[i]);
      kept.confidence.push_back(m.confidence[i]);
      kept.saturated.push_back(m.saturated[i]);
    }
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3)
    if (map[m.indices[t]] >= 0 && map[m.indices[t + 1]] >= 0 && map[m.indices[t + 2]] >= 0)
      for (int k = 0; k < 3; ++k) kept.indices.push_back(static_cast<uint32_t>(map[m.indices[t + k]]));
  return kept;
}

TEST(RoomBounce, AClosedRoomOfUniformRadianceSendsEachPointPiL) {
  // Every ray from inside hits the room: E = pi L exactly, whatever the rays (stratified or not).
  RoomMesh m = insideSphere(1.5);
  m.radiance.assign(m.positions.size(), cv::Vec3f(0.2f, 0.4f, 0.8f));
  const reconstruction::MeshRays rays(m.positions, m.indices);
  reconstruction::RoomBounceOptions o;
  o.rays = 16;
  const auto E = reconstruction::roomBounceIrradiance(m, rays, o);
  ASSERT_EQ(E.size(), m.positions.size());
  for (size_t i = 0; i < E.size(); i += 37)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(E[i][c], CV_PI * m.radiance[i][c], 1e-4 * CV_PI) << i;
}

TEST(RoomBounce, HalfBrightRoomGivesTheCosineWeightedIntegral) {
  // The upper half (z > 0) at radiance 1, the lower dark. The ceiling's pole looks straight down at the dark
  // half through a hemisphere centred on its normal: by symmetry of the inside of a sphere, a point sees the
  // sphere's area uniformly weighted (the form factor from a point on a sphere's inside to dA is
  // dA / (4 pi R^2)), so E = pi x (the bright fraction of the area) = pi / 2 everywhere.
  RoomMesh m = insideSphere(1.0, 64, 128);
  for (size_t i = 0; i < m.positions.size(); ++i)
    m.radiance[i] = m.positions[i][2] > 0 ? cv::Vec3f(1, 1, 1) : cv::Vec3f(0, 0, 0);
  const reconstruction::MeshRays rays(m.positions, m.indices);
  reconstruction::RoomBounceOptions o;
  o.rays = 256;
  o.offsetM = 1e-3;
  const auto E = reconstruction::roomBounceIrradiance(m, rays, o);
  double worst = 0;
  for (size_t i = 0; i < E.size(); i += 11) worst = std::max(worst, std::abs(E[i][0] - CV_PI / 2) / (CV_PI / 2));
  EXPECT_LT(worst, 0.05);  // 256 stratified rays and the 1 mm offset; the smoothing mixes neighbours only
}

TEST(RoomBounce, SaturatedSurfacesSendNothingAndUnseenDirectionsSendWhatTheSeenOnesSend) {
  RoomMesh m = insideSphere(1.0);
  m.radiance.assign(m.positions.size(), cv::Vec3f(0.5f, 0.5f, 0.5f));
  // A lamp (saturated) over the north cap: its light is a listed light's, not the room's.
  for (size_t i = 0; i < m.positions.size(); ++i)
    if (m.positions[i][2] > 0.9f) m.saturated[i] = 1, m.radiance[i] = cv::Vec3f(100, 100, 100);
  const reconstruction::MeshRays rays(m.positions, m.indices);
  reconstruction::RoomBounceOptions o;
  o.rays = 64;
  o.smoothing = 0;
  const auto E = reconstruction::roomBounceIrradiance(m, rays, o);
  for (size_t i = 0; i < E.size(); ++i)
    ASSERT_LE(E[i][0], CV_PI * 0.5f * 1.0001f) << "a saturated surface sent light, vertex " << i;
  // The southern half only (a room scanned from below the equator): its points still see the half of the
  // sphere that is there and nothing else, so unseen directions take what the seen part sends, pi 0.5.
  RoomMesh half = insideSphere(1.0);
  half.radiance.assign(half.positions.size(), cv::Vec3f(0.5f, 0.5f, 0.5f));
  const RoomMesh kept = keptPart(half, [](const cv::Vec3f& p) { return p[2] < 0.2f; });
  const reconstruction::MeshRays keptRays(kept.positions, kept.indices);
  o.outside = {7, 7, 7};
  const auto Ek = reconstruction::roomBounceIrradiance(kept, keptRays, o);
  int bottom = 0;
  for (size_t i = 0; i < Ek.size(); ++i)
    if (kept.positions[i][2] < -0.9f) {
      ++bottom;
      EXPECT_NEAR(Ek[i][0], CV_PI * 0.5, 1e-3) << "the floor sees the walls, fills the rest with them";
    }
  EXPECT_GT(bottom, 10);
}

/// The inside of a unit sphere, its band z > 0.5 of radiance 1 and the rest 0.1, without its top cap z > 0.8.
RoomMesh bandedRoomWithoutItsTop() {
  RoomMesh full = insideSphere(1.0, 64, 128);
  for (size_t i = 0; i < full.positions.size(); ++i)
    full.radiance[i] = full.positions[i][2] > 0.5f ? cv::Vec3f(1, 1, 1) : cv::Vec3f(0.1f, 0.1f, 0.1f);
  return keptPart(full, [](const cv::Vec3f& p) { return p[2] <= 0.8f; });
}

/// Every vertex's own 256 rays, unsmoothed, from a millimetre off the surface.
reconstruction::RoomBounceOptions everyVertexExactly() {
  reconstruction::RoomBounceOptions o;
  o.rays = 256;
  o.offsetM = 1e-3;
  o.smoothing = 0;
  o.vertexStride = 1;
  return o;
}

TEST(RoomBounce, AHoleInTheCeilingSendsWhatTheCeilingAroundItSends) {
  // The inside of a sphere, its top cap (z > 0.8, a tenth of its area) never seen, the band below it bright
  // (z > 0.5: radiance 1; the rest 0.1), as a ceiling near a lamp is beside the walls. From the floor (the
  // bottom pole) a point sees a sphere's inside area-uniformly, so the closed room sends pi (0.25 + 0.075).
  // Continued from its rim, the hole sends the band's 1: that again. The seen rays' mean instead gives
  // pi 0.25, 23 % short.
  const RoomMesh kept = bandedRoomWithoutItsTop();
  const reconstruction::MeshRays rays(kept.positions, kept.indices);
  reconstruction::RoomBounceOptions o = everyVertexExactly();
  const auto E = reconstruction::roomBounceIrradiance(kept, rays, o);
  o.holeReachM = 0;
  const auto seenMean = reconstruction::roomBounceIrradiance(kept, rays, o);
  int bottom = 0;
  for (size_t i = 0; i < E.size(); ++i)
    if (kept.positions[i][2] < -0.99f) {
      ++bottom;
      EXPECT_NEAR(E[i][0], CV_PI * 0.325, 0.03 * CV_PI * 0.325) << i;
      EXPECT_LT(seenMean[i][0], 0.85 * CV_PI * 0.325) << i;
    }
  EXPECT_GT(bottom, 10);
}

TEST(RoomBounce, AnOpeningTheCamerasSawThroughSendsWhatTheySawBeyondIt) {
  // The same room, its top cap an opening (a window) through which the cameras saw a sky of radiance 2: from the
  // floor a cap above z0 is (1 - z0) / 2 of what a point sees, so the room sends pi ((z0 - 0.5) / 2 + 0.075 +
  // (1 - z0)), about pi 0.425 (z0 = 0.8, the hole's rim the highest kept vertex), not the band continued into it
  // (pi 0.325).
  RoomMesh kept = bandedRoomWithoutItsTop();
  kept.openings.recorded = true;
  for (int x = -7; x < 7; ++x)
    for (int y = -7; y < 7; ++y)
      for (int z = 8; z < 11; ++z) kept.openings.cells.push_back({x, y, z});
  std::sort(kept.openings.cells.begin(), kept.openings.cells.end(), [](const cv::Vec3i& a, const cv::Vec3i& b) {
    return std::tie(a[0], a[1], a[2]) < std::tie(b[0], b[1], b[2]);
  });
  kept.openings.radiance.assign(kept.openings.cells.size(), cv::Vec3f(2, 2, 2));
  kept.openings.clipped.assign(kept.openings.cells.size(), 0);
  ASSERT_GE(kept.openings.find({0.05, 0.05, 0.85}), 0);
  const reconstruction::MeshRays rays(kept.positions, kept.indices);
  const auto E = reconstruction::roomBounceIrradiance(kept, rays, everyVertexExactly());
  double z0 = -1;
  for (const cv::Vec3f& p : kept.positions) z0 = std::max(z0, double(p[2]));
  const double expected = CV_PI * ((z0 - 0.5) / 2 + 0.075 + (1 - z0));
  ASSERT_NEAR(expected, CV_PI * 0.425, 0.05);
  int bottom = 0;
  for (size_t i = 0; i < E.size(); ++i)
    if (kept.positions[i][2] < -0.99f) {
      ++bottom;
      EXPECT_NEAR(E[i][0], expected, 0.04 * expected) << i;  // 256 rays
    }
  EXPECT_GT(bottom, 10);
}

TEST(RoomBounce, TheRoomsAlbedoUnderALampAndItsOwnBounceIsTheTrueAlbedo) {
  // A lamp of intensity I at the centre of a closed sphere of albedo rho: every point receives E_d = I / R^2
  // directly and pi <L> from the rest, so L = rho (E_d + pi L) / pi, L = rho E_d / (pi (1 - rho)). Without the
  // room's bounce the albedo reads pi L / E_d = rho / (1 - rho): 1 (clamped) for rho = 0.5.
  const double R = 1.5, I = 9.0, rho = 0.5, Ed = I / (R * R);
  RoomMesh m = insideSphere(R);
  const float L = static_cast<float>(rho * Ed / (CV_PI * (1 - rho)));
  m.radiance.assign(m.positions.size(), cv::Vec3f(L, L, L));
  reconstruction::AlbedoLights lights;
  lights.points.push_back({{0, 0, 0}, cv::Vec3d::all(I)});
  const reconstruction::MeshRays rays(m.positions, m.indices);
  const auto bounce = reconstruction::roomBounceIrradiance(m, rays);
  const auto with = reconstruction::estimateRoomAlbedo(m, lights, {}, nullptr, &bounce);
  const auto without = reconstruction::estimateRoomAlbedo(m, lights);
  size_t measured = 0;
  for (size_t i = 0; i < m.positions.size(); ++i) {
    if (with.status[i] != reconstruction::AlbedoStatus::Measured) continue;
    ++measured;
    EXPECT_NEAR(with.albedo[i][0], rho, 0.01) << i;
    EXPECT_GT(without.albedo[i][0], 0.95f) << i;
  }
  EXPECT_GT(measured, m.positions.size() * 9 / 10);
  // What the lamp's bounce off the room should use for the room to send its fused radiance: for rho = 0.3,
  // albedo x E / E_d = 0.3 / 0.7, and that times E_d is pi L.
  const float L3 = static_cast<float>(0.3 * Ed / (CV_PI * 0.7));
  m.radiance.assign(m.positions.size(), cv::Vec3f(L3, L3, L3));
  const auto bounce3 = reconstruction::roomBounceIrradiance(m, rays);
  const auto three = reconstruction::estimateRoomAlbedo(m, lights, {}, nullptr, &bounce3);
  for (size_t i = 0; i < m.positions.size(); i += 17) {
    if (three.status[i] != reconstruction::AlbedoStatus::Measured) continue;
    EXPECT_NEAR(three.albedo[i][0], 0.3, 0.01) << i;
    EXPECT_NEAR(three.sent[i][0], 0.3 / 0.7, 0.01) << i;
    EXPECT_NEAR(three.sent[i][0] * Ed, CV_PI * L3, 0.01 * CV_PI * L3) << i;
  }
  EXPECT_EQ(without.sent, without.albedo) << "without the room's bounce the two agree";
  const std::vector<cv::Vec3f> wrongSize(3);
  EXPECT_THROW(reconstruction::estimateRoomAlbedo(m, lights, {}, nullptr, &wrongSize), std::invalid_argument);
}

TEST(RoomBounce, EmptyAndDegenerateRoomsGiveFiniteZeros) {
  RoomMesh empty;
  const reconstruction::MeshRays none(empty.positions, empty.indices);
  EXPECT_TRUE(reconstruction::roomBounceIrradiance(empty, none).empty());
  RoomMesh m = insideSphere(1.0, 8, 16);
  m.radiance.assign(m.positions.size(), cv::Vec3f(1e30f, 0, 1));
  m.normals[0] = {0, 0, 0};
  m.positions[1] = {NAN, 0, 0};
  const reconstruction::MeshRays rays(m.positions, m.indices);
  const auto E = reconstruction::roomBounceIrradiance(m, rays);
  for (const auto& e : E)
    for (int c = 0; c < 3; ++c) EXPECT_TRUE(std::isfinite(e[c]));
  // A room without triangles: one status, albedo and shadow flag per vertex all the same.
  RoomMesh points = m;
  points.indices.clear();
  const auto a = reconstruction::estimateRoomAlbedo(points, {});
  EXPECT_EQ(a.status.size(), points.positions.size());
  EXPECT_EQ(a.inShadow.size(), points.positions.size());
  EXPECT_EQ(a.albedo.size(), points.positions.size());
}

}  // namespace
