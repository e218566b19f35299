#pragma once
/// The ambient as the shading pass has it: a uniform radiance plus SH bands 0-2 of the directional remainder
/// (lighting/sh.h convention), and what the techniques that gather it (imperfect volumes, precomputed
/// illuminance composition) need of it on the CPU.
#include <array>
#include <memory>
#include <opencv2/core.hpp>

#include "lighting/radiance_map.h"

namespace mrgi::lighting {

struct Ambient {
  cv::Vec3f uniform{0, 0, 0};
  std::array<cv::Vec3f, 9> sh{};  ///< zero = none
  /// The same light over every direction, sharper than its SH bands (a room seen from the objects), for what the
  /// objects hide of it across the caps they cover (lighting/object_shadow.h); null: the SH alone.
  std::shared_ptr<const RadianceMap> map;
  /// The 9 coefficients of the whole ambient (the uniform part on y_00).
  std::array<cv::Vec3f, 9> coefficients() const;
  /// Irradiance about n, as the shading pass: pi uniform + the SH part's clamped cosine, clamped at 0.
  cv::Vec3f irradiance(const cv::Vec3f& n) const;
  /// Radiance arriving from direction w (towards the scene), each channel clamped at 0.
  cv::Vec3f radiance(const cv::Vec3f& w) const;
};

}  // namespace mrgi::lighting
