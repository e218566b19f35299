// Direct light of the scene's lights at a surface point, with shadow tests against the frame's shadow maps
// (world positions per light: layer i). Shared by the shading pass and techniques that light their own
// points (imperfect volumes); the C++ side binds the maps with FrameResources::bindShadowMaps and sets the
// uniforms with lighting::setLightUniforms; lighting::shadowVisibility is the C++ twin of the tests.
//   without the objects (mu): V = test(RSM^mu), the region's real surfaces
//   with the objects (rho):   V = test(RSM^mu) * test(objects' map), the objects' map holding the virtual
//                             objects alone in a view fitted to their bounding sphere (many times finer than
//                             the region's RSM: the object's shadow edges are what the delta is made of);
//                             test(RSM^rho) where a light sits too close to the objects for that view
#include "lighting/view_factor.glsl"

#ifndef MAX_LIGHTS
#define MAX_LIGHTS 16
#endif

layout(binding = 12) uniform sampler2DArray uShadowRho;      // per light: RSM^rho world positions (w = 1 where seen)
layout(binding = 13) uniform sampler2DArray uShadowMu;       // per light: RSM^mu world positions
layout(binding = 14) uniform sampler2DArray uShadowObjects;  // per light: the objects' world positions

uniform int uLightCount;
uniform int uLightType[MAX_LIGHTS];
uniform vec3 uLightPosition[MAX_LIGHTS];
uniform vec3 uLightDirection[MAX_LIGHTS];
uniform vec3 uLightPower[MAX_LIGHTS];
uniform float uSpotCos[MAX_LIGHTS];
uniform int uLightSoft[MAX_LIGHTS];      // 1: the objects' shadow of light i is soft (frame knob soft_shadow_lights)
uniform float uLightExtent[MAX_LIGHTS];  // directional: sin of its half-angle; point/spot: radius, metres
uniform mat4 uLightViewProj[MAX_LIGHTS];
uniform float uShadowBias[MAX_LIGHTS];  // metres, distance tolerance of the shadow test; < -1e29: no map
uniform mat4 uObjectViewProj[MAX_LIGHTS];
uniform float uObjectShadowBias[MAX_LIGHTS];  // < -1e29: no objects' map for this light (RSM^rho instead)
uniform float uObjectNear[MAX_LIGHTS];        // where the objects' sphere begins, in the test's distance

// The shadow test's distance of a point: along a directional light's direction, else from the light.
float lightDistance(int i, vec3 p) {
  return uLightType[i] == 2 ? dot(p, uLightDirection[i]) : distance(p, uLightPosition[i]);
}

// Where p falls in a light's map ([0, 1]^2), through the light's view and projection; false behind the light or
// outside the map (nothing there occludes p). lighting::mapCoordinates is the C++ twin.
bool mapCoordinates(mat4 viewProj, vec3 p, out vec2 uv) {
  vec4 c = viewProj * vec4(p, 1.0);
  uv = vec2(0.0);
  if (c.w <= 0.0) return false;
  vec2 ndc = c.xy / c.w;
  if (any(greaterThan(abs(ndc), vec2(1.0)))) return false;
  uv = ndc * 0.5 + 0.5;
  return true;
}

// The distance of what light i's map holds where p projects (1e30 where nothing, or outside the map: not
// occluded by what it holds).
float occluderDistance(sampler2DArray map, int i, mat4 viewProj, vec3 p) {
  vec2 uv;
  if (!mapCoordinates(viewProj, p, uv)) return 1e30;
  vec4 s = texture(map, vec3(uv, float(i)));
  return s.w < 0.5 ? 1e30 : lightDistance(i, s.xyz);
}

// Shadow-map test with a normal offset: the lookup point moves off the surface by the bias (about two map
// texels) along its normal, so surfaces near the terminator (depth slope ~ tan θ per texel) do not shadow
// themselves; the depth comparison keeps the same tolerance for the remaining slope.
float shadowTest(sampler2DArray map, int i, mat4 viewProj, float bias, vec3 x, vec3 n) {
  if (bias < -1e29) return 1.0;
  x += n * bias;
  return occluderDistance(map, i, viewProj, x) < lightDistance(i, x) - bias ? 0.0 : 1.0;
}

// Only where the including program defines SOFT_OBJECT_SHADOWS (the shading pass); techniques' own passes
// take the hard test of the light's centre.
#define SOFT_SHADOW_TAPS 16
#define SOFT_SHADOW_SEARCH_TAPS 8
// The objects' soft shadow of a light with extent (lighting::softObjectsShadow is the C++ twin): the blockers'
// mean distance over the widest penumbra, then the fraction of taps over the penumbra's disc left lit.
// Tap k of `taps` on a Vogel spiral over the disc of `radius` spanned by t and b.
vec3 softShadowTap(int k, int taps, float radius, vec3 t, vec3 b) {
  float r = radius * sqrt((float(k) + 0.5) / float(taps)), a = float(k) * 2.399963229728653;
  return r * cos(a) * t + r * sin(a) * b;
}

float softObjectsShadow(int i, vec3 at, vec3 n) {
  float bias = uObjectShadowBias[i];
  vec3 x = at + n * bias;  // the receiver with the normal offset the tests take
  float self = lightDistance(i, x);
  if (!(self - bias > uObjectNear[i])) return 1.0;
  bool directional = uLightType[i] == 2;
  vec3 L = directional ? uLightDirection[i] : normalize(x - uLightPosition[i]);
  vec3 t = normalize(cross(L, abs(L.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
  vec3 b = cross(L, t);
  float ext = uLightExtent[i];  // directional: sin a; point/spot: radius
  float tanA = ext / sqrt(max(1e-12, 1.0 - ext * ext));
  float near = uObjectNear[i];
  float widest = directional ? (self - near) * tanA : (self - near) * ext / max(near, 1e-4);
  if (widest < 0.5 * bias) return shadowTest(uShadowObjects, i, uObjectViewProj[i], bias, at, n);
  // Each tap compares with the receiver's tangent plane where the light's ray through the tap meets it.
  float facing = min(dot(n, L), -0.1);
  float sum = 0.0;
  int blockers = 0;
  for (int k = 0; k < SOFT_SHADOW_SEARCH_TAPS; ++k) {
    vec3 o = softShadowTap(k, SOFT_SHADOW_SEARCH_TAPS, widest, t, b);
    float d = occluderDistance(uShadowObjects, i, uObjectViewProj[i], x + o);
    if (d < self - dot(n, o) / facing - bias) {
      sum += d;
      ++blockers;
    }
  }
  if (blockers == 0) return 1.0;
  if (blockers == SOFT_SHADOW_SEARCH_TAPS) return 0.0;  // the widest penumbra's disc all covered: the umbra
  float dB = sum / float(blockers);
  float w = directional ? (self - dB) * tanA : (self - dB) * ext / max(dB, 1e-4);
  int lit = 0;
  for (int k = 0; k < SOFT_SHADOW_TAPS; ++k) {
    vec3 o = softShadowTap(k, SOFT_SHADOW_TAPS, w, t, b);
    if (!(occluderDistance(uShadowObjects, i, uObjectViewProj[i], x + o) < self - dot(n, o) / facing - bias)) ++lit;
  }
  return float(lit) / float(SOFT_SHADOW_TAPS);
}

// The real surfaces' map tested at the four texels around x's projection, the results weighed bilinearly: the
// visibility of a virtual surface changes over a texel where a real occluder's edge crosses it, not in a step a
// texel wide (the table's edge cutting off light from just below an object's horizon drew stair-step bands on
// its lower half). lighting::smoothShadowTest is the C++ twin.
float smoothShadowTest(sampler2DArray map, int i, mat4 viewProj, float bias, vec3 x, vec3 n) {
  if (bias < -1e29) return 1.0;
  x += n * bias;
  vec2 uv;
  if (!mapCoordinates(viewProj, x, uv)) return 1.0;
  ivec2 size = textureSize(map, 0).xy;
  vec2 f = uv * vec2(size) - 0.5;
  vec2 t0 = floor(f), w = f - t0;
  float self = lightDistance(i, x) - bias;
  float lit[4];
  for (int k = 0; k < 4; ++k) {
    ivec2 t = clamp(ivec2(t0) + ivec2(k & 1, k >> 1), ivec2(0), size - 1);
    vec4 s = texelFetch(map, ivec3(t, i), 0);
    lit[k] = s.w < 0.5 || !(lightDistance(i, s.xyz) < self) ? 1.0 : 0.0;
  }
  return mix(mix(lit[0], lit[1], w.x), mix(lit[2], lit[3], w.x), w.y);
}

// The objects' map's test of light i at (x, n): soft for the lights with extent the frame knob soft_shadow_lights
// picked (SOFT_OBJECT_SHADOWS), hard otherwise.
float objectsVisibility(int i, vec3 x, vec3 n) {
#ifdef SOFT_OBJECT_SHADOWS
  return uLightSoft[i] == 1 ? softObjectsShadow(i, x, n)  // set for lights with extent only
                            : shadowTest(uShadowObjects, i, uObjectViewProj[i], uObjectShadowBias[i], x, n);
#else
  return shadowTest(uShadowObjects, i, uObjectViewProj[i], uObjectShadowBias[i], x, n);
#endif
}

// A virtual surface's visibility of light i with the objects (the shading pass's virtual pixels): the real
// surfaces' map tested smoothly (smoothShadowTest), the objects' as for real receivers.
float virtualVisibility(int i, vec3 x, vec3 n) {
  if (uObjectShadowBias[i] < -1e29) return smoothShadowTest(uShadowRho, i, uLightViewProj[i], uShadowBias[i], x, n);
  return smoothShadowTest(uShadowMu, i, uLightViewProj[i], uShadowBias[i], x, n) * objectsVisibility(i, x, n);
}

float visibility(bool withObjects, int i, vec3 x, vec3 n) {
  if (!withObjects) return shadowTest(uShadowMu, i, uLightViewProj[i], uShadowBias[i], x, n);
  if (uObjectShadowBias[i] < -1e29) return shadowTest(uShadowRho, i, uLightViewProj[i], uShadowBias[i], x, n);
  return shadowTest(uShadowMu, i, uLightViewProj[i], uShadowBias[i], x, n) * objectsVisibility(i, x, n);
}

// Light i's irradiance at a point before any shadow test (lighting::unshadowedIrradiance); a light with
// extent keeps what of it is still above the surface's horizon (capCosine).
vec3 unshadowedIrradiance(int i, vec3 x, vec3 n) {
  if (uLightType[i] == 2) return uLightPower[i] * capCosine(dot(n, -uLightDirection[i]), uLightExtent[i]);
  vec3 l = uLightPosition[i] - x;
  float d2 = max(dot(l, l), 1e-8);
  vec3 ln = l * inversesqrt(d2);
  if (uLightType[i] == 1 && dot(-ln, uLightDirection[i]) < uSpotCos[i]) return vec3(0.0);
  float sinA = uLightExtent[i] > 0.0 ? min(uLightExtent[i] * inversesqrt(d2), 1.0) : 0.0;
  return uLightPower[i] * capCosine(dot(n, ln), sinA) / d2;
}

// The objects' direct shadow at (x, n) from the lights whose bit is set in `lights` (bit i: light i): for every
// light, directIrradiance(true, x, n) - directIrradiance(false, x, n), with each light's maps tested once: a light
// counts only where its objects' test leaves some of it out, or where it has no objects' map (RSM^rho's test
// against RSM^mu's); exactly zero where the objects shadow nothing.
vec3 objectsDirectShadow(int lights, vec3 x, vec3 n) {
  vec3 e = vec3(0.0);
  for (int i = 0; i < uLightCount; ++i) {
    if (((lights >> i) & 1) == 0) continue;
    vec3 contribution = unshadowedIrradiance(i, x, n);
    if (!any(greaterThan(contribution, vec3(0.0)))) continue;
    if (uObjectShadowBias[i] < -1e29) {  // no objects' map: RSM^rho's test against RSM^mu's
      float rho = shadowTest(uShadowRho, i, uLightViewProj[i], uShadowBias[i], x, n);
      float mu = shadowTest(uShadowMu, i, uLightViewProj[i], uShadowBias[i], x, n);
      e += contribution * (rho - mu);
      continue;
    }
    float objects = objectsVisibility(i, x, n);
    if (objects < 1.0) e += contribution * shadowTest(uShadowMu, i, uLightViewProj[i], uShadowBias[i], x, n) * (objects - 1.0);
  }
  return e;
}

// directIrradiance(true, x, n) for a virtual surface (virtualVisibility).
vec3 virtualDirectIrradiance(vec3 x, vec3 n) {
  vec3 e = vec3(0.0);
  for (int i = 0; i < uLightCount; ++i) {
    vec3 contribution = unshadowedIrradiance(i, x, n);
    if (any(greaterThan(contribution, vec3(0.0)))) e += contribution * virtualVisibility(i, x, n);
  }
  return e;
}

vec3 directIrradiance(bool withObjects, vec3 x, vec3 n) {
  vec3 e = vec3(0.0);
  for (int i = 0; i < uLightCount; ++i) {
    vec3 contribution = unshadowedIrradiance(i, x, n);
    if (any(greaterThan(contribution, vec3(0.0)))) e += contribution * visibility(withObjects, i, x, n);
  }
  return e;
}
