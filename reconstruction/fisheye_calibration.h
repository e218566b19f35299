#pragma once
/// Fisheye calibration from checkerboard photos with OpenCV's fisheye module (equidistant model).
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "capture/types.h"

namespace mrgi::reconstruction {

struct FisheyeCalibrationResult {
  capture::FisheyeCalibration calibration;
  double rms = 0;                     ///< reprojection RMS in pixels over the used views
  std::vector<std::string> used;      ///< images whose board was found and kept
  std::vector<std::string> rejected;  ///< "path: reason"
};

/// innerCorners = corners per row x per column (e.g. 6x8); squareSize in metres (does not affect K, D).
/// Views that make the problem ill-conditioned are dropped one at a time. Throws std::runtime_error
/// naming the folder when fewer than 3 views remain.
FisheyeCalibrationResult calibrateFisheye(const std::vector<std::string>& imagePaths, cv::Size innerCorners,
                                          double squareSize = 0.025);

}  // namespace mrgi::reconstruction
