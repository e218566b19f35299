#version 450 core
// The shared shading pass (algorithms.md §3, Algorithm 1), linear light. It knows nothing of techniques:
// it does the direct light, the shadows and the ambient, then adds what the techniques handed out.
//   real pixel:    rgb = E_delta * albedo / pi, a = 0   (the compositor adds it to the background)
//                  E_delta = the real-role technique's delta, plus (when that technique does not already
//                  account for it) the direct light the object blocks, sum_i E_i (vis_i(rho) - vis_i(mu)) (lighting/direct_light.glsl),
//                  and, for every technique, what the objects hide of the light around them net of what they reflect of it,
//                  -integral_objects (L_hidden - L_object) cos (lighting/object_shadow.glsl); L_hidden is the ambient,
//                  or the room's surfaces seen from the objects when lights are listed beside a room (uHidden*);
//                  and (likewise) the lights the objects reflect onto real surfaces (lighting/object_shadow.glsl);
//                  where a camera channel of the pixel is clipped (the G-buffer albedo's a < 0), a delta that darkens
//                  it is taken from the radiance the lights predict there, albedo E / pi, when that is above the
//                  camera's white (lighting/clipped_real.glsl)
//   virtual pixel: rgb = (sum_i E_i * visibility_i + pi * ambient + E_sh(n) + E_indirect) * albedo / pi + L_indirect, a = 1
//                  E_sh: the ambient's directional part, SH bands 0-2 convolved with the clamped cosine
//                  E_indirect, L_indirect from the virtual-role technique; none when the ambient is an
//                  environment seen at the object (uEnvironmentHoldsBounce: it holds the real surfaces' bounce)
//   no surface:    rgb = 0, a = 0
// Output 1 (debug): rgb = E_delta (real) or E_indirect (virtual) in W/m^2, a = 1 where a surface was seen.
// SHARED_UPSAMPLE (with REDUCED_OBJECT_TERMS): the real-role delta is at the object terms' reduced view (the same
// factor and size): the two are upsampled with one set of weights, the values each alone would have.
// SHADE_UNLIT (a program variant): no virtual object in the scene: everything zero, a = 1 on output 1 where a surface
// was seen; the pass draws it alone (llvmpipe would run the whole program's every branch for the same zeros).
// SHADE_REAL_ONLY (a program variant): the real pixels without the objects' direct shadow, for the pixels
// outside lighting::objectsFootprint (no object there, no direct shadow of theirs: the same values there as
// the whole program's), which the whole program then draws alone. llvmpipe runs every branch of a fragment
// program under masks: the variant's pixels cost what it holds, not what they take of the whole program.
#define MAX_LIGHTS 16
#define SHADE_PI 3.14159265358979

layout(binding = 0) uniform sampler2D uGPosition;
layout(binding = 1) uniform sampler2D uGNormal;
layout(binding = 2) uniform sampler2D uGAlbedo;
layout(binding = 3) uniform sampler2D uRealDelta;         // rgb: E_delta of the real-role technique (W/m^2)
layout(binding = 4) uniform sampler2D uVirtualIrradiance; // rgb: indirect irradiance on the object (W/m^2)
layout(binding = 5) uniform sampler2D uVirtualRadiance;   // rgb: indirect radiance of the object (W/m^2/sr)
// UPSAMPLE_OUTPUTS: the three above may be at 1/factor of the frame's resolution (frame knob render_scale),
// upsampled here joint-bilaterally with the reduced G-buffer's positions and normals (lighting/upsample.glsl).
#ifdef UPSAMPLE_OUTPUTS
layout(binding = 6) uniform sampler2D uLowPosition;
layout(binding = 7) uniform sampler2D uLowNormal;
uniform int uRealDeltaFactor, uVirtualIrradianceFactor, uVirtualRadianceFactor;  // 1: the frame's resolution
#include "lighting/upsample.glsl"
#else
#define uRealDeltaFactor 1
#define uVirtualIrradianceFactor 1
#define uVirtualRadianceFactor 1
#endif
// With SOFT_OBJECT_SHADOWS defined (a program variant): the objects' soft shadows of lights with extent.
#include "lighting/direct_light.glsl"

uniform int uRealDeltaOn;       // 0: the real-role technique hands out no real-pixel delta (uRealDelta unread)
uniform int uPassShadows;       // bit i: the real-role technique leaves the objects' direct shadow of light i here
uniform int uAllLights;         // bit i for every light i
uniform vec3 uAmbient;          // radiance, W/m^2/sr
uniform int uEnvironmentHoldsBounce;  // 1: the ambient is an environment seen at the object (real bounce included)
uniform float uCameraWhite;     // the camera's white in scene radiance (1 / exposure); 0: clipped pixels not corrected
#include "lighting/clipped_real.glsl"
uniform vec3 uAmbientSh[9];     // radiance as SH bands 0-2, lighting world (reconstruction::shBasis2's basis); 0 = none
#include "lighting/ambient_sh.glsl"
#include "lighting/object_terms.glsl"
// REDUCED_OBJECT_TERMS (with UPSAMPLE_OUTPUTS): the object terms come from lighting/object_terms.frag at the
// reduced view's resolution, upsampled here; the objects' direct shadow stays at the frame's.
#ifdef REDUCED_OBJECT_TERMS
layout(binding = 8) uniform sampler2D uObjectTerms;
uniform int uObjectTermsFactor;
#endif

layout(location = 0) out vec4 outShade;
layout(location = 1) out vec4 outIrradiance;

vec3 techniqueOutput(sampler2D t, int factor, ivec2 p, vec4 position, vec4 normal) {
#ifdef UPSAMPLE_OUTPUTS
  if (factor > 1) return upsampled(t, uLowPosition, uLowNormal, factor, p, position, normal);
#endif
  return texelFetch(t, p, 0).rgb;
}

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 pos = texelFetch(uGPosition, p, 0);
  outShade = vec4(0.0);
  outIrradiance = vec4(0.0);
  if (pos.w < 0.5) return;
#ifdef SHADE_UNLIT
  outIrradiance = vec4(0.0, 0.0, 0.0, 1.0);
  return;
#else
  vec4 normal = texelFetch(uGNormal, p, 0);
  vec3 n = normal.xyz;
  vec4 albedo = texelFetch(uGAlbedo, p, 0);
  bool isVirtual = albedo.a > 0.5;
#ifdef SHADE_REAL_ONLY
  if (isVirtual) return;  // drawn by the whole program: the objects lie in the footprint
#else
  if (isVirtual) {
    vec3 e = virtualDirectIrradiance(pos.xyz, n) + SHADE_PI * uAmbient + ambientShIrradiance(uAmbientSh, n);
    vec3 indirect = uEnvironmentHoldsBounce == 1 ? vec3(0.0)
                                                 : techniqueOutput(uVirtualIrradiance, uVirtualIrradianceFactor, p, pos, normal);
    vec3 radiance = uEnvironmentHoldsBounce == 1 ? vec3(0.0)
                                                 : techniqueOutput(uVirtualRadiance, uVirtualRadianceFactor, p, pos, normal);
    outShade = vec4((e + indirect) * albedo.rgb / SHADE_PI + radiance, 1.0);
    outIrradiance = vec4(indirect, 1.0);
    return;
  }
#endif
  {
#ifdef SHARED_UPSAMPLE
    // The real-role delta and the objects' terms at one reduced view: upsampled with weights computed once.
    vec3 delta, terms;
    upsampledPair(uRealDelta, uObjectTerms, uLowPosition, uLowNormal, uObjectTermsFactor, p, pos, normal, delta, terms);
#else
    // A real-role technique without a real-pixel output of its own (Kinect-VAL) hands out none: nothing read.
    vec3 delta = uRealDeltaOn == 1 ? techniqueOutput(uRealDelta, uRealDeltaFactor, p, pos, normal) : vec3(0.0);
#endif
    // Only where the objects reach: a sphere seen at a view factor of at least lighting::kObjectsMinViewFactor, or
    // a light the objects' map may shadow here. Elsewhere every object term below is exactly zero and skipped.
    bool seen = objectsSeen(pos.xyz, n);
#ifdef REDUCED_OBJECT_TERMS
#ifdef SHARED_UPSAMPLE
    if (seen) delta += terms;
#else
    if (seen) delta += upsampled(uObjectTerms, uLowPosition, uLowNormal, uObjectTermsFactor, p, pos, normal);
#endif
#ifndef SHADE_REAL_ONLY
    if (uPassShadows != 0) delta += objectsDirectShadow(uPassShadows, pos.xyz, n);
#endif
#else
    if (seen) {
      // The object terms need the direct light with and without the objects: the direct shadow is their difference.
      vec3 directMu = directIrradiance(false, pos.xyz, n), directRho = directIrradiance(true, pos.xyz, n);
      if (uPassShadows == uAllLights) delta += directRho - directMu;
      else if (uPassShadows != 0) delta += objectsDirectShadow(uPassShadows, pos.xyz, n);
      delta += objectTerms(pos.xyz, n, directMu, directRho);
    }
#ifndef SHADE_REAL_ONLY
    else if (uPassShadows != 0) {
      delta += objectsDirectShadow(uPassShadows, pos.xyz, n);
    }
#endif
#endif
    vec3 shaded = delta * albedo.rgb / SHADE_PI;
    if (albedo.a < -0.5 && uCameraWhite > 0.0 && any(lessThan(shaded, vec3(0.0)))) {
      // A clipped channel the objects darken: from the radiance the lights predict there, without the objects.
      vec3 e = directIrradiance(false, pos.xyz, n) + ambientIrradiance(uAmbient, uAmbientSh, n);
      shaded = clippedRealShade(shaded, e * albedo.rgb / SHADE_PI, uCameraWhite, albedo.a);
    }
    outShade = vec4(shaded, 0.0);
    outIrradiance = vec4(delta, 1.0);
  }
#endif
}
