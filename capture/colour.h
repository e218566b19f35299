#pragma once
/// sRGB transfer functions (IEC 61966-2-1). All lighting math is in linear RGB; decode camera images once
/// on the way in, encode once on the way out. GLSL twin: lighting/colour.glsl (same constants).
#include <cmath>

namespace mrgi::capture {

/// sRGB-encoded value in [0, 1] -> linear; values outside [0, 1] are clamped first.
inline float srgbToLinear(float c) {
  c = c < 0.f ? 0.f : (c > 1.f ? 1.f : c);
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

/// Linear value -> sRGB-encoded in [0, 1]; negative, NaN and > 1 values are clamped.
inline float linearToSrgb(float c) {
  if (!(c > 0.f)) return 0.f;
  if (c >= 1.f) return 1.f;
  return c <= 0.0031308f ? c * 12.92f : 1.055f * std::pow(c, 1.f / 2.4f) - 0.055f;
}

}  // namespace mrgi::capture

#include <opencv2/core.hpp>

namespace mrgi::capture {
/// Relative luminance of linear Rec.709/sRGB primaries.
inline double luminance(const cv::Vec3d& rgb) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }
}  // namespace mrgi::capture

namespace mrgi::capture {
/// RGB8 sRGB image (CV_8UC3) -> linear CV_32FC3.
cv::Mat decodeSrgb(const cv::Mat& rgb8);
/// Scene radiance from a camera's 8-bit sRGB image taken at `exposure` (linear value per unit radiance).
inline cv::Mat radianceOf(const cv::Mat& rgb8, double exposure) {
  cv::Mat linear = decodeSrgb(rgb8);
  if (exposure != 1.0) linear *= 1.0 / exposure;
  return linear;
}
/// Linear CV_32FC3 -> RGB8 sRGB (rounded to nearest; clamped; NaN -> 0).
cv::Mat encodeSrgb(const cv::Mat& linear);
}  // namespace mrgi::capture
