#version 450 core
// Precomputed illuminance composition's outputs for the shared shading pass, on virtual pixels (pic.h
// interpolateGrid, shIrradiance, shLobeRadiance): the grid's eight caches around the point, trilinear and
// weighed by how little of each lies behind geometry (1 - backFraction); out 0 the irradiance about the
// normal (the room's bounce minus the ambient it hides), out 1 the glossy radiance: the object's specular
// times the radiance over its normalised Phong lobe about the mirror direction.
#include "lighting/techniques/pic/pic.glsl"
#define MAX_OBJECTS 16

layout(binding = 0) uniform sampler2D uGPosition;
layout(binding = 1) uniform sampler2D uGNormal;
layout(binding = 2) uniform sampler2D uGAlbedo;
layout(std430, binding = 10) readonly buffer Caches { float caches[]; };
layout(std430, binding = 11) readonly buffer Back { float backFraction[]; };

uniform vec3 uGridCentre;
uniform float uGridSide;
uniform int uGridResolution;
uniform vec3 uCameraPosition;
uniform float uSpecular[MAX_OBJECTS];
uniform float uExponent[MAX_OBJECTS];

layout(location = 0) out vec4 outIrradiance;
layout(location = 1) out vec4 outRadiance;

void main() {
  outIrradiance = outRadiance = vec4(0.0);
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec4 pos = texelFetch(uGPosition, px, 0);
  if (pos.w < 0.5 || texelFetch(uGAlbedo, px, 0).a < 0.5) return;
  vec4 nw = texelFetch(uGNormal, px, 0);
  int R = max(uGridResolution, 1);
  vec3 g = (pos.xyz - (uGridCentre - 0.5 * uGridSide)) / uGridSide * float(R) - 0.5;
  g = clamp(g, vec3(0.0), vec3(float(R - 1)));
  ivec3 i0 = min(ivec3(g), ivec3(max(R - 2, 0)));
  vec3 f = R > 1 ? g - vec3(i0) : vec3(0.0);
  float w[8], plain[8], sum = 0.0;
  int idx[8];
  for (int k = 0; k < 8; ++k) {
    ivec3 d = ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
    ivec3 c = min(i0 + d, ivec3(R - 1));
    idx[k] = (c.z * R + c.y) * R + c.x;
    plain[k] = (d.x == 1 ? f.x : 1.0 - f.x) * (d.y == 1 ? f.y : 1.0 - f.y) * (d.z == 1 ? f.z : 1.0 - f.z);
    w[k] = plain[k] * (1.0 - backFraction[idx[k]]);
    sum += w[k];
  }
  bool usePlain = !(sum > 1e-6);
  float cache[PIC_CACHE_FLOATS];
  for (int j = 0; j < PIC_CACHE_FLOATS; ++j) cache[j] = 0.0;
  for (int k = 0; k < 8; ++k) {
    float wk = usePlain ? plain[k] : w[k] / sum;
    if (wk == 0.0) continue;
    for (int j = 0; j < PIC_CACHE_FLOATS; ++j) cache[j] += wk * caches[idx[k] * PIC_CACHE_FLOATS + j];
  }
  vec3 n = normalize(nw.xyz);
  vec3 e = SH_PI * picLobe(cache, n, 1.0);
  outIrradiance = vec4((any(isnan(e)) || any(isinf(e))) ? vec3(0.0) : e, 1.0);
  int obj = clamp(int(nw.w + 0.5) - 1, 0, MAX_OBJECTS - 1);
  if (uSpecular[obj] > 0.0) {
    vec3 v = normalize(uCameraPosition - pos.xyz);
    vec3 r = reflect(-v, n);
    vec3 l = uSpecular[obj] * picLobe(cache, r, uExponent[obj]);
    outRadiance = vec4((any(isnan(l)) || any(isinf(l))) ? vec3(0.0) : l, 1.0);
  }
}
