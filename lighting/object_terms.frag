#version 450 core
// The shading pass's object terms (lighting/object_terms.glsl) on the reduced G-buffer (frame knobs
// render_scale < 1 or object_terms_scale): they vary smoothly over a surface, and the shading pass upsamples
// them joint-bilaterally as it does the techniques' reduced outputs (lighting/upsample.glsl), keeping the
// objects' direct shadow at the frame's resolution. rgb = the terms (W/m^2) on real pixels where a sphere is
// seen, else 0.
// TERMS_HISTORY (frame knob object_terms_history > 0): blended with the previous frame's terms where its
// surface is this texel's (lighting/terms_history.glsl), and this frame's points and normals written beside
// them for the next frame.
#define SHADE_PI 3.14159265358979
layout(binding = 0) uniform sampler2D uGPosition;
layout(binding = 1) uniform sampler2D uGNormal;
layout(binding = 2) uniform sampler2D uGAlbedo;
#include "lighting/direct_light.glsl"
#include "lighting/ambient_sh.glsl"
#include "lighting/object_terms.glsl"

layout(location = 0) out vec4 outTerms;

#ifdef TERMS_HISTORY
#include "lighting/terms_history.glsl"
layout(binding = 3) uniform sampler2D uPreviousTerms;
layout(binding = 4) uniform sampler2D uPreviousPosition;
layout(binding = 5) uniform sampler2D uPreviousNormal;
uniform int uHistory;  // 0: no history (the first frame, or the objects, lights or ambient changed)
uniform float uHistoryWeight;
uniform mat4 uPreviousCameraFromWorld;
uniform vec4 uPreviousIntrinsics;  // fx, fy, cx, cy
uniform int uPreviousFactor;
uniform vec3 uEye;
layout(location = 1) out vec4 outPosition;
layout(location = 2) out vec4 outNormal;
#endif

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 pos = texelFetch(uGPosition, p, 0);
  vec3 n = texelFetch(uGNormal, p, 0).xyz;
  outTerms = vec4(0.0);
#ifdef TERMS_HISTORY
  outPosition = vec4(0.0);
  outNormal = vec4(0.0);
#endif
  if (pos.w < 0.5 || texelFetch(uGAlbedo, p, 0).a > 0.5 || !objectsSeen(pos.xyz, n)) return;
  outTerms = vec4(objectTerms(pos.xyz, n, directIrradiance(false, pos.xyz, n), directIrradiance(true, pos.xyz, n)), 1.0);
#ifdef TERMS_HISTORY
  outPosition = vec4(pos.xyz, 1.0);
  outNormal = vec4(n, 0.0);
  if (uHistory == 1) {
    ivec2 q = historyTexel(uPreviousCameraFromWorld, uPreviousIntrinsics, uPreviousFactor,
                           textureSize(uPreviousTerms, 0), pos.xyz);
    if (q.x >= 0) {
      bool agrees = historyAgrees(pos.xyz, n, uEye, texelFetch(uPreviousPosition, q, 0),
                                  texelFetch(uPreviousNormal, q, 0));
      outTerms = blendHistory(outTerms, texelFetch(uPreviousTerms, q, 0), uHistoryWeight, agrees);
    }
  }
#endif
}
