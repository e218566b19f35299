// Lights from the room model: a synthetic room (3 x 3 x 2.5 m) with one ceiling lamp whose every
// observation clipped, a white floor lit by it, grey walls.
#include "reconstruction/room_lights.h"

#include <gtest/gtest.h>

#include <cmath>

#include "capture/colour.h"

using namespace mrgi;
using reconstruction::RoomMesh;

namespace {

constexpr double kLampRadiance = 40.0, kBound = 1.0, kWall = 0.05, kFloorAlbedo = 0.8;
const cv::Vec3d kLamp(0.6, 0.4, 2.49);
constexpr double kLampSide = 0.2;

/// A grid quad: origin + i/n * a + j/n * b, normal n, radiance from f(position).
template <class F>
void addQuad(RoomMesh& m, const cv::Vec3d& origin, const cv::Vec3d& a, const cv::Vec3d& b, const cv::Vec3d& normal,
             int n, F radiance, bool saturated) {
  const uint32_t base = static_cast<uint32_t>(m.positions.size());
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const cv::Vec3d p = origin + a * (static_cast<double>(i) / n) + b * (static_cast<double>(j) / n);
      m.positions.emplace_back(p);
      m.normals.emplace_back(normal);
      m.radiance.emplace_back(radiance(p));
      m.confidence.push_back(saturated ? 0.f : 1.f);
      m.saturated.push_back(saturated ? 1 : 0);
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const uint32_t v = base + static_cast<uint32_t>(j * (n + 1) + i);
      for (uint32_t k : {v, v + 1, v + static_cast<uint32_t>(n + 1), v + 1, v + static_cast<uint32_t>(n + 2),
                         v + static_cast<uint32_t>(n + 1)})
        m.indices.push_back(k);
    }
}

/// The lamp's irradiance at a floor point (normal up), by summing 20 x 20 patches of the lamp.
double lampIrradiance(const cv::Vec3d& p) {
  double E = 0;
  const int n = 20;
  const double dA = (kLampSide / n) * (kLampSide / n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const cv::Vec3d q =
          kLamp + cv::Vec3d(-kLampSide / 2 + (i + 0.5) * kLampSide / n, -kLampSide / 2 + (j + 0.5) * kLampSide / n, 0);
      const cv::Vec3d d = q - p;
      const double r2 = d.dot(d), r = std::sqrt(r2);
      E += kLampRadiance * dA * (d[2] / r) * (d[2] / r) / r2;  // cos at the floor x cos at the lamp (both vertical)
    }
  return E;
}

RoomMesh lampRoom() {
  RoomMesh m;
  const auto grey = [](const cv::Vec3d&) { return cv::Vec3f::all(static_cast<float>(kWall)); };
  // Floor: white, lit by the lamp and by the walls' and ceiling's radiance (a uniform upper hemisphere).
  addQuad(
      m, {-1.5, -1.5, 0}, {3, 0, 0}, {0, 3, 0}, {0, 0, 1}, 40,
      [](const cv::Vec3d& p) {
        return cv::Vec3f::all(static_cast<float>(kFloorAlbedo / CV_PI * (lampIrradiance(p) + CV_PI * kWall)));
      },
      false);
  addQuad(m, {-1.5, -1.5, 2.5}, {3, 0, 0}, {0, 3, 0}, {0, 0, -1}, 20, grey, false);
  addQuad(m, {-1.5, -1.5, 0}, {3, 0, 0}, {0, 0, 2.5}, {0, 1, 0}, 20, grey, false);
  addQuad(m, {-1.5, 1.5, 0}, {3, 0, 0}, {0, 0, 2.5}, {0, -1, 0}, 20, grey, false);
  addQuad(m, {-1.5, -1.5, 0}, {0, 3, 0}, {0, 0, 2.5}, {1, 0, 0}, 20, grey, false);
  addQuad(m, {1.5, -1.5, 0}, {0, 3, 0}, {0, 0, 2.5}, {-1, 0, 0}, 20, grey, false);
  // The lamp: seen only clipped, its radiance the bound.
  addQuad(
      m, kLamp - cv::Vec3d(kLampSide / 2, kLampSide / 2, 0), {kLampSide, 0, 0}, {0, kLampSide, 0}, {0, 0, -1}, 4,
      [](const cv::Vec3d&) { return cv::Vec3f::all(static_cast<float>(kBound)); }, true);
  return m;
}

}  // namespace

TEST(RoomLights, OneLampGivesADominantLightWithin5DegreesAndItsIntensityFromTheWhiteFloor) {
  const RoomMesh room = lampRoom();
  const cv::Vec3d centre(0, 0, 0.3);
  const reconstruction::RoomLights lights = reconstruction::estimateRoomLights(room, centre);
  EXPECT_GT(lights.coverage, 0.99);
  // The white-patch estimate of the lamp's gain over its clip bound: the floor's brightest lit vertices have
  // albedo 0.8, so the gain is the lamp's true radiance over the bound.
  EXPECT_TRUE(lights.gainEstimated);
  EXPECT_FALSE(lights.overExposed);
  EXPECT_LT(lights.saturatedFraction, 0.01);
  EXPECT_GT(lights.gainSamples, 100);
  EXPECT_NEAR(lights.gain, kLampRadiance / kBound, 0.1 * kLampRadiance / kBound);
  ASSERT_FALSE(lights.lights.empty());
  const reconstruction::RoomLight* dominant = &lights.lights[0];
  for (const auto& l : lights.lights)
    if (capture::luminance(l.irradiance) > capture::luminance(dominant->irradiance)) dominant = &l;
  const cv::Vec3d truth = cv::normalize(kLamp - centre);
  const double angle = std::acos(std::clamp(dominant->direction.dot(truth), -1.0, 1.0)) * 180 / CV_PI;
  EXPECT_LT(angle, 5.0);
  ASSERT_TRUE(dominant->point);
  EXPECT_LT(cv::norm(dominant->position - kLamp), 0.05);
  EXPECT_GT(dominant->saturatedFraction, 0.9);
  // Its intensity: the lamp's radiance x area (x cos, about 1 towards the centre) within 10 %.
  const double I = kLampRadiance * kLampSide * kLampSide * truth[2];
  EXPECT_NEAR(capture::luminance(dominant->intensity), I, 0.1 * I);
  // The rest is ambient: the grey walls' radiance, about the 0.05 they hold (the lit floor adds some).
  EXPECT_GT(lights.ambientRadiance[1], 0.8 * kWall);
  EXPECT_LT(lights.ambientRadiance[1], 3 * kWall);
  // Lights and ambient still hold the map's power.
  cv::Vec3d total(0, 0, 0);
  const auto rays = reconstruction::latLongRays(lights.environment.cols);
  total = reconstruction::totalPower(lights.environment, rays);
  cv::Vec3d split = lights.split.ambientSh[0] * (4 * CV_PI * 0.28209479177387814);
  for (const auto& l : lights.split.lights) split += l.power;
  EXPECT_NEAR(split[1], total[1], 1e-3 * total[1]);
}

/// A room lit by a small lamp hanging 0.5 m under the ceiling (a point of kHangingI W/sr): the camera clipped the
/// lamp's body (an 8 cm box) and the ceiling around it out to about 0.9 m, where the lamp puts more than the
/// sensor's white on its 0.8 albedo. `withBody` false: the same ceiling, no body (a wide clipped patch alone).
constexpr double kHangingI = 8.0;
const cv::Vec3d kHanging(0.6, 0.4, 2.0);
RoomMesh hangingLampRoom(bool withBody) {
  RoomMesh m;
  const auto lit = [](const cv::Vec3d& p, const cv::Vec3d& n) {
    const cv::Vec3d d = kHanging - p;
    const double r = cv::norm(d);
    return kFloorAlbedo / CV_PI * (kHangingI * std::max(0.0, n.dot(d / r)) / (r * r) + CV_PI * kWall);
  };
  const auto grey = [](const cv::Vec3d&) { return cv::Vec3f::all(static_cast<float>(kWall)); };
  addQuad(
      m, {-1.5, -1.5, 0}, {3, 0, 0}, {0, 3, 0}, {0, 0, 1}, 40,
      [&](const cv::Vec3d& p) {
        return cv::Vec3f::all(static_cast<float>(lit(p, {0, 0, 1})));
      },
      false);
  const size_t ceiling = m.positions.size();
  addQuad(
      m, {-1.5, -1.5, 2.5}, {3, 0, 0}, {0, 3, 0}, {0, 0, -1}, 60,
      [&](const cv::Vec3d& p) {
        return cv::Vec3f::all(static_cast<float>(lit(p, {0, 0, -1})));
      },
      false);
  for (size_t i = ceiling; i < m.positions.size(); ++i)
    if (m.radiance[i][1] >= kBound) m.radiance[i] = cv::Vec3f::all(static_cast<float>(kBound)), m.saturated[i] = 1;
  addQuad(m, {-1.5, -1.5, 0}, {3, 0, 0}, {0, 0, 2.5}, {0, 1, 0}, 20, grey, false);
  addQuad(m, {-1.5, 1.5, 0}, {3, 0, 0}, {0, 0, 2.5}, {0, -1, 0}, 20, grey, false);
  addQuad(m, {-1.5, -1.5, 0}, {0, 3, 0}, {0, 0, 2.5}, {1, 0, 0}, 20, grey, false);
  addQuad(m, {1.5, -1.5, 0}, {0, 3, 0}, {0, 0, 2.5}, {-1, 0, 0}, 20, grey, false);
  if (withBody) {
    const double h = 0.04;
    const auto bound = [](const cv::Vec3d&) { return cv::Vec3f::all(static_cast<float>(kBound)); };
    const cv::Vec3d c = kHanging;
    addQuad(m, c + cv::Vec3d(-h, -h, -h), {2 * h, 0, 0}, {0, 2 * h, 0}, {0, 0, -1}, 4, bound, true);
    addQuad(m, c + cv::Vec3d(-h, -h, -h), {2 * h, 0, 0}, {0, 0, 2 * h}, {0, -1, 0}, 4, bound, true);
    addQuad(m, c + cv::Vec3d(-h, h, -h), {2 * h, 0, 0}, {0, 0, 2 * h}, {0, 1, 0}, 4, bound, true);
    addQuad(m, c + cv::Vec3d(-h, -h, -h), {0, 2 * h, 0}, {0, 0, 2 * h}, {-1, 0, 0}, 4, bound, true);
    addQuad(m, c + cv::Vec3d(h, -h, -h), {0, 2 * h, 0}, {0, 0, 2 * h}, {1, 0, 0}, 4, bound, true);
  }
  return m;
}

TEST(RoomLights, ALampsOverExposedCeilingIsASurfaceItLightsNotALamp) {
  // The ceiling's clipped patch is far wider than the lamp: taken as an emitter it would stand in for the lamp
  // half a metre above it and spread its light over the patch. The lamp's clipped body (a compact piece) lights
  // the patch, so the patch is a surface it lights: the light sits at the body.
  const cv::Vec3d centre(0, 0, 0.3);
  const reconstruction::RoomLights lights = reconstruction::estimateRoomLights(hangingLampRoom(true), centre);
  EXPECT_GT(lights.lampLitClipped, 500u);
  EXPECT_TRUE(lights.gainEstimated);
  ASSERT_FALSE(lights.lights.empty());
  const reconstruction::RoomLight* dominant = &lights.lights[0];
  for (const auto& l : lights.lights)
    if (capture::luminance(l.irradiance) > capture::luminance(dominant->irradiance)) dominant = &l;
  ASSERT_TRUE(dominant->point);
  std::printf("hanging lamp: found %.3f m from it, intensity %.2f W/sr (true %.2f), %zu clipped ceiling vertices lit\n",
              cv::norm(dominant->position - kHanging), capture::luminance(dominant->intensity), kHangingI,
              lights.lampLitClipped);
  // On the body's face towards the centre (4 cm from its middle); its power from the white floor 20 % low (the
  // body's clipped faces stand in for the point inside it). Taken from the clipped ceiling too, the light sat
  // 0.56 m away, on the ceiling.
  EXPECT_LT(cv::norm(dominant->position - kHanging), 0.08);
  EXPECT_NEAR(capture::luminance(dominant->intensity), kHangingI, 0.25 * kHangingI);
  // Without a body to light it, a wide clipped patch stays an emitter (a panel light, a clipped window).
  const reconstruction::RoomLights patch = reconstruction::estimateRoomLights(hangingLampRoom(false), centre);
  EXPECT_EQ(patch.lampLitClipped, 0u);
  EXPECT_GT(patch.saturatedFraction, 0.01);
}

TEST(RoomLights, AGivenGainIsUsedAndAnUnscannedRoomStaysFinite) {
  reconstruction::RoomLightOptions o;
  o.saturatedGain = 10;
  const auto lights = reconstruction::estimateRoomLights(lampRoom(), {0, 0, 0.3}, o);
  EXPECT_FALSE(lights.gainEstimated);
  EXPECT_EQ(lights.gain, 10);
  // Only a floor: most directions miss (never scanned) and take the floor's mean radiance.
  RoomMesh floor;
  addQuad(
      floor, {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 1}, 10, [](const cv::Vec3d&) { return cv::Vec3f::all(0.1f); },
      false);
  const auto f = reconstruction::estimateRoomLights(floor, {0, 0, 0.3});
  EXPECT_LT(f.coverage, 0.5);
  EXPECT_FALSE(f.gainEstimated);
  for (const auto& l : f.lights)
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isfinite(l.irradiance[k]) && std::isfinite(l.intensity[k]));
  EXPECT_NEAR(f.ambientRadiance[0] + 0 * f.lights.size(), 0.1, 0.05);
  EXPECT_THROW(reconstruction::estimateRoomLights(RoomMesh{}, {0, 0, 0}), std::invalid_argument);
  // An over-exposed recording: the whole floor clipped. Not a lamp: no gain is estimated, the bound stays.
  RoomMesh clipped;
  addQuad(
      clipped, {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 1}, 10, [](const cv::Vec3d&) { return cv::Vec3f::all(1.f); },
      true);
  addQuad(
      clipped, {-1, -1, 2}, {2, 0, 0}, {0, 2, 0}, {0, 0, -1}, 10, [](const cv::Vec3d&) { return cv::Vec3f::all(0.1f); },
      false);
  const auto c = reconstruction::estimateRoomLights(clipped, {0, 0, 0.3});
  EXPECT_TRUE(c.overExposed);
  EXPECT_FALSE(c.gainEstimated);
  EXPECT_EQ(c.gain, 1.0);
}

TEST(RoomLights, DirectionsNeverScannedContinueTheSurfacesAroundThem) {
  // A room whose ceiling (bright, 0.5) was never scanned straight above the object: a 1.6 m square hole over
  // it, 20 degrees around the zenith from the centre; walls and floor dark (0.05). The hole's directions take
  // the ceiling around them, not the mean of what was scanned (0.08 here), so the irradiance from above stays the
  // closed room's.
  constexpr double kCeiling = 0.5;
  const auto dark = [](const cv::Vec3d&) { return cv::Vec3f::all(static_cast<float>(kWall)); };
  const auto bright = [](const cv::Vec3d&) { return cv::Vec3f::all(static_cast<float>(kCeiling)); };
  auto walls = [&](RoomMesh& m) {
    addQuad(m, {-1.5, -1.5, 0}, {3, 0, 0}, {0, 3, 0}, {0, 0, 1}, 20, dark, false);
    addQuad(m, {-1.5, -1.5, 0}, {3, 0, 0}, {0, 0, 2.5}, {0, 1, 0}, 20, dark, false);
    addQuad(m, {-1.5, 1.5, 0}, {3, 0, 0}, {0, 0, 2.5}, {0, -1, 0}, 20, dark, false);
    addQuad(m, {-1.5, -1.5, 0}, {0, 3, 0}, {0, 0, 2.5}, {1, 0, 0}, 20, dark, false);
    addQuad(m, {1.5, -1.5, 0}, {0, 3, 0}, {0, 0, 2.5}, {-1, 0, 0}, 20, dark, false);
  };
  RoomMesh closed, holed;
  walls(closed), walls(holed);
  addQuad(closed, {-1.5, -1.5, 2.5}, {3, 0, 0}, {0, 3, 0}, {0, 0, -1}, 30, bright, false);
  addQuad(holed, {-1.5, -1.5, 2.5}, {3, 0, 0}, {0, 0.7, 0}, {0, 0, -1}, 30, bright, false);  // y < -0.8
  addQuad(holed, {-1.5, 0.8, 2.5}, {3, 0, 0}, {0, 0.7, 0}, {0, 0, -1}, 30, bright, false);   // y > 0.8
  addQuad(holed, {-1.5, -0.8, 2.5}, {0.7, 0, 0}, {0, 1.6, 0}, {0, 0, -1}, 10, bright, false);
  addQuad(holed, {0.8, -0.8, 2.5}, {0.7, 0, 0}, {0, 1.6, 0}, {0, 0, -1}, 10, bright, false);
  const cv::Vec3d centre(0, 0, 0.3);
  const auto a = reconstruction::estimateRoomLights(closed, centre),
             b = reconstruction::estimateRoomLights(holed, centre);
  EXPECT_GT(a.coverage, 0.99);
  EXPECT_LT(b.coverage, 0.98);
  const auto rays = reconstruction::latLongRays(b.environment.cols);
  double worst = 0;
  int texels = 0;
  auto irradianceUp = [&](const cv::Mat& L) {
    double E = 0;
    for (int v = 0; v < L.rows; ++v)
      for (int u = 0; u < L.cols; ++u) {
        const double c = rays.directions.at<cv::Vec3f>(v, u)[2];
        if (c > 0) E += capture::luminance(cv::Vec3d(L.at<cv::Vec3f>(v, u))) * c * rays.solidAngle.at<double>(v, u);
      }
    return E;
  };
  for (int v = 0; v < b.environment.rows; ++v)
    for (int u = 0; u < b.environment.cols; ++u)
      if (rays.directions.at<cv::Vec3f>(v, u)[2] > std::cos(15 * CV_PI / 180))
        worst = std::max(worst, std::abs(b.environment.at<cv::Vec3f>(v, u)[1] - kCeiling)), ++texels;
  EXPECT_GT(texels, 50);
  EXPECT_LT(worst, 0.05 * kCeiling);  // the mean fill put 0.08 there
  EXPECT_NEAR(irradianceUp(b.environment), irradianceUp(a.environment), 0.02 * irradianceUp(a.environment));
}
