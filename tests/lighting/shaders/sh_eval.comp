#version 450 core
// Evaluates lighting/sh.glsl for the GL parity test: per item, SH_COEFFS basis values at dirs[i].xyz,
// 8 Phong factors for exponent dirs[i].w, 8 cone zonal coefficients for half-angle alphas[i].
#include "lighting/sh.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Dirs { vec4 dirs[]; };
layout(std430, binding = 1) readonly buffer Alphas { float alphas[]; };
layout(std430, binding = 2) writeonly buffer Results { float results[]; };
uniform int uCount;

void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= uCount) return;
  const int stride = SH_COEFFS + 2 * SH_BANDS;
  float y[SH_COEFFS];
  shEvaluate(dirs[i].xyz, y);
  for (int k = 0; k < SH_COEFFS; ++k) results[i * stride + k] = y[k];
  for (int l = 0; l < SH_BANDS; ++l) {
    results[i * stride + SH_COEFFS + l] = shPhongFactor(dirs[i].w, l);
    results[i * stride + SH_COEFFS + SH_BANDS + l] = shConeZonal(alphas[i], l);
  }
}
