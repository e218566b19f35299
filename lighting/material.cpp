#include "lighting/material.h"

#include <algorithm>
#include <cmath>

namespace mrgi::lighting {

float phongLobe(float c, float k) {
  if (k <= 0.f) return 1.f;
  if (c <= 0.f) return 0.f;
  return std::exp(k * std::log(c));
}

float phongExponent(float roughness) {
  const float r = std::clamp(roughness, 0.f, 1.f);
  if (r <= 0.f) return kMaxPhongExponent;
  return std::clamp(2.f / (r * r) - 2.f, 0.f, kMaxPhongExponent);
}

}  // namespace mrgi::lighting
