// The objects' shadow of the ambient on real surfaces (lighting/object_shadow.h is the C++ twin): each
// object a sphere, its view factor from the surface element times the ambient's radiance towards its centre
// less what the sphere reflects of the ambient back along it, the total within +- the ambient's irradiance.
// Needs lighting/ambient_sh.glsl.
#define MAX_OCCLUDERS 16

uniform int uOccluderCount;
uniform vec4 uOccluders[MAX_OCCLUDERS];  // xyz centre (lighting world), w radius; object_shadow.h occluderSphere
uniform vec3 uOccluderAlbedo[MAX_OCCLUDERS];  // diffuse albedo of what each reflects of the ambient

#include "lighting/view_factor.glsl"

float sphereViewFactor(vec3 x, vec3 n, vec4 s) {
  vec3 d = s.xyz - x;
  float dist = length(d), r = s.w;
  if (!(r > 0.0)) return 0.0;
  if (dist <= r) return 1.0;
  return sphereViewFactorH(dist / r, dot(n, d) / dist);
}

// The irradiance the objects take from (x, n) under the ambient, net of what they reflect of it (> 0: subtract it).
vec3 ambientShadow(vec3 uniformPart, vec3 sh[9], vec3 x, vec3 n) {
  const float pi = 3.14159265358979;
  vec3 e = vec3(0.0);
  for (int i = 0; i < uOccluderCount && i < MAX_OCCLUDERS; ++i) {
    float f = sphereViewFactor(x, n, uOccluders[i]);
    if (f <= 0.0) continue;
    vec3 d = uOccluders[i].xyz - x;
    float len = length(d);
    vec3 w = len > 0.0 ? d / len : n;
    vec3 reflected = uOccluderAlbedo[i] * max(pi * uniformPart + ambientShIrradiance(sh, -w), vec3(0.0)) / pi;
    e += pi * f * (ambientRadiance(uniformPart, sh, w) - reflected);
  }
  vec3 full = max(pi * uniformPart + ambientShIrradiance(sh, n), vec3(0.0));
  e = clamp(e, -full, full);
  return (any(isnan(e)) || any(isinf(e))) ? vec3(0.0) : e;
}
