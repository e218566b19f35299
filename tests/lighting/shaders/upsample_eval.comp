#version 450 core
// Evaluates lighting/upsample.glsl for the GL parity test: per frame pixel, the upsampled value of uValue.
#include "lighting/upsample.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0) uniform sampler2D uPosition;
layout(binding = 1) uniform sampler2D uNormal;
layout(binding = 2) uniform sampler2D uLowPosition;
layout(binding = 3) uniform sampler2D uLowNormal;
layout(binding = 4) uniform sampler2D uValue;
layout(std430, binding = 0) writeonly buffer Results { vec4 results[]; };
uniform int uFactor;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy), size = textureSize(uPosition, 0);
  if (p.x >= size.x || p.y >= size.y) return;
  vec3 v = upsampled(uValue, uLowPosition, uLowNormal, uFactor, p, texelFetch(uPosition, p, 0), texelFetch(uNormal, p, 0));
  results[p.y * size.x + p.x] = vec4(v, 1.0);
}
