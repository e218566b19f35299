#version 450 core
// Delta injection (algorithms.md §3; C++ twin: lpv.h injectReference). One vertex per RSM texel, instance 0
// injects the indirect lobe, instance 1 the direct lobe. Texels bit-identical in the other RSM are skipped
// when uSkipIdentical is set, so unchanged texels cancel exactly.
#include "lighting/techniques/dlpv/lpv.glsl"

layout(binding = 0) uniform sampler2D uPosition;
layout(binding = 1) uniform sampler2D uNormal;
layout(binding = 2) uniform sampler2D uFlux;
layout(binding = 3) uniform sampler2D uDirect;
layout(binding = 4) uniform sampler2D uOtherPosition;
layout(binding = 5) uniform sampler2D uOtherNormal;
layout(binding = 6) uniform sampler2D uOtherFlux;
layout(binding = 7) uniform sampler2D uOtherDirect;

uniform int uSize;
uniform float uSign;
uniform int uMode;  // bit 0 indirect, bit 1 direct
uniform int uSkipIdentical;
uniform int uLightType;
uniform vec3 uLightPosition;
uniform vec3 uLightDirection;
uniform vec3 uGridOrigin;
uniform float uCellSize;
uniform int uResolution;

out ivec3 vCell;  // x < 0: nothing to inject
out vec4 vShR;
out vec4 vShG;
out vec4 vShB;

bool same(sampler2D a, sampler2D b, ivec2 t) { return all(equal(texelFetch(a, t, 0), texelFetch(b, t, 0))); }

void main() {
  vCell = ivec3(-1);
  vShR = vShG = vShB = vec4(0.0);
  gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
  ivec2 t = ivec2(gl_VertexID % uSize, gl_VertexID / uSize);
  vec4 p = texelFetch(uPosition, t, 0);
  if (p.w < 0.5) return;
  if (uSkipIdentical != 0 && same(uPosition, uOtherPosition, t) && same(uNormal, uOtherNormal, t) &&
      same(uFlux, uOtherFlux, t) && same(uDirect, uOtherDirect, t))
    return;
  float half_ = 0.5 * uCellSize;
  vec3 at, dir, flux;
  if (gl_InstanceID == 0) {
    if ((uMode & 1) == 0) return;
    dir = texelFetch(uNormal, t, 0).xyz;
    flux = texelFetch(uFlux, t, 0).rgb;
    at = p.xyz + dir * half_;
  } else {
    if ((uMode & 2) == 0) return;
    vec3 l = uLightType == 2 ? uLightDirection : p.xyz - uLightPosition;
    float len = length(l);
    if (len <= 0.0) return;
    dir = l / len;
    flux = texelFetch(uDirect, t, 0).rgb * kLpvDirectLobeScale;
    at = p.xyz - dir * half_;
  }
  vec3 c = floor((at - uGridOrigin) / uCellSize);
  if (any(lessThan(c, vec3(0.0))) || any(greaterThanEqual(c, vec3(float(uResolution))))) return;
  vCell = ivec3(c);
  vec4 lobe = lpvCosineLobe(dir) * (uSign / LPV_PI);
  vShR = flux.r * lobe;
  vShG = flux.g * lobe;
  vShB = flux.b * lobe;
}
