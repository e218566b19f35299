#version 450 core
// Differential-rendering merge (algorithms.md §3, Algorithm 1), in linear light.
// real pixel:    background + exposure * delta          (delta already holds E_delta * albedo / pi)
// virtual pixel: exposure * the virtual object's shaded radiance
// The camera's linear values are scene radiance x its exposure; the lighting works in scene radiance.
#include "compositor/colour.glsl"

layout(binding = 0) uniform sampler2D uBackground;  // RGBA8, sRGB-encoded camera image, row 0 = top
layout(binding = 1) uniform sampler2D uDelta;       // RGBA32F linear: rgb = delta radiance, a = 1 on virtual pixels
layout(location = 0) out vec4 outColour;             // RGBA8, sRGB-encoded
uniform float uExposure = 1.0;

void main() {
  const ivec2 p = ivec2(gl_FragCoord.xy);
  const vec3 background = srgbToLinear(texelFetch(uBackground, p, 0).rgb);
  const vec4 delta = texelFetch(uDelta, p, 0) * vec4(vec3(uExposure), 1.0);
  const vec3 linear = delta.a > 0.5 ? delta.rgb : background + delta.rgb;
  outColour = vec4(linearToSrgb(linear), 1.0);
}
