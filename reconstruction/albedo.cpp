#include "reconstruction/albedo.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include "capture/colour.h"
#include "capture/view_factor.h"

namespace mrgi::reconstruction {
namespace {

struct Contribution {
  cv::Vec3d toLight;  ///< unit
  double distance;    ///< to the light (distant: ray length)
  cv::Vec3d normalIrradiance;
  double sinA = 0;  ///< sine of the half-angle the light is seen under (0: a point)
  /// Its irradiance on a surface of unit normal n.
  cv::Vec3d on(const cv::Vec3d& n) const { return normalIrradiance * capture::capCosine(n.dot(toLight), sinA); }
};

using capture::luminance;

/// True when the depth map shows a surface between p and the light along `dir` (screen-space march).
bool occluded(const cv::Mat& positions, const capture::Intrinsics& k, const cv::Vec3d& p, const cv::Vec3d& dir,
              double length, const AlbedoOptions& o) {
  const double start = std::max(0.02, 0.01 * p[2]);  // leave the surface's own noise behind
  for (int s = 1; s <= o.shadowSteps; ++s) {
    const double t = start + (length - start) * s / o.shadowSteps;
    const cv::Vec3d q = p + dir * t;
    if (!(q[2] > 0.05)) return false;  // behind the camera: nothing seen there can occlude
    const int u = static_cast<int>(std::lround(k.fx * q[0] / q[2] + k.cx));
    const int v = static_cast<int>(std::lround(k.fy * q[1] / q[2] + k.cy));
    if (u < 0 || v < 0 || u >= positions.cols || v >= positions.rows) return false;  // left the view
    const float z = positions.at<cv::Vec3f>(v, u)[2];
    if (z > 0.f && z < q[2] - o.shadowTolerance * q[2] && z > q[2] - o.shadowThickness) return true;
  }
  return false;
}

/// Navier-Stokes inpainting of each channel of a CV_32FC3 image where `mask` is set, one thread per channel
/// (Telea's adds an 8-bit rounding offset (+0.5) to float images).
void inpaintChannels(cv::Mat& image, const cv::Mat& mask, double radius) {
  std::vector<cv::Mat> ch;
  cv::split(image, ch);
  cv::parallel_for_(cv::Range(0, 3), [&](const cv::Range& r) {
    for (int i = r.start; i < r.end; ++i)
      cv::inpaint(ch[static_cast<size_t>(i)].clone(), mask, ch[static_cast<size_t>(i)], radius, cv::INPAINT_NS);
  });
  cv::merge(ch, image);
}

/// Fills the rejected pixels (AlbedoOptions::fillScale): scale <= 1 by full-resolution inpainting; else the
/// measured pixels' mean per scale x scale block, blocks less than a quarter measured inpainted at that
/// resolution, and the rejected pixels take the blocks' bilinear upsampling.
void fillRejected(cv::Mat& albedo, const cv::Mat& rejected, int scale) {
  if (scale <= 1 || albedo.cols < 4 * scale || albedo.rows < 4 * scale) {
    inpaintChannels(albedo, rejected, 5);
  } else {
    const cv::Size small((albedo.cols + scale - 1) / scale, (albedo.rows + scale - 1) / scale);
    cv::Mat valid, sum, weight;
    cv::Mat(~rejected).convertTo(valid, CV_32F, 1.0 / 255.0);
    cv::Mat masked = albedo.clone();
    masked.setTo(cv::Scalar::all(0), rejected);
    cv::resize(masked, sum, small, 0, 0, cv::INTER_AREA);
    cv::resize(valid, weight, small, 0, 0, cv::INTER_AREA);
    cv::Mat coarse(small, CV_32FC3);
    for (int y = 0; y < small.height; ++y)
      for (int x = 0; x < small.width; ++x) {
        const float w = weight.at<float>(y, x);
        coarse.at<cv::Vec3f>(y, x) = w > 0 ? sum.at<cv::Vec3f>(y, x) / w : cv::Vec3f(0, 0, 0);
      }
    const cv::Mat holes = weight < 0.25f;
    if (cv::countNonZero(holes) > 0 && cv::countNonZero(~holes) > 0) inpaintChannels(coarse, holes, 3);
    cv::Mat up;
    cv::resize(coarse, up, albedo.size(), 0, 0, cv::INTER_LINEAR);
    up.copyTo(albedo, rejected);
  }
  albedo = cv::min(cv::max(albedo, 0.0), 1.0);
}

}  // namespace

AlbedoResult estimateAlbedo(const cv::Mat& colour, const cv::Mat& positions, const cv::Mat& normals,
                            const capture::Intrinsics& k, const AlbedoLights& lights, const AlbedoOptions& o) {
  CV_Assert(colour.size() == positions.size() && normals.size() == positions.size());
  CV_Assert(positions.type() == CV_32FC3 && normals.type() == CV_32FC3);
  CV_Assert(colour.type() == CV_8UC3 || colour.type() == CV_32FC3);
  CV_Assert(o.exposure > 0);
  const cv::Mat linear = colour.type() == CV_8UC3 ? cv::Mat(capture::decodeSrgb(colour) * (1.0 / o.exposure)) : colour;
  AlbedoResult out;
  out.albedo.create(colour.size(), CV_32FC3);
  out.status.create(colour.size(), CV_8UC1);
  // A clipped pixel's value is a lower bound of its radiance, so pi I / E bounds its albedo from below: after
  // the fill it takes at least that (a white patch filled from dark neighbours would darken less under a
  // virtual shadow than it should).
  cv::Mat bound(colour.size(), CV_32FC3, cv::Scalar::all(0));
  // Rows are independent: split over the CPU's threads (the same values as one thread).
  cv::parallel_for_(cv::Range(0, colour.rows), [&](const cv::Range& rows) {
    std::vector<Contribution> c;
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < colour.cols; ++x) {
        auto& status = out.status.at<uchar>(y, x);
        auto& albedo = out.albedo.at<cv::Vec3f>(y, x);
        albedo = {0, 0, 0};
        const cv::Vec3d p(positions.at<cv::Vec3f>(y, x)), n(normals.at<cv::Vec3f>(y, x));
        if (!(p[2] > 0) || !(cv::norm(n) > 0.5)) {
          status = uchar(AlbedoStatus::NoGeometry);
          continue;
        }
        bool clipped = false;
        if (colour.type() == CV_8UC3) {
          const cv::Vec3b px = colour.at<cv::Vec3b>(y, x);
          clipped = px[0] >= o.saturationLevel || px[1] >= o.saturationLevel || px[2] >= o.saturationLevel;
        }
        c.clear();
        for (const auto& l : lights.points) {
          cv::Vec3d d = l.position - p;
          const double r2 = std::max(d.dot(d), 1e-8);  // d -> 0 stays finite
          const double r = std::sqrt(r2);
          d /= r;
          c.push_back({d, r, l.intensity / r2, seenSine(l, r)});
        }
        for (const auto& l : lights.distant) c.push_back({l.direction, o.distantRayLength, l.power, seenSine(l)});
        cv::Vec3d direct(0, 0, 0), normalSum(0, 0, 0);
        for (const auto& ci : c) {
          direct += ci.on(n);
          normalSum += ci.normalIrradiance;
        }
        if (!c.empty() && luminance(direct) < o.minEffectiveCos * luminance(normalSum)) {
          status = uchar(luminance(direct) > 0 ? AlbedoStatus::Grazing : AlbedoStatus::Unlit);
          if (luminance(direct) > 0 || luminance(lights.ambientIrradiance) <= 0) continue;
        }
        if (o.shadowTest && luminance(direct) > 0) {
          cv::Vec3d visible = direct;
          for (const auto& ci : c) {
            const cv::Vec3d e = ci.on(n);
            if (luminance(e) < 0.2 * luminance(direct)) continue;  // only lights that matter are marched
            if (occluded(positions, k, p, ci.toLight, ci.distance, o)) visible -= e;
          }
          if (luminance(visible) < 0.5 * luminance(direct)) {
            status = uchar(AlbedoStatus::Shadowed);
            continue;
          }
        }
        const cv::Vec3d e = direct + lights.ambientIrradiance;
        if (!(luminance(e) > 1e-12)) {
          status = uchar(AlbedoStatus::Unlit);
          continue;
        }
        const cv::Vec3f I = linear.at<cv::Vec3f>(y, x);
        for (int ch = 0; ch < 3; ++ch) {
          const double kd = e[ch] > 1e-12 ? CV_PI * I[ch] / e[ch] : 0.0;
          albedo[ch] = static_cast<float>(std::clamp(std::isfinite(kd) ? kd : 0.0, 0.0, 1.0));
        }
        status = uchar(AlbedoStatus::Measured);
        if (clipped) {
          bound.at<cv::Vec3f>(y, x) = albedo;
          albedo = {0, 0, 0};
          status = uchar(AlbedoStatus::Saturated);
        }
      }
  });
  if (o.fill) {
    const cv::Mat rejected = out.status != uchar(AlbedoStatus::Measured);
    if (cv::countNonZero(rejected) > 0 && cv::countNonZero(~rejected) > 0)
      fillRejected(out.albedo, rejected, o.fillScale);
  }
  out.albedo = cv::max(out.albedo, bound);
  return out;
}

}  // namespace mrgi::reconstruction
