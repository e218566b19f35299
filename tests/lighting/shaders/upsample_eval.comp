#version 450 core
// Evaluates lighting/upsample.glsl for the GL parity test: per frame pixel, the upsampled value of uValue, and
// upsampledPair() of uValue and uValue2.
#include "lighting/upsample.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0) uniform sampler2D uPosition;
layout(binding = 1) uniform sampler2D uNormal;
layout(binding = 2) uniform sampler2D uLowPosition;
layout(binding = 3) uniform sampler2D uLowNormal;
layout(binding = 4) uniform sampler2D uValue;
layout(binding = 5) uniform sampler2D uValue2;
layout(std430, binding = 0) writeonly buffer Results { vec4 results[]; };
layout(std430, binding = 1) writeonly buffer Pairs { vec4 pairs[]; };  // per pixel: uValue's, then uValue2's
uniform int uFactor;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy), size = textureSize(uPosition, 0);
  if (p.x >= size.x || p.y >= size.y) return;
  vec3 v = upsampled(uValue, uLowPosition, uLowNormal, uFactor, p, texelFetch(uPosition, p, 0), texelFetch(uNormal, p, 0));
  results[p.y * size.x + p.x] = vec4(v, 1.0);
  vec3 a, b;
  upsampledPair(uValue, uValue2, uLowPosition, uLowNormal, uFactor, p, texelFetch(uPosition, p, 0),
                texelFetch(uNormal, p, 0), a, b);
  pairs[2 * (p.y * size.x + p.x)] = vec4(a, 1.0);
  pairs[2 * (p.y * size.x + p.x) + 1] = vec4(b, 1.0);
}
