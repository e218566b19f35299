#version 450 core
// Imperfect volumes, the objects' cone (iv.h coneCorrection): per voxel near a surface and outside the
// sphere bounding the virtual objects, minus the first gather's (L_rho - L_mu) y(w) 4 pi / N over the
// gather's directions inside the cone the sphere subtends, plus the same difference over uConeRays rays
// stratified over that cone times its solid angle / uConeRays; added into rho's incident SH, so that the
// real-pixel delta samples the objects as densely from every voxel.
#include "lighting/techniques/imperfect_volumes/iv.glsl"

layout(local_size_x = 32) in;

layout(std430, binding = 2) readonly buffer Voxels { IvVoxel voxels[]; };
layout(std430, binding = 14) readonly buffer Occupancy { uint occupancy[]; };  // iv.glsl IV_REAL ...
layout(std430, binding = 3) readonly buffer Needed { uint needed[]; };
layout(std430, binding = 4) readonly buffer Directions { vec4 directions[]; };
layout(std430, binding = 5) buffer Incident { float incident[]; };
layout(std430, binding = 1) readonly buffer Hits { ivec2 hits[]; };  // iv_hits.comp (uCachedHits)
uniform int uCachedHits;  // 1: the rays' hits from iv_hits.comp, 0: marched here

uniform int uNeededCount;
uniform int uRays;
uniform int uConeRays;
uniform float uRange;
uniform int uBounceLight;  // 0: surfaces send nothing (ambient occlusion only)
uniform vec3 uAmbient;
uniform vec3 uAmbientSh[9];
uniform vec4 uBound;  // xyz centre, w radius (lighting world)

vec3 ivReflectedAt(int v) { return vec3(0.0); }  // the cone takes the first bounce only
#include "lighting/techniques/imperfect_volumes/iv_march.glsl"

// What one ray of the first gather with hits h brings (iv.cpp firstGatherRadiance).
vec3 firstGather(ivec2 h, vec3 d, bool rho) {
  bool hit, open;
  vec3 L = ivSurfaces(h, d, rho, false, hit, open);
  return open ? L + ambientRadiance(uAmbient, uAmbientSh, d) : L;
}
// L_rho - L_mu along one ray: one march serves both versions.
vec3 rhoMinusMu(ivec2 h, vec3 d) { return firstGather(h, d, true) - firstGather(h, d, false); }

void main() {
  int slot = int(gl_GlobalInvocationID.x);
  if (slot >= uNeededCount) return;
  int v = int(needed[slot]);
  vec3 o = ivCentre(ivCoords(v));
  vec3 axis = uBound.xyz - o;
  float dist = length(axis);
  if (!(dist > 1.0001 * uBound.w) || uConeRays <= 0) return;  // iv.cpp kConeOutside
  vec3 u = axis / dist;
  float sinA = uBound.w / dist, cosA = sqrt(max(0.0, 1.0 - sinA * sinA));
  float acc[3 * SH_COEFFS];
  for (int q = 0; q < 3 * SH_COEFFS; ++q) acc[q] = 0.0;
  float wUniform = 4.0 * SH_PI / float(uRays);
  // The gather's own directions inside the cone, taken out ...
  for (int j = 0; j < uRays; ++j) {
    vec3 d = directions[j].xyz;
    if (dot(d, u) < cosA) continue;
    vec3 diff = rhoMinusMu(ivRayHits(slot, j, o, d), d);
    if (diff == vec3(0.0)) continue;
    float y[SH_COEFFS];
    shEvaluate(d, y);
    for (int q = 0; q < SH_COEFFS; ++q) {
      acc[q] -= wUniform * diff.r * y[q];
      acc[SH_COEFFS + q] -= wUniform * diff.g * y[q];
      acc[2 * SH_COEFFS + q] -= wUniform * diff.b * y[q];
    }
  }
  // ... and the cone sampled in their place (iv.cpp capDirections).
  vec3 a = abs(u.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  vec3 x = normalize(cross(a, u)), yAxis = cross(u, x);
  float golden = SH_PI * (3.0 - sqrt(5.0));
  float wCone = 2.0 * SH_PI * (1.0 - cosA) / float(uConeRays);
  for (int k = 0; k < uConeRays; ++k) {
    float c = 1.0 - (1.0 - cosA) * (float(k) + 0.5) / float(uConeRays);
    float s = sqrt(max(0.0, 1.0 - c * c)), phi = golden * float(k);
    vec3 d = normalize(s * cos(phi) * x + s * sin(phi) * yAxis + c * u);
    vec3 diff = rhoMinusMu(ivHitsWithinRange(o, d), d);
    if (diff == vec3(0.0)) continue;
    float y[SH_COEFFS];
    shEvaluate(d, y);
    for (int q = 0; q < SH_COEFFS; ++q) {
      acc[q] += wCone * diff.r * y[q];
      acc[SH_COEFFS + q] += wCone * diff.g * y[q];
      acc[2 * SH_COEFFS + q] += wCone * diff.b * y[q];
    }
  }
  int base = v * 3 * SH_COEFFS;
  for (int q = 0; q < 3 * SH_COEFFS; ++q) incident[base + q] += acc[q];
}
