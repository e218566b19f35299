#pragma once
/// The reference's BRDF: Lambertian albedo plus the normalised Phong lobe ((k + 1) / (2 pi)) cos^k(alpha) about
/// the mirror direction (k = 0: uniform over the hemisphere). Written here, not taken from lighting/, so that
/// the path tracer shares no shading code with the real-time techniques it judges.
#include <cmath>

namespace mrgi::groundtruth {

/// cos^k(alpha) for the cosine to the mirror direction; 1 everywhere at k = 0, 0 behind the lobe otherwise.
inline float phongPower(float cosAlpha, float k) {
  if (k <= 0.f) return 1.f;
  return cosAlpha > 0.f ? std::pow(cosAlpha, k) : 0.f;
}

/// (k + 1) / (2 pi): the lobe integrates (times cos alpha about the mirror direction) to 1.
inline float phongNormalisation(float k) { return (k + 1.f) / (2.f * 3.14159265358979f); }

}  // namespace mrgi::groundtruth
