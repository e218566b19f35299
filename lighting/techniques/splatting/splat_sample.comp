#version 450 core
// Splatting, sampling one light's pixel lights by hierarchical warping (splat.h warp): sample i takes the R2
// point of index uFirstSample + i, descends the importance pyramid from its top (vertical split, then
// horizontal within the chosen row) to a texel t, and writes that texel's pixel lights with the weight
// total / (N p_t) (an unbiased estimate of the sum over all texels):
//   uMode 0 (real-pixel delta): 3 records: RSM^rho's diffuse light, its glossy light (a glossy object's texel;
//                              else zero flux) and RSM^mu's diffuse light with negated flux
//   uMode 1 (the object):       1 record, RSM^rho's diffuse light (real texels only)
#include "lighting/techniques/splatting/splat.glsl"
#define MAX_OBJECTS 16
#define MAX_LEVELS 14
layout(local_size_x = 64) in;

layout(binding = 0) uniform sampler2D uRhoPosition;
layout(binding = 1) uniform sampler2D uRhoNormal;
layout(binding = 2) uniform sampler2D uRhoFlux;
layout(binding = 3) uniform sampler2D uRhoDirect;
layout(binding = 4) uniform sampler2D uMuPosition;
layout(binding = 5) uniform sampler2D uMuNormal;
layout(binding = 6) uniform sampler2D uMuFlux;
layout(binding = 7) uniform sampler2D uMuDirect;

layout(std430, binding = 0) readonly buffer Pyramid { float pyr[]; };
layout(std430, binding = 2) writeonly buffer Lights { PixelLight lights[]; };

uniform int uMode;
uniform int uCount;        // samples of this light
uniform int uFirstSample;  // index of its first R2 point
uniform int uFirstRecord;  // where its records start
uniform int uLevels;       // levels of the pyramid (level uLevels - 1 is 1 x 1)
uniform int uLevelOffset[MAX_LEVELS];
uniform int uLightType;    // 0 point, 1 spot, 2 directional
uniform vec3 uLightPosition;
uniform vec3 uLightDirection;
uniform vec3 uLightPower;  // intensity (W/sr) or irradiance (W/m^2)
uniform float uWiden;
uniform float uSpecular[MAX_OBJECTS];
uniform float uExponent[MAX_OBJECTS];

float at(int level, ivec2 t) {
  int side = 1 << (uLevels - 1 - level);
  return pyr[uLevelOffset[level] + t.y * side + t.x];
}

// The texel's diffuse pixel light (area: the texel's footprint across the beam over <n, l>, clamped at 0.1;
// kinect_val valsFromRsm) and the light's direction towards it.
PixelLight texelLight(vec4 p, vec4 n, vec3 flux, vec3 direct, float scale, out vec3 toLight) {
  vec3 beam;
  if (uLightType == 2) {
    toLight = -uLightDirection;
    beam = uLightPower;
  } else {
    vec3 d = uLightPosition - p.xyz;
    float d2 = max(dot(d, d), 1e-12);
    toLight = d * inversesqrt(d2);
    beam = uLightPower / d2;
  }
  int c = beam.r >= beam.g && beam.r >= beam.b ? 0 : (beam.g >= beam.b ? 1 : 2);
  float across = beam[c] > 0.0 ? direct[c] / beam[c] : 0.0;
  PixelLight l;
  l.positionArea = vec4(p.xyz, across / max(dot(n.xyz, toLight), 0.1));
  l.normalExponent = vec4(n.xyz, 0.0);
  l.fluxWiden = vec4(flux * scale, 0.0);
  l.axis = vec4(n.xyz, 0.0);
  return l;
}

void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= uCount) return;
  int records = uMode == 0 ? 3 : 1;
  PixelLight none;
  none.positionArea = none.normalExponent = none.fluxWiden = none.axis = vec4(0.0);
  none.normalExponent.z = none.axis.z = 1.0;
  for (int r = 0; r < records; ++r) lights[uFirstRecord + records * i + r] = none;
  float total = at(uLevels - 1, ivec2(0));
  if (!(total > 0.0)) return;
  vec2 u = splatSamplePoint(uFirstSample + i);
  ivec2 t = ivec2(0);
  for (int k = uLevels - 2; k >= 0; --k) {
    t *= 2;
    float t0 = at(k, t), t1 = at(k, t + ivec2(1, 0)), b0 = at(k, t + ivec2(0, 1)), b1 = at(k, t + ivec2(1, 1));
    float rTop = (t0 + t1) / (t0 + t1 + b0 + b1);
    if (u.y < rTop) {
      u.y = u.y / rTop;
    } else {
      u.y = (u.y - rTop) / (1.0 - rTop);
      t.y += 1;
    }
    float l = (t.y % 2 == 0) ? t0 : b0, rr = (t.y % 2 == 0) ? t1 : b1;
    float c = l / (l + rr);
    if (u.x < c) {
      u.x = u.x / c;
    } else {
      u.x = (u.x - c) / (1.0 - c);
      t.x += 1;
    }
    u = clamp(u, vec2(0.0), vec2(0.99999994));
  }
  float p = at(0, t);
  if (!(p > 0.0)) return;
  float scale = total / (float(uCount) * p);
  vec4 pr = texelFetch(uRhoPosition, t, 0), nr = texelFetch(uRhoNormal, t, 0);
  vec3 toLight;
  if (uMode == 1) {
    lights[uFirstRecord + i] = texelLight(pr, nr, texelFetch(uRhoFlux, t, 0).rgb, texelFetch(uRhoDirect, t, 0).rgb, scale, toLight);
    return;
  }
  int base = uFirstRecord + 3 * i;
  if (pr.w > 0.5) {
    vec3 direct = texelFetch(uRhoDirect, t, 0).rgb;
    lights[base] = texelLight(pr, nr, texelFetch(uRhoFlux, t, 0).rgb, direct, scale, toLight);
    if (nr.w > 0.5) {
      int obj = clamp(int(nr.w + 0.5) - 1, 0, MAX_OBJECTS - 1);
      if (uSpecular[obj] > 0.0) {
        PixelLight g = texelLight(pr, nr, uSpecular[obj] * direct, direct, scale, toLight);
        g.normalExponent.w = max(uExponent[obj], 0.0);
        g.fluxWiden.w = uWiden;
        g.axis = vec4(reflect(-toLight, nr.xyz), 0.0);
        if (uExponent[obj] > 0.0) lights[base + 1] = g;
      }
    }
  }
  vec4 pm = texelFetch(uMuPosition, t, 0);
  if (pm.w > 0.5) {
    PixelLight m = texelLight(pm, texelFetch(uMuNormal, t, 0), texelFetch(uMuFlux, t, 0).rgb, texelFetch(uMuDirect, t, 0).rgb,
                              scale, toLight);
    m.fluxWiden.rgb = -m.fluxWiden.rgb;
    lights[base + 2] = m;
  }
}
