#version 450 core
// Splatting: a pixel light's bounded contribution to the G-buffer point under the fragment (splat.h
// splatIrradiance), added by blending: uTarget 0 onto real pixels (the delta's signed lights), 1 onto
// virtual pixels (the object's indirect light). Alpha counts the splats that reached the pixel (overdraw).
// At far level uLevel > 0 only the shell between level uLevel - 1's box and its own, weighted and cross-faded
// (splat.h splatFar: coverage of its box minus that of the level before).
#include "lighting/techniques/splatting/splat.glsl"
layout(std430, binding = 2) readonly buffer Lights { PixelLight lights[]; };
layout(binding = 0) uniform sampler2D uGPosition;
layout(binding = 1) uniform sampler2D uGNormal;
layout(binding = 2) uniform sampler2D uGAlbedo;

uniform int uTarget;
uniform float uILowScale;  // at far level k: the knob's / 16^k
uniform int uLevel;
uniform int uFarLevels;  // the knob far_levels: level uFarLevels is the outermost
uniform float uWeight;  // the far level's weight n / farSamples(n, level)

flat in int vLight;
layout(location = 0) out vec4 outRealDelta;
layout(location = 1) out vec4 outVirtualIrradiance;

void main() {
  outRealDelta = outVirtualIrradiance = vec4(0.0);
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec4 pos = texelFetch(uGPosition, px, 0);
  if (pos.w < 0.5) return;
  bool isVirtual = texelFetch(uGAlbedo, px, 0).a > 0.5;
  if (isVirtual != (uTarget == 1)) return;
  PixelLight l = lights[vLight];
  float iLow = splatScaledILow(l, uILowScale);
  // Below the outermost level the box's coverage, at it the box itself (splat.h splatFar).
  SplatBox b = splatBox(l, iLow);
  float outer = uLevel < uFarLevels ? splatBoxCoverage(b, pos.xyz) : (splatInsideBox(b, pos.xyz) ? 1.0 : 0.0);
  if (!(outer > 0.0)) return;
  float w = outer - (uLevel > 0 ? splatBoxCoverage(splatBox(l, iLow * float(SPLAT_FAR_STRIDE)), pos.xyz) : 0.0);
  if (w == 0.0) return;
  vec3 e = (uWeight * w) * splatIrradiance(l, pos.xyz, texelFetch(uGNormal, px, 0).xyz);
  if (uTarget == 0)
    outRealDelta = vec4(e, 1.0);
  else
    outVirtualIrradiance = vec4(e, 1.0);
}
