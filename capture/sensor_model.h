#pragma once
/// A structured-light depth sensor's error model, for synthetic sessions:
///  - axial noise sigma(z) = a + b (z - z0)^2 metres (Kinect v1 fit of Nguyen, Izadi & Lovell 2012:
///    a = 1.2 mm, b = 1.9 mm/m^2, z0 = 0.4 m), quantised to the recording's depth units;
///  - dropouts at grazing angles (surface normal vs. view ray beyond maxIncidenceDeg);
///  - dropouts along depth discontinuities (the projector/camera baseline shadow);
///  - random elliptical holes; no returns outside [minRange, maxRange].
#include <cstdint>
#include <opencv2/core.hpp>

namespace mrgi::capture {

struct DepthNoiseModel {
  double sigmaA = 0.0012, sigmaB = 0.0019, sigmaZ0 = 0.4;  ///< metres, metres/m^2, metres
  double minRange = 0.4, maxRange = 4.0;                   ///< metres
  double maxIncidenceDeg = 78.0;                           ///< beyond this angle returns drop out
  double edgeJump = 0.04;                                  ///< metres: a neighbour this much farther marks an edge
  double edgeDropProbability = 0.6;                        ///< per pixel next to an edge
  int holesPerFrame = 3;                                   ///< random elliptical holes
  double maxHoleRadiusPx = 9.0;
};

/// Applies the model to ideal depth (CV_32FC1 metres, 0 = no surface) with per-pixel camera-space unit
/// normals (CV_32FC3) and ray directions implied by the intrinsics. Deterministic for a given seed.
cv::Mat applyDepthNoise(const cv::Mat& idealDepth, const cv::Mat& normals, double fx, double fy, double cx, double cy,
                        const DepthNoiseModel& model, uint64_t seed);

}  // namespace mrgi::capture
