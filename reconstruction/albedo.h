#pragma once
/// Real-surface albedo from one linearised camera image, its geometry and the estimated lights
/// (shared/notes/algorithms.md §3):  k_d = pi * I_p / E_p,  E_p = sum_i E_i <n_p, w_i>+ (+ ambient), a light with
/// extent counting the part of it above the surface's horizon (capture::capCosine) instead of <n_p, w_i>+.
/// The factor pi matches the compositor's Lambertian shading (radiance = k_d / pi * E), so re-shading a
/// real pixel with the same lights reproduces its camera value. Pixels that cannot be trusted (no
/// geometry, grazing light, saturated, in shadow, unlit) are rejected and filled from their neighbours.
#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <vector>

#include "capture/types.h"
#include "reconstruction/light_estimation.h"

namespace mrgi::reconstruction {

struct AlbedoPointLight {
  cv::Vec3d position;   ///< camera frame, metres
  cv::Vec3d intensity;  ///< RGB radiant intensity (W/sr, or the camera's radiance units x m^2)
  double radius = 0;    ///< metres: a sphere lamp, lighting a surface by the part of it above the horizon (0: a point)
};

/// The sine of the half-angle a lamp is seen under from `distance` metres (0: a point), for capture::capCosine.
inline double seenSine(const AlbedoPointLight& l, double distance) {
  return l.radius > 0 ? std::min(l.radius / distance, 1.0) : 0.0;
}
/// The sine of a distant light's half-angle (0: a point direction), for capture::capCosine.
inline double seenSine(const EstimatedLight& l) { return std::sin(std::clamp(l.angularRadius, 0.0, 1.5)); }

struct AlbedoLights {
  std::vector<AlbedoPointLight> points;
  /// Directions in the camera frame; power = irradiance at normal incidence; a disc of angularRadius lights a
  /// surface by the part of it above the horizon (capture::capCosine), as the shading pass has it.
  std::vector<EstimatedLight> distant;
  cv::Vec3d ambientIrradiance{0, 0, 0};  ///< unoccluded ambient term (pi * ambient radiance)
};

enum class AlbedoStatus : uint8_t { Measured = 0, NoGeometry = 1, Grazing = 2, Saturated = 3, Shadowed = 4, Unlit = 5 };

struct AlbedoOptions {
  double minEffectiveCos = 0.2;  ///< reject when E_direct < this x the lights' normal-incidence sum
  int saturationLevel = 250;     ///< 8-bit channel value counted as clipped
  bool shadowTest = true;        ///< screen-space occlusion test towards each significant light
  int shadowSteps = 48;
  double shadowThickness = 0.25;   ///< metres: a surface this far in front of a ray sample does not occlude it
  double shadowTolerance = 0.005;  ///< relative depth: a surface must be this much in front of a sample to occlude it
  double distantRayLength = 2.0;   ///< metres marched towards distant lights
  bool fill = true;                ///< fill rejected pixels from their neighbours (cv::inpaint)
  /// The fill's resolution. 1 (default): Navier-Stokes inpainting at full resolution. > 1: rejected pixels take
  /// the bilinear upsampling of the measured pixels' means per fillScale x fillScale block, the blocks without
  /// enough measured pixels inpainted at that resolution: 30x cheaper on a frame with large rejected regions
  /// (BM_Albedo) at 4, but 4 x 4 blocks mix across sharp albedo edges (a clipped white tag square takes in its
  /// black neighbours, and a virtual shadow darkens it less). The frame pipeline fills from 2 x 2 blocks.
  int fillScale = 1;
  double exposure = 1.0;  ///< an 8-bit colour's linear value per unit radiance (RgbdFrame::exposure)
};

struct AlbedoResult {
  cv::Mat albedo;  ///< CV_32FC3 linear RGB in [0, 1]
  cv::Mat status;  ///< CV_8UC1 AlbedoStatus per pixel (filled pixels keep their rejection reason)
};

/// colour: CV_8UC3 sRGB (RGB order) or CV_32FC3 linear; positions/normals: CV_32FC3 camera frame from
/// backProject/computeNormals (zero = unknown).
AlbedoResult estimateAlbedo(const cv::Mat& colour, const cv::Mat& positions, const cv::Mat& normals,
                            const capture::Intrinsics& k, const AlbedoLights& lights,
                            const AlbedoOptions& options = {});

}  // namespace mrgi::reconstruction
