#version 450 core
// Splatting, sampling one light's pixel lights by hierarchical warping (splat.h warp): sample i takes the R2
// point of index uFirstSample + i, descends the importance pyramid from its top (vertical split, then
// horizontal within the chosen row) to a texel t, and writes that texel's pixel lights with the weight
// total / (N p_t) (an unbiased estimate of the sum over all texels):
//   uMode 0 (real-pixel delta): 3 records: RSM^rho's diffuse light (an object's texel: the light's bounce
//                              alone; the ambient it hides and reflects is the shading pass's), its glossy
//                              light (a glossy object's texel; else zero flux) and RSM^mu's diffuse light with
//                              negated flux
//   uMode 1 (the object):       1 record, the real surface's diffuse light (RSM^rho's real texel, else
//                              RSM^mu's in the object's shadow)
// The object's diffuse fluxes as splat_texel.glsl makes them (with the ambient's bounce and, for an
// occluder, the ambient it blocks), as the importance weighs them.
#include "lighting/techniques/splatting/splat.glsl"
#include "lighting/techniques/splatting/splat_texel.glsl"
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
uniform float uWiden;
uniform float uSpecular[MAX_OBJECTS];
uniform float uExponent[MAX_OBJECTS];

float at(int level, ivec2 t) {
  int side = 1 << (uLevels - 1 - level);
  return pyr[uLevelOffset[level] + t.y * side + t.x];
}

// A texel's diffuse pixel light of flux f (its footprint from splat_texel.glsl).
PixelLight diffuseLight(vec4 p, vec4 n, vec3 f, float area, float scale) {
  PixelLight l;
  l.positionArea = vec4(p.xyz, area);
  l.normalExponent = vec4(n.xyz, 0.0);
  l.fluxWiden = vec4(f * scale, 0.0);
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
  vec4 pm = texelFetch(uMuPosition, t, 0), nm = texelFetch(uMuNormal, t, 0);
  vec3 toLight;
  float area;
  if (uMode == 1) {
    // The object's light from a real surface: its direct bounce, ambient bounce and the ambient it blocks; where
    // the object hides it from the light (RSM^rho shows the object), RSM^mu's surface, in the object's shadow.
    // Its area is that of the texels the sample stands for (the footprint x its weight, at least the
    // footprint): a receiver touching it gets at most their radiosity, not one texel's flux over one texel.
    if (pr.w > 0.5 && nr.w < 0.5) {
      vec3 direct = texelFetch(uRhoDirect, t, 0).rgb;
      area = splatTexelArea(pr.xyz, nr.xyz, direct, toLight);
      vec3 f = splatTexelFlux(nr.xyz, texelFetch(uRhoFlux, t, 0).rgb, direct, area, true);
      lights[uFirstRecord + i] = diffuseLight(pr, nr, f, area * max(scale, 1.0), scale);
    } else if (pm.w > 0.5) {
      vec3 direct = texelFetch(uMuDirect, t, 0).rgb;
      area = splatTexelArea(pm.xyz, nm.xyz, direct, toLight);
      vec3 f = splatTexelFlux(nm.xyz, texelFetch(uMuFlux, t, 0).rgb, direct, area, false);
      lights[uFirstRecord + i] = diffuseLight(pm, nm, f, area * max(scale, 1.0), scale);
    }
    return;
  }
  int base = uFirstRecord + 3 * i;
  if (pr.w > 0.5) {
    // The light's bounce off the texel: the ambient an object reflects and hides from the real surfaces
    // is the shading pass's (lighting/object_shadow.h), and a real surface RSM^rho shows is there in both
    // versions (the ambient's parts cancel).
    vec3 direct = texelFetch(uRhoDirect, t, 0).rgb, flux = texelFetch(uRhoFlux, t, 0).rgb;
    bool isObject = nr.w > 0.5;
    area = splatTexelArea(pr.xyz, nr.xyz, direct, toLight);
    lights[base] = diffuseLight(pr, nr, flux, area, scale);
    if (isObject) {
      int obj = clamp(int(nr.w + 0.5) - 1, 0, MAX_OBJECTS - 1);
      if (uSpecular[obj] > 0.0 && uExponent[obj] > 0.0) {
        PixelLight g = diffuseLight(pr, nr, uSpecular[obj] * direct, area, scale);
        g.normalExponent.w = uExponent[obj];
        g.fluxWiden.w = uWiden;
        g.axis = vec4(reflect(-toLight, nr.xyz), 0.0);
        lights[base + 1] = g;
      }
    }
  }
  if (pm.w > 0.5) {
    // The real surface the object hides from the light loses its direct bounce only: it is still there,
    // reflecting and blocking the ambient as before.
    float a = splatTexelArea(pm.xyz, nm.xyz, texelFetch(uMuDirect, t, 0).rgb, toLight);
    lights[base + 2] = diffuseLight(pm, nm, -texelFetch(uMuFlux, t, 0).rgb, a, scale);
  }
}
