#version 450 core
// Splatting, importance of one light's RSM texels (splat.h importance), level 0 of two sum pyramids
// (padded to P x P, a power of two):
//   delta:  texels where RSM^rho and RSM^mu differ (the object, and the real surfaces it hides from the
//           light): lum(Phi_rho) (+ the glossy lobe's lum(s Phi) (1 + P) on a glossy object) + lum(Phi_mu)
//   object: the real texels of RSM^rho (the light real surfaces send the object; its own texels excluded)
#include "lighting/techniques/splatting/splat.glsl"
#define MAX_OBJECTS 16
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D uRhoPosition;
layout(binding = 1) uniform sampler2D uRhoNormal;
layout(binding = 2) uniform sampler2D uRhoFlux;
layout(binding = 3) uniform sampler2D uRhoDirect;
layout(binding = 4) uniform sampler2D uMuPosition;
layout(binding = 5) uniform sampler2D uMuNormal;
layout(binding = 6) uniform sampler2D uMuFlux;

layout(std430, binding = 0) writeonly buffer DeltaImportance { float delta[]; };
layout(std430, binding = 1) writeonly buffer ObjectImportance { float object[]; };

uniform int uSize;    // RSM texels per side
uniform int uPadded;  // P
uniform float uSpecular[MAX_OBJECTS];
uniform float uExponent[MAX_OBJECTS];

float lum(vec3 c) { return splatLum(abs(c)); }
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
    if (differs) {
      if (pr.w > 0.5) {
        d += lum(fr.rgb);
        if (nr.w > 0.5) {
          int obj = clamp(int(nr.w + 0.5) - 1, 0, MAX_OBJECTS - 1);
          if (uSpecular[obj] > 0.0)
            d += lum(uSpecular[obj] * texelFetch(uRhoDirect, t, 0).rgb) * (1.0 + uExponent[obj]);
        }
      }
      if (pm.w > 0.5) d += lum(fm.rgb);
    }
    if (pr.w > 0.5 && nr.w < 0.5) o = lum(fr.rgb);
  }
  delta[k] = finiteOrZero(d);
  object[k] = finiteOrZero(o);
}
