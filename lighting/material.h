#pragma once
/// The material model of virtual objects shared by every technique and the reference: Lambertian albedo
/// plus a normalised Phong lobe (exponent from the roughness).
#include <opencv2/core.hpp>

namespace mrgi::lighting {

constexpr float kMaxPhongExponent = 1e4f;

/// Phong exponent of a material: k = 2/r² − 2 (r = roughness), 0 at r = 1, clamped to [0, 10⁴].
float phongExponent(float roughness);
/// cos^k of the angle c to the mirror direction: 1 everywhere at k = 0 (also at c ≤ 0), 0 below the lobe
/// otherwise. A technique evaluating the lobe on the GPU keeps a GLSL twin held to this by a test.
float phongLobe(float c, float k);
/// c_k = (k + 1) / (2π): the normalised Phong lobe.
inline float phongNorm(float k) { return (k + 1.0f) / (2.0f * static_cast<float>(CV_PI)); }

}  // namespace mrgi::lighting
