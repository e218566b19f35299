#version 450 core
// Per-pixel lighting for the compositor (algorithms.md §3, Algorithm 1), linear light:
//   real pixel:    rgb = E_delta * albedo / pi, a = 0   (the compositor adds it to the background)
//                  E_delta from the delta volume (dlpv), V^rho - V^mu (lpv-diff), or only the direct light
//                  the object blocks, sum_i E_i (vis_i(RSM^rho) - vis_i(RSM^mu)) (kinect-val alone)
//   virtual pixel: rgb = (sum_i E_i * visibility_i + pi * ambient) * albedo / pi + indirect, a = 1
//                  indirect = E_indirect(V^rho) * albedo / pi, or the Kinect-VAL radiance pass's output
//   no surface:    rgb = 0, a = 0
// Output 1 (debug): rgb = E_delta (real) or E_indirect (virtual) in W/m^2, a = 1 where a surface was seen.
#include "lighting/lpv.glsl"
#define MAX_LIGHTS 16

layout(binding = 0) uniform sampler2D uGPosition;
layout(binding = 1) uniform sampler2D uGNormal;
layout(binding = 2) uniform sampler2D uGAlbedo;
layout(binding = 3) uniform sampler3D uDeltaR;  // V^delta, or V^rho (direct + indirect) for lpv-diff
layout(binding = 4) uniform sampler3D uDeltaG;
layout(binding = 5) uniform sampler3D uDeltaB;
layout(binding = 6) uniform sampler3D uMuR;     // lpv-diff only: V^mu, subtracted
layout(binding = 7) uniform sampler3D uMuG;
layout(binding = 8) uniform sampler3D uMuB;
layout(binding = 9) uniform sampler3D uRhoR;    // V^rho, indirect only: bounce light on the virtual object
layout(binding = 10) uniform sampler3D uRhoG;
layout(binding = 11) uniform sampler3D uRhoB;
layout(binding = 12) uniform sampler2DArray uShadow;  // per light: RSM^rho world positions (w = 1 where seen)
layout(binding = 13) uniform sampler2DArray uShadowMu;  // kinect-val alone: RSM^mu world positions
layout(binding = 14) uniform sampler2D uValRadiance;   // Kinect-VAL: indirect radiance of virtual pixels
layout(binding = 15) uniform sampler2D uValIrradiance; // Kinect-VAL: its irradiance E (debug output)

uniform vec3 uGridOrigin;
uniform float uCellSize;
uniform int uResolution;
uniform int uRealMode;    // real pixels: 0 delta volume, 1 V^rho - V^mu, 2 direct shadow only
uniform int uVirtualMode; // virtual pixels' bounce light: 0 V^rho, 1 Kinect-VAL
uniform int uLighting; // 0: no virtual object in this frame (everything zero)
uniform vec3 uAmbient; // radiance, W/m^2/sr
uniform int uLightCount;
uniform int uLightType[MAX_LIGHTS];
uniform vec3 uLightPosition[MAX_LIGHTS];
uniform vec3 uLightDirection[MAX_LIGHTS];
uniform vec3 uLightPower[MAX_LIGHTS];
uniform float uSpotCos[MAX_LIGHTS];
uniform mat4 uLightViewProj[MAX_LIGHTS];
uniform float uShadowBias[MAX_LIGHTS];  // metres, distance tolerance of the shadow test

layout(location = 0) out vec4 outShade;
layout(location = 1) out vec4 outIrradiance;

// Shadow-map test with a normal offset: the lookup point moves off the surface by the bias (about two map
// texels) along its normal, so surfaces near the terminator (depth slope ~ tan θ per texel) do not shadow
// themselves; the depth comparison keeps the same tolerance for the remaining slope.
float visibility(sampler2DArray map, int i, vec3 x, vec3 n) {
  x += n * max(uShadowBias[i], 0.0);
  vec4 c = uLightViewProj[i] * vec4(x, 1.0);
  if (c.w <= 0.0) return 1.0;
  vec3 ndc = c.xyz / c.w;
  if (any(greaterThan(abs(ndc.xy), vec2(1.0)))) return 1.0;  // outside the map: not occluded by the object
  vec4 s = texture(map, vec3(ndc.xy * 0.5 + 0.5, float(i)));
  if (s.w < 0.5) return 1.0;
  float dSelf, dOcc;
  if (uLightType[i] == 2) {
    dSelf = dot(x, uLightDirection[i]);
    dOcc = dot(s.xyz, uLightDirection[i]);
  } else {
    dSelf = distance(x, uLightPosition[i]);
    dOcc = distance(s.xyz, uLightPosition[i]);
  }
  return dOcc < dSelf - uShadowBias[i] ? 0.0 : 1.0;
}

vec3 directIrradiance(sampler2DArray map, vec3 x, vec3 n) {
  vec3 e = vec3(0.0);
  for (int i = 0; i < uLightCount; ++i) {
    vec3 contribution;
    if (uLightType[i] == 2) {
      contribution = uLightPower[i] * max(dot(n, -uLightDirection[i]), 0.0);
    } else {
      vec3 l = uLightPosition[i] - x;
      float d2 = max(dot(l, l), 1e-8);
      vec3 ln = l * inversesqrt(d2);
      if (uLightType[i] == 1 && dot(-ln, uLightDirection[i]) < uSpotCos[i]) continue;
      contribution = uLightPower[i] * max(dot(n, ln), 0.0) / d2;
    }
    if (any(greaterThan(contribution, vec3(0.0)))) e += contribution * visibility(map, i, x, n);
  }
  return e;
}

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 pos = texelFetch(uGPosition, p, 0);
  outShade = vec4(0.0);
  outIrradiance = vec4(0.0);
  if (pos.w < 0.5) return;
  vec3 n = texelFetch(uGNormal, p, 0).xyz;
  vec4 albedo = texelFetch(uGAlbedo, p, 0);
  bool isVirtual = albedo.a > 0.5;
  if (uLighting == 0) {
    outIrradiance = vec4(0.0, 0.0, 0.0, 1.0);
    return;
  }
  LpvGrid grid = LpvGrid(uGridOrigin, uCellSize, uResolution);
  if (isVirtual) {
    vec3 e = directIrradiance(uShadow, pos.xyz, n) + LPV_PI * uAmbient;
    if (uVirtualMode == 1) {
      outShade = vec4(e * albedo.rgb / LPV_PI + texelFetch(uValRadiance, p, 0).rgb, 1.0);
      outIrradiance = vec4(texelFetch(uValIrradiance, p, 0).rgb, 1.0);
    } else {
      vec3 indirect = max(lpvIrradiance(uRhoR, uRhoG, uRhoB, grid, pos.xyz, n), vec3(0.0));
      outShade = vec4((e + indirect) * albedo.rgb / LPV_PI, 1.0);
      outIrradiance = vec4(indirect, 1.0);
    }
  } else {
    vec3 delta;
    if (uRealMode == 2) {
      delta = directIrradiance(uShadow, pos.xyz, n) - directIrradiance(uShadowMu, pos.xyz, n);
    } else {
      delta = lpvIrradiance(uDeltaR, uDeltaG, uDeltaB, grid, pos.xyz, n);
      if (uRealMode == 1) delta -= lpvIrradiance(uMuR, uMuG, uMuB, grid, pos.xyz, n);
    }
    outShade = vec4(delta * albedo.rgb / LPV_PI, 0.0);
    outIrradiance = vec4(delta, 1.0);
  }
}
