#version 450 core
// The shading pass's object terms (lighting/object_terms.glsl) on the reduced G-buffer (frame knob
// render_scale < 1): they vary smoothly over a surface, and the shading pass upsamples them joint-bilaterally
// as it does the techniques' reduced outputs (lighting/upsample.glsl), keeping the objects' direct shadow at
// the frame's resolution. rgb = the terms (W/m^2) on real pixels where a sphere is seen, else 0.
#define SHADE_PI 3.14159265358979
layout(binding = 0) uniform sampler2D uGPosition;
layout(binding = 1) uniform sampler2D uGNormal;
layout(binding = 2) uniform sampler2D uGAlbedo;
#include "lighting/direct_light.glsl"
#include "lighting/ambient_sh.glsl"
#include "lighting/object_terms.glsl"

layout(location = 0) out vec4 outTerms;

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 pos = texelFetch(uGPosition, p, 0);
  vec3 n = texelFetch(uGNormal, p, 0).xyz;
  outTerms = vec4(0.0);
  if (pos.w < 0.5 || texelFetch(uGAlbedo, p, 0).a > 0.5 || !objectsSeen(pos.xyz, n)) return;
  outTerms = vec4(objectTerms(pos.xyz, n, directIrradiance(false, pos.xyz, n), directIrradiance(true, pos.xyz, n)), 1.0);
}
