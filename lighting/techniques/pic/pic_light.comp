#version 450 core
// Precomputed illuminance composition: the surfels' outgoing flux (pic.h surfelFlux): albedo x (the lights'
// direct irradiance where the surfel sees them (the visibility bits, Embree; the lights' uniforms of
// lighting/direct_light.glsl, its shadow maps unused) + the ambient's irradiance +
// the bounce from its receiver's cache about its normal (uBounce)) x area, never negative; stored as RGB9E5
// (uPacked) or RGBA32F per node (the leaves are nodes 0 .. surfels-1).
#include "lighting/ambient_sh.glsl"
#include "lighting/direct_light.glsl"
#include "lighting/techniques/pic/pic.glsl"
layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Surfels { PicSurfel surfels[]; };
layout(std430, binding = 1) readonly buffer Visibility { uint visible[]; };  // bit l: light l
layout(std430, binding = 2) buffer FluxF { vec4 fluxF[]; };
layout(std430, binding = 3) buffer FluxP { uint fluxP[]; };
layout(std430, binding = 4) readonly buffer Receivers { float receivers[]; };  // PIC_CACHE_FLOATS each

uniform int uCount;
uniform int uPacked;
uniform int uBounce;
uniform vec3 uAmbient;
uniform vec3 uAmbientSh[9];

void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= uCount) return;
  PicSurfel s = surfels[i];
  vec3 n = s.normalReceiver.xyz;
  vec3 e = SH_PI * uAmbient + ambientShIrradiance(uAmbientSh, n);
  e = max(e, vec3(0.0));
  uint bits = visible[i];
  for (int l = 0; l < uLightCount; ++l)
    if ((bits & (1u << uint(l))) != 0u) e += unshadowedIrradiance(l, s.positionArea.xyz, n);
  int r = int(s.normalReceiver.w);
  if (uBounce != 0 && r >= 0) {
    float cache[PIC_CACHE_FLOATS];
    for (int k = 0; k < PIC_CACHE_FLOATS; ++k) cache[k] = receivers[r * PIC_CACHE_FLOATS + k];
    e += SH_PI * picLobe(cache, n, 1.0);
  }
  vec3 f = s.albedo.rgb * e * s.positionArea.w;
  if (any(isnan(f)) || any(isinf(f))) f = vec3(0.0);
  f = max(f, vec3(0.0));
  if (uPacked != 0)
    fluxP[i] = picPackRgb9e5(f);
  else
    fluxF[i] = vec4(f, 0.0);
}
