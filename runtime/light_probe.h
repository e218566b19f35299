#pragma once
// `mrgi calibrate-fisheye` and `mrgi lights`: the fisheye light probe's side of the product — its calibration
// from checkerboard images (OpenCV's fisheye model, written as ROS calibration YAML), and the distant lights of a
// calibrated fisheye image or an equirectangular probe (median cut, an SH remainder), printed.
#include <string>

namespace mrgi::runtime {

struct CalibrateOptions {
  /// The folder of images, inner corners COLSxROWS, the YAML written; the square edge in metres.
  std::string dir, board = "6x8", out;
  double square = 0.025;
};
/// Calibrates and writes the YAML; prints one JSON line. Throws FlagError("--board") for a bad board.
int calibrateFisheye(const CalibrateOptions& o);

struct LightsOptions {
  /// The image (HDR or sRGB) and, for a fisheye view, its calibration; without it an equirectangular probe.
  std::string image, calib;
  int count = 16;
  bool json = false, variance = false;
  double exposure = 1.0, maxThetaDeg = 108;
  double ambientThreshold = -1;  ///< 0: every bit of light to the lights, no SH remainder; < 0: by the field
};
/// Estimates and prints the lights (one JSON object with `json`); warns when over 1 % of the image is saturated.
int estimateLights(const LightsOptions& o);

}  // namespace mrgi::runtime
