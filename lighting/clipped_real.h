#pragma once
/// Real pixels whose camera channels are clipped: which channels, and the delta the objects make there taken
/// from the radiance the lights predict rather than from the sensor's white (lighting/clipped_real.glsl, whose
/// C++ twin this is; the shading pass applies it).
#include <algorithm>
#include <cstdint>
#include <opencv2/core.hpp>

namespace mrgi::lighting {

/// An 8-bit channel at or above this reads the sensor's white (reconstruction::AlbedoOptions::saturationLevel).
constexpr int kClippedLevel = 250;

/// Bit k set where channel k of `rgb` is at or above `level`.
inline uint8_t clippedChannelBits(const cv::Vec3b& rgb, int level = kClippedLevel) {
  return static_cast<uint8_t>((rgb[0] >= level ? 1 : 0) | (rgb[1] >= level ? 2 : 0) | (rgb[2] >= level ? 4 : 0));
}

/// clippedChannelBits of every pixel of an RGB8 image (CV_8UC1).
cv::Mat clippedChannels(const cv::Mat& rgb8, int level = kClippedLevel);

/// clipped_real.glsl's clippedRealShade: `shaded` = albedo E_delta / pi, `predicted` = albedo E / pi (E without
/// the objects), `white` the camera's white in scene radiance (<= 0: unchanged), `bits` the clipped channels.
/// A clipped channel the objects darken gets min(0, shaded + max(predicted - white, 0)).
inline cv::Vec3f clippedRealShade(const cv::Vec3f& shaded, const cv::Vec3f& predicted, float white, int bits) {
  if (!(white > 0) || bits <= 0) return shaded;
  cv::Vec3f result = shaded;
  for (int k = 0; k < 3; ++k)
    if ((bits >> k & 1) && shaded[k] < 0) result[k] = std::min(0.f, shaded[k] + std::max(predicted[k] - white, 0.f));
  return result;
}

}  // namespace mrgi::lighting
