#include "reconstruction/albedo.h"

#include <gtest/gtest.h>

#include <cmath>

#include "capture/colour.h"
#include "capture/session.h"
#include "capture/view_factor.h"
#include "reconstruction/depth.h"
#include "reconstruction/depth_filter.h"

using namespace mrgi;
using namespace mrgi::reconstruction;

namespace {

// Does the segment a -> b pass through the axis-aligned box [lo, hi]? (slab test)
bool segmentHitsBox(const cv::Vec3d& a, const cv::Vec3d& b, const cv::Vec3d& lo, const cv::Vec3d& hi) {
  double t0 = 0, t1 = 1;
  for (int i = 0; i < 3; ++i) {
    const double d = b[i] - a[i];
    if (std::abs(d) < 1e-12) {
      if (a[i] < lo[i] || a[i] > hi[i]) return false;
      continue;
    }
    double ta = (lo[i] - a[i]) / d, tb = (hi[i] - a[i]) / d;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta), t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

// The bundled synthetic session has known albedos: recover the table's from a real pipeline frame
// (noisy depth, guided filter, normals, the ground-truth point light and ambient term).
TEST(Albedo, RecoversTheKnownTableAlbedoAndRejectsTheBoxShadow) {
  capture::SessionSource session(std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-synth");
  const auto& gt = session.manifest().groundTruth;
  const capture::Frame frame = session.read(0);
  const capture::RgbdFrame& f = *frame.rgbd;
  const capture::Pose T_world_camera = *frame.groundTruthT_world_camera;
  const capture::Pose T_camera_world = T_world_camera.inv();
  DepthFilterOptions fo;
  const cv::Mat depth = guidedFilterDepth(f.depth, guideFromColour(f.colour), fo.radiusPx, fo);
  const cv::Mat pos = backProject(depth, f.colourIntrinsics);
  const cv::Mat nrm = computeNormals(pos);

  AlbedoLights lights;
  const auto& l = gt["lights"][0];
  const cv::Vec3d lightWorld(l["position"][0].get<double>(), l["position"][1].get<double>(),
                             l["position"][2].get<double>());
  lights.points.push_back(
      AlbedoPointLight{capture::transformPoint(T_camera_world, lightWorld),
                       cv::Vec3d(l["intensity_w_sr"][0].get<double>(), l["intensity_w_sr"][1].get<double>(),
                                 l["intensity_w_sr"][2].get<double>())});
  const double ambient = gt["scene"]["ambient_radiance"][0];
  lights.ambientIrradiance = cv::Vec3d::all(CV_PI * ambient);
  const auto result = estimateAlbedo(f.colour, pos, nrm, f.colourIntrinsics, lights);
  ASSERT_TRUE(cv::checkRange(result.albedo, true, nullptr, 0.0, 1.0 + 1e-6));
  {
    // The rows and the fill's channels run on the CPU's threads: one thread gives the same bits.
    const int threads = cv::getNumThreads();
    cv::setNumThreads(1);
    const auto serial = estimateAlbedo(f.colour, pos, nrm, f.colourIntrinsics, lights);
    cv::setNumThreads(threads);
    EXPECT_EQ(cv::norm(serial.albedo, result.albedo, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::countNonZero(serial.status != result.status), 0);
    EXPECT_GT(cv::countNonZero(result.status != uchar(AlbedoStatus::Measured)), 1000) << "the fill ran";
  }

  cv::Vec3d table;
  for (const auto& m : gt["scene"]["materials"])
    if (m["name"] == "table")
      table = {m["albedo"][0].get<double>(), m["albedo"][1].get<double>(), m["albedo"][2].get<double>()};
  const cv::Vec3d boxLo(0.22, 0.75, -0.26), boxHi(0.37, 0.90, -0.11);
  int lit = 0, litGood = 0, shadow = 0, shadowRejected = 0, shadowFlagged = 0;
  // The fill in the box's shadow against the table's truth: inpainted at full resolution (the default) and
  // from 4 x 4 blocks (fillScale 4).
  AlbedoOptions blocks;
  blocks.fillScale = 4;
  const auto coarse = estimateAlbedo(f.colour, pos, nrm, f.colourIntrinsics, lights, blocks);
  AlbedoOptions halves;  // the frame pipeline's fill: 2 x 2 blocks
  halves.fillScale = 2;
  const auto half = estimateAlbedo(f.colour, pos, nrm, f.colourIntrinsics, lights, halves);
  EXPECT_EQ(cv::norm(half.albedo, result.albedo, cv::NORM_INF, result.status == uchar(AlbedoStatus::Measured)), 0.0)
      << "a fill changes only what it fills";
  double fillError = 0, exactFillError = 0, halfFillError = 0;
  int filled = 0;
  std::vector<double> red;
  for (int y = 0; y < pos.rows; ++y)
    for (int x = 0; x < pos.cols; ++x) {
      const cv::Vec3d p(pos.at<cv::Vec3f>(y, x));
      if (!(p[2] > 0)) continue;
      const cv::Vec3d w = capture::transformPoint(T_world_camera, p);
      // Table top, away from its edges, the tag and the box footprint.
      if (std::abs(w[1] - 0.75) > 0.004 || std::abs(w[0]) > 0.55 || std::abs(w[2]) > 0.35) continue;
      if (std::abs(w[0]) < 0.13 && std::abs(w[2]) < 0.13) continue;
      if (w[0] > 0.19 && w[0] < 0.40 && w[2] > -0.29 && w[2] < -0.08) continue;
      const cv::Vec3f a = result.albedo.at<cv::Vec3f>(y, x);
      const bool good = cv::norm(cv::Vec3d(a) - table) < 0.1 * cv::norm(table);
      const auto st = static_cast<AlbedoStatus>(result.status.at<uchar>(y, x));
      if (segmentHitsBox(w + cv::Vec3d(0, 0.002, 0), lightWorld, boxLo, boxHi)) {
        ++shadow;
        shadowFlagged += st == AlbedoStatus::Shadowed;
        shadowRejected += st != AlbedoStatus::Measured;
        if (st != AlbedoStatus::Measured) {
          exactFillError += cv::norm(cv::Vec3d(a) - table) / cv::norm(table);
          fillError += cv::norm(cv::Vec3d(coarse.albedo.at<cv::Vec3f>(y, x)) - table) / cv::norm(table);
          halfFillError += cv::norm(cv::Vec3d(half.albedo.at<cv::Vec3f>(y, x)) - table) / cv::norm(table);
          ++filled;
        }
      } else if (st == AlbedoStatus::Measured) {
        ++lit;
        litGood += good;
        red.push_back(a[0]);
      }
    }
  ASSERT_GT(lit, 5000);
  ASSERT_GT(shadow, 100);
  ASSERT_GT(filled, 100);
  fillError /= filled, exactFillError /= filled, halfFillError /= filled;
  std::printf(
      "fill in the box shadow: %.1f %% off the table's albedo from 4 x 4 blocks, %.1f %% from 2 x 2, %.1f %% "
      "inpainted at full resolution\n",
      100 * fillError, 100 * halfFillError, 100 * exactFillError);
  // Measured: 20.7 % against 36.5 % (full-resolution inpainting pulls in the box's and the shadow edge's colour).
  EXPECT_LT(fillError, 0.3);
  EXPECT_LT(fillError, exactFillError + 0.02);
  EXPECT_LT(halfFillError, exactFillError + 0.02);
  std::nth_element(red.begin(), red.begin() + red.size() / 2, red.end());
  std::printf(
      "table: %d lit px, %.1f%% within 10%% of truth, median red %.3f (truth %.3f); box shadow: %d px, "
      "%.1f%% flagged shadowed, %.1f%% not used as measured\n",
      lit, 100.0 * litGood / lit, red[red.size() / 2], table[0], shadow, 100.0 * shadowFlagged / shadow,
      100.0 * shadowRejected / shadow);
  // Measured: 99.5 % of lit table pixels within 10 %, median exact to 3 digits; of the visible box
  // shadow (a thin strip at the table's far edge) 74 % flagged by the screen-space test, 90 % rejected.
  EXPECT_NEAR(red[red.size() / 2], table[0], 0.03 * table[0]);
  EXPECT_GT(static_cast<double>(litGood) / lit, 0.95);
  EXPECT_GT(static_cast<double>(shadowFlagged) / shadow, 0.65);
  EXPECT_GT(static_cast<double>(shadowRejected) / shadow, 0.85);
}

TEST(Albedo, AnalyticPlaneAndRejections) {
  // A fronto-parallel plane at 1 m lit by a point light at the camera: I = k / pi * E exactly.
  const capture::Intrinsics k{40, 30, 40, 40, 19.5, 14.5};
  cv::Mat depth(30, 40, CV_32F, cv::Scalar(1.0f));
  const cv::Mat pos = backProject(depth, k);
  cv::Mat nrm(30, 40, CV_32FC3, cv::Scalar(0, 0, -1));
  AlbedoLights lights;
  lights.points.push_back(AlbedoPointLight{cv::Vec3d(0, 0, 0), cv::Vec3d(2, 2, 2)});
  const cv::Vec3d truth(0.6, 0.3, 0.1);
  cv::Mat colour(30, 40, CV_32FC3);
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x) {
      const cv::Vec3d p(pos.at<cv::Vec3f>(y, x));
      const double r = cv::norm(p), cosine = p[2] / r;
      const cv::Vec3d I = truth / CV_PI * (2.0 * cosine / (r * r));
      colour.at<cv::Vec3f>(y, x) = cv::Vec3f(I);
    }
  nrm.at<cv::Vec3f>(5, 5) = {0, 0, 0};  // no normal
  AlbedoOptions o;
  o.shadowTest = false;
  auto r = estimateAlbedo(colour, pos, nrm, k, lights, o);
  EXPECT_EQ(r.status.at<uchar>(5, 5), uchar(AlbedoStatus::NoGeometry));
  for (int y = 0; y < 30; y += 7)
    for (int x = 0; x < 40; x += 9) {
      if (y == 5 && x == 5) continue;
      EXPECT_EQ(r.status.at<uchar>(y, x), uchar(AlbedoStatus::Measured));
      EXPECT_LT(cv::norm(cv::Vec3d(r.albedo.at<cv::Vec3f>(y, x)) - truth), 1e-5);
    }
  EXPECT_LT(cv::norm(cv::Vec3d(r.albedo.at<cv::Vec3f>(5, 5)) - truth), 0.02);  // filled from neighbours
  // Grazing light, no light, a light on the surface (d -> 0), saturation: finite, clear statuses.
  lights.points[0].position = {5, 0, 0.5};  // cos ~ 0.1
  r = estimateAlbedo(colour, pos, nrm, k, lights, o);
  EXPECT_EQ(r.status.at<uchar>(15, 20), uchar(AlbedoStatus::Grazing));
  r = estimateAlbedo(colour, pos, nrm, k, AlbedoLights{}, o);
  EXPECT_EQ(r.status.at<uchar>(15, 20), uchar(AlbedoStatus::Unlit));
  EXPECT_TRUE(cv::checkRange(r.albedo));
  lights.points[0].position = cv::Vec3d(pos.at<cv::Vec3f>(15, 20));
  r = estimateAlbedo(colour, pos, nrm, k, lights, o);
  EXPECT_TRUE(cv::checkRange(r.albedo, true, nullptr, 0.0, 1.0 + 1e-6));
  cv::Mat white(30, 40, CV_8UC3, cv::Scalar(255, 255, 255));
  lights.points[0].position = {0, 0, 0};
  r = estimateAlbedo(white, pos, nrm, k, lights, o);
  EXPECT_EQ(r.status.at<uchar>(15, 20), uchar(AlbedoStatus::Saturated));
}

TEST(Albedo, ALightWithExtentLightsBelowItsCentresHorizonAsTheShadingPassHasIt) {
  // A plane lit by a disc of sky half of whose width straddles its horizon (cos theta 0.3, half-angle 0.5 rad),
  // and by a sphere lamp low over it: rendered with the part of each still above the horizon
  // (capture::capCosine), the estimate takes the same and recovers the albedo; a point's cosine would not.
  const capture::Intrinsics k{40, 30, 40, 40, 19.5, 14.5};
  cv::Mat depth(30, 40, CV_32F, cv::Scalar(1.0f));
  const cv::Mat pos = backProject(depth, k);
  const cv::Mat nrm(30, 40, CV_32FC3, cv::Scalar(0, 0, -1));
  const cv::Vec3d truth(0.6, 0.3, 0.1), ambient(0.1, 0.1, 0.1);
  for (const bool distant : {true, false}) {
    AlbedoLights lights;
    lights.ambientIrradiance = ambient;
    const double cosT = 0.3, sinT = std::sqrt(1 - cosT * cosT);
    if (distant) {
      EstimatedLight l;
      l.direction = {sinT, 0, -cosT};
      l.power = {2, 2, 2};
      l.angularRadius = 0.5;
      lights.distant.push_back(l);
    } else {
      lights.points.push_back(AlbedoPointLight{cv::Vec3d(1.2, 0, 0.6), cv::Vec3d(3, 3, 3), 0.6});
    }
    cv::Mat colour(30, 40, CV_32FC3);
    double pointError = 0;
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 40; ++x) {
        const cv::Vec3d p(pos.at<cv::Vec3f>(y, x)), n(0, 0, -1);
        cv::Vec3d e, toLight;
        double sinA;
        if (distant) {
          toLight = lights.distant[0].direction;
          e = lights.distant[0].power;
          sinA = std::sin(0.5);
        } else {
          const cv::Vec3d d = lights.points[0].position - p;
          toLight = d / cv::norm(d);
          e = lights.points[0].intensity / d.dot(d);
          sinA = 0.6 / cv::norm(d);
        }
        const double c = capture::capCosine(n.dot(toLight), sinA);
        colour.at<cv::Vec3f>(y, x) = cv::Vec3f(truth / CV_PI * (e[0] * c + ambient[0]));
        pointError = std::max(
            pointError, std::abs((e[0] * c + ambient[0]) / (e[0] * std::max(n.dot(toLight), 0.0) + ambient[0]) - 1));
      }
    EXPECT_GT(pointError, 0.02);  // what a point's cosine would put into the albedo (3-4 %)
    AlbedoOptions o;
    o.shadowTest = false;
    const auto r = estimateAlbedo(colour, pos, nrm, k, lights, o);
    int measured = 0;
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 40; ++x) {
        if (r.status.at<uchar>(y, x) != uchar(AlbedoStatus::Measured)) continue;
        ++measured;
        EXPECT_LT(cv::norm(cv::Vec3d(r.albedo.at<cv::Vec3f>(y, x)) - truth), 1e-5) << x << "," << y;
      }
    EXPECT_GT(measured, 1000) << (distant ? "disc of sky" : "sphere lamp");
  }
}

TEST(Albedo, AClippedPatchTakesAtLeastTheAlbedoItsClippedValueBounds) {
  // A white card clipped by the camera on a dark table: filled from its dark neighbours alone it would read
  // dark (and a virtual shadow over it would darken it too little); its clipped value bounds it from below.
  const capture::Intrinsics k{40, 30, 40, 40, 19.5, 14.5};
  const cv::Mat depth(30, 40, CV_32F, cv::Scalar(1.0f)), pos = backProject(depth, k);
  const cv::Mat nrm(30, 40, CV_32FC3, cv::Scalar(0, 0, -1));
  AlbedoLights lights;
  lights.points.push_back(AlbedoPointLight{cv::Vec3d(0, 0, 0), cv::Vec3d(2, 2, 2)});
  cv::Mat colour(30, 40, CV_8UC3, cv::Scalar(20, 20, 20));
  colour(cv::Rect(15, 10, 10, 10)).setTo(cv::Scalar(255, 255, 255));
  AlbedoOptions o;
  o.shadowTest = false;
  const auto r = estimateAlbedo(colour, pos, nrm, k, lights, o);
  const double clipBound = CV_PI * capture::srgbToLinear(1.0f) / 2.0;  // pi I_clip / E at the centre, > 1
  ASSERT_GT(clipBound, 1.0);
  EXPECT_EQ(r.status.at<uchar>(15, 20), uchar(AlbedoStatus::Saturated));
  EXPECT_FLOAT_EQ(r.albedo.at<cv::Vec3f>(15, 20)[0], 1.0f);
  EXPECT_LT(r.albedo.at<cv::Vec3f>(2, 2)[0], 0.1f);  // the table
}
