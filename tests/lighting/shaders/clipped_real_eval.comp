#version 450 core
// Evaluates lighting/clipped_real.glsl for the GL parity test: per item, clippedRealShade of
// (shaded, predicted, white, code).
#include "lighting/clipped_real.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Shaded { vec4 shaded[]; };       // xyz, w = white
layout(std430, binding = 1) readonly buffer Predicted { vec4 predicted[]; }; // xyz, w = code
layout(std430, binding = 2) writeonly buffer Results { vec4 results[]; };
uniform int uCount;

void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= uCount) return;
  results[i] = vec4(clippedRealShade(shaded[i].xyz, predicted[i].xyz, shaded[i].w, predicted[i].w), 0.0);
}
