// The objects' terms of the shading pass beyond their direct shadow (lighting/object_shadow.h is the C++
// twin): what they hide of the light around a real point net of what they reflect of it, lit as the point's
// surroundings and the ground under the faces they turn to it, and (uAddReflectedLight) the lights they
// reflect. Shared by the shading pass (lighting/shade.frag) and its reduced-resolution variant
// (lighting/object_terms.frag). Needs lighting/direct_light.glsl and lighting/ambient_sh.glsl.
uniform vec3 uHiddenUniform;     // what the objects hide: radiance, uniform part (the ambient unless a room's surfaces)
uniform vec3 uHiddenSh[9];       // ... and its SH bands 1-2
uniform int uHiddenMapOn;        // 1: uHiddenMap holds the hidden light sharper than its SH (a room's surfaces)
layout(binding = 11) uniform sampler2D uHiddenMap;  // lat-long radiance with its levels (lighting/radiance_map.h)
uniform int uAddReflectedLight;  // 1: the real-role technique leaves the lights the objects reflect onto real surfaces to this pass
#include "lighting/radiance_map.glsl"
#include "lighting/object_shadow.glsl"

// At a real point x with normal n where a sphere is seen (objectsSeen), the direct light there without and
// with the objects given.
vec3 objectTerms(vec3 x, vec3 n, vec3 directMu, vec3 directRho) {
  vec3 full = ambientIrradiance(uHiddenUniform, uHiddenSh, n), hides, mapped, reflects;
  ambientShadowParts(uHiddenUniform, uHiddenSh, x, n, uHiddenMapOn == 1, uHiddenMap, hides, mapped, reflects);
  // The objects' faces turned towards this point see its surroundings and the ground under them, both
  // darkened by their shadows (lighting::facedGround, blendLit).
  vec3 lit = litFraction(full, hides, directMu, directRho);
  float groundWeight;
  vec3 ground = facedGround(x, n, groundWeight);
  if (groundWeight > 0.0) {
    vec3 hidesGround, mappedGround, reflectsGround;
    ambientShadowParts(uHiddenUniform, uHiddenSh, ground, n, false, uHiddenMap, hidesGround, mappedGround, reflectsGround);
    vec3 litGround = litFraction(full, hidesGround, directIrradiance(false, ground, n), directIrradiance(true, ground, n));
    lit += groundWeight * (litGround - lit);
  }
  // The hidden light holds the near real surfaces' bounce too; a technique whose own delta blocks some of
  // it (DLPV's volume blocks the bounce it injected) has that part taken twice (docs/bench-resolution.md).
  // What they hide through the map where there is one: the lit fractions above are ratios, smooth enough for
  // the SH bands; the shadow itself follows the room's bright and dark surfaces across each cap.
  if (uHiddenMapOn == 1) hides = mapped;
  vec3 terms = -ambientShadow(full, hides, reflects, lit);
  if (uAddReflectedLight == 1) terms += reflectedLight(x, n);
  return terms;
}
