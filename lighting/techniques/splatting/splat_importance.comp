#version 450 core
// Splatting, importance of one light's RSM texels (splat.h importance), level 0 of two sum pyramids
// (padded to P x P, a power of two):
//   delta:  texels where RSM^rho and RSM^mu differ (the object, and the real surfaces it hides from the
//           light): lum(Phi_rho) (+ the glossy lobe's lum(s Phi) (1 + P) on a glossy object) + lum(Phi_mu),
//           the texels' direct bounce (the ambient the objects hide and reflect is the shading pass's); each
//           texel's terms times (1 - AO), AO its occlusion in its RSM (rsmOcclusion)
//   object: the real surfaces (RSM^rho's real texels; RSM^mu's where RSM^rho shows the object, without
//           their direct bounce: they lie in its shadow): what they send the object and the ambient they block
#include "lighting/techniques/splatting/splat.glsl"
#include "lighting/techniques/splatting/splat_texel.glsl"
#define MAX_OBJECTS 16
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D uRhoPosition;
layout(binding = 1) uniform sampler2D uRhoNormal;
layout(binding = 2) uniform sampler2D uRhoFlux;
layout(binding = 3) uniform sampler2D uRhoDirect;
layout(binding = 4) uniform sampler2D uMuPosition;
layout(binding = 5) uniform sampler2D uMuNormal;
layout(binding = 6) uniform sampler2D uMuFlux;
layout(binding = 7) uniform sampler2D uMuDirect;

layout(std430, binding = 0) writeonly buffer DeltaImportance { float delta[]; };
layout(std430, binding = 1) writeonly buffer ObjectImportance { float object[]; };

uniform int uSize;    // RSM texels per side
uniform int uPadded;  // P
uniform float uSpecular[MAX_OBJECTS];
uniform float uExponent[MAX_OBJECTS];

uniform float uAoRadius;  // metres (splat.h rsmOcclusion)

float lum(vec3 c) { return splatLum(abs(c)); }

// splat.h rsmOcclusion: screen-space AO of texel t in the light's view, at most 0.9.
float rsmOcclusion(sampler2D positions, vec3 p, vec3 n, ivec2 t) {
  const ivec2 dirs[8] = ivec2[8](ivec2(1, 0), ivec2(1, 1), ivec2(0, 1), ivec2(-1, 1), ivec2(-1, 0), ivec2(-1, -1), ivec2(0, -1),
                                 ivec2(1, -1));
  if (!(uAoRadius > 0.0)) return 0.0;
  float occ = 0.0;
  for (int r = 0; r < 2; ++r)
    for (int k = 0; k < 8; ++k) {
      ivec2 q = t + (r == 0 ? 2 : 5) * dirs[k];
      if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, ivec2(uSize)))) continue;
      vec4 o = texelFetch(positions, q, 0);
      if (!(o.w > 0.5)) continue;
      vec3 v = o.xyz - p;
      float len = sqrt(dot(v, v));
      if (!(len > 0.0) || len >= uAoRadius) continue;
      if (dot(n, v) > 0.2 * len) occ += 1.0 - len / uAoRadius;
    }
  return min(occ / 16.0, 0.9);
}
// The luminance of a texel's diffuse flux as the sampling pass makes its light (splat_texel.glsl).
float texelFluxLum(vec4 p, vec4 n, vec3 flux, vec3 direct, bool withDirect) {
  vec3 toLight;
  float area = splatTexelArea(p.xyz, n.xyz, direct, toLight);
  return lum(splatTexelFlux(n.xyz, flux, direct, area, withDirect));
}
float finiteOrZero(float v) { return (isnan(v) || isinf(v) || v < 0.0) ? 0.0 : v; }

void main() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  if (t.x >= uPadded || t.y >= uPadded) return;
  int k = t.y * uPadded + t.x;
  float d = 0.0, o = 0.0;
  if (t.x < uSize && t.y < uSize) {
    vec4 pr = texelFetch(uRhoPosition, t, 0), nr = texelFetch(uRhoNormal, t, 0), fr = texelFetch(uRhoFlux, t, 0);
    vec4 pm = texelFetch(uMuPosition, t, 0), nm = texelFetch(uMuNormal, t, 0), fm = texelFetch(uMuFlux, t, 0);
    bool differs = pr != pm || nr != nm || fr != fm;
    // The diffuse fluxes as the sampling pass makes the lights.
    vec3 dr = texelFetch(uRhoDirect, t, 0).rgb, dm = texelFetch(uMuDirect, t, 0).rgb;
    bool isObject = pr.w > 0.5 && nr.w > 0.5;
    float aoRho = pr.w > 0.5 ? rsmOcclusion(uRhoPosition, pr.xyz, nr.xyz, t) : 0.0;
    float aoMu = pm.w > 0.5 ? rsmOcclusion(uMuPosition, pm.xyz, nm.xyz, t) : 0.0;
    if (differs) {
      if (pr.w > 0.5) {
        float r = lum(fr.rgb);
        if (isObject) {
          int obj = clamp(int(nr.w + 0.5) - 1, 0, MAX_OBJECTS - 1);
          if (uSpecular[obj] > 0.0) r += lum(uSpecular[obj] * dr) * (1.0 + uExponent[obj]);
        }
        d += r * (1.0 - aoRho);
      }
      if (pm.w > 0.5) d += lum(fm.rgb) * (1.0 - aoMu);
    }
    if (pr.w > 0.5 && !isObject)
      o = texelFluxLum(pr, nr, fr.rgb, dr, true) * (1.0 - aoRho);
    else if (pm.w > 0.5)
      o = texelFluxLum(pm, nm, fm.rgb, dm, false) * (1.0 - aoMu);
  }
  delta[k] = finiteOrZero(d);
  object[k] = finiteOrZero(o);
}
