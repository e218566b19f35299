// Splatting: an RSM texel as a pixel light's source (splat.h texelArea, ambientFlux, occluderFlux): its
// footprint on the surface, the ambient its surface reflects and the ambient it blocks. Shared by the
// importance and the sampling passes.
#include "lighting/ambient_sh.glsl"

uniform int uLightType;    // 0 point, 1 spot, 2 directional
uniform vec3 uLightPosition;
uniform vec3 uLightDirection;
uniform vec3 uLightPower;  // intensity (W/sr) or irradiance (W/m^2)
uniform vec3 uAmbient;     // uniform ambient radiance
uniform vec3 uAmbientSh[9];
uniform float uAmbientShare;  // this light's share of the ambient's bounce (1 / the lights sampled)

// splat.h texelArea: across the beam direct / beam (its brightest channel) over <n, l> clamped at 0.1;
// toLight: the unit direction to the light.
float splatTexelArea(vec3 p, vec3 n, vec3 direct, out vec3 toLight) {
  vec3 beam;
  if (uLightType == 2) {
    toLight = -uLightDirection;
    beam = uLightPower;
  } else {
    vec3 d = uLightPosition - p;
    float d2 = max(dot(d, d), 1e-12);
    toLight = d * inversesqrt(d2);
    beam = uLightPower / d2;
  }
  int c = beam.r >= beam.g && beam.r >= beam.b ? 0 : (beam.g >= beam.b ? 1 : 2);
  float across = beam[c] > 0.0 ? direct[c] / beam[c] : 0.0;
  return across / max(dot(n, toLight), 0.1);
}

// splat.h ambientFlux: albedo (flux / direct per channel) x the ambient's irradiance about n x A x share.
vec3 splatAmbientFlux(vec3 flux, vec3 direct, vec3 n, float area) {
  vec3 e = SPLAT_PI * uAmbient + ambientShIrradiance(uAmbientSh, n);
  vec3 albedo = vec3(0.0);
  for (int c = 0; c < 3; ++c) albedo[c] = direct[c] > 0.0 ? clamp(flux[c] / direct[c], 0.0, 1.0) : 0.0;
  vec3 a = albedo * e * (area * uAmbientShare);
  return (any(isnan(a)) || any(isinf(a))) ? vec3(0.0) : max(a, vec3(0.0));
}

// splat.h occluderFlux: the ambient a surface patch blocks, seen from in front of it (the sky behind it
// along -n), as a negative Lambertian light: -pi L_ambient(-n) A x share.
vec3 splatOccluderFlux(vec3 n, float area) {
  vec3 o = -SPLAT_PI * ambientRadiance(uAmbient, uAmbientSh, -n) * (area * uAmbientShare);
  return (any(isnan(o)) || any(isinf(o))) ? vec3(0.0) : o;
}

// A real surface's or an object's diffuse flux, its footprint `area` (splatTexelArea): the light's direct
// bounce (withDirect: not where the objects shadow it), its share of the ambient's bounce and of the ambient
// it blocks (splat.h ambientFlux, occluderFlux).
vec3 splatTexelFlux(vec3 n, vec3 flux, vec3 direct, float area, bool withDirect) {
  return (withDirect ? flux : vec3(0.0)) + splatAmbientFlux(flux, direct, n, area) + splatOccluderFlux(n, area);
}
