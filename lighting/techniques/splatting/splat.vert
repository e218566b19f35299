#version 450 core
// Splatting: one instance per pixel light, a screen rectangle around its splat box (the 8 corners projected;
// the whole screen when the box reaches behind the camera's near plane; nothing for a light without flux).
// At far level k the box is that of I_low / 16^k, uILowScale already divided (splat.h splatFar).
#include "lighting/techniques/splatting/splat.glsl"
layout(std430, binding = 2) readonly buffer Lights { PixelLight lights[]; };

uniform int uFirstRecord;
uniform mat4 uViewProj;  // the camera's clip <- world
uniform float uILowScale;  // I_low of a light = uILowScale x lum(|Phi|) (at far level k: the knob's / 16^k)
uniform int uLevel;
uniform int uFarLevels;

flat out int vLight;

void main() {
  vLight = uFirstRecord + gl_InstanceID;
  PixelLight l = lights[vLight];
  vec2 corner = vec2(gl_VertexID & 1, gl_VertexID >> 1);  // triangle strip 0..3
  float iLow = splatScaledILow(l, uILowScale);
  if (!(iLow > 0.0)) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // outside the clip volume: no fragment
    return;
  }
  SplatBox b = splatBox(l, iLow);
  vec2 lo = vec2(1e30), hi = vec2(-1e30);
  bool behind = false;
  for (int k = 0; k < 8; ++k) {
    vec3 s = vec3((k & 1) != 0 ? 1.0 : -1.0, (k & 2) != 0 ? 1.0 : -1.0, (k & 4) != 0 ? 1.0 : -1.0);
    // Below the outermost level the box with its fade band (splat.frag, splatBoxCoverage).
    vec3 h = (uLevel < uFarLevels ? 1.0 + SPLAT_BOX_FADE : 1.0) * b.halfExtent;
    vec3 p = b.centre + s.x * h.x * b.a0 + s.y * h.y * b.a1 + s.z * h.z * b.a2;
    vec4 c = uViewProj * vec4(p, 1.0);
    if (c.w <= 1e-6) {
      behind = true;
      break;
    }
    lo = min(lo, c.xy / c.w);
    hi = max(hi, c.xy / c.w);
  }
  if (behind) lo = vec2(-1.0), hi = vec2(1.0);
  lo = clamp(lo, vec2(-1.0), vec2(1.0));
  hi = clamp(hi, vec2(-1.0), vec2(1.0));
  gl_Position = vec4(mix(lo, hi, corner), 0.0, 1.0);
}
