#version 450 core
// The real VALs the virtual object now shadows, dimmed: the camera saw them lit without the object, so each
// reflects exitance x E_with / E_without (per channel, clamped to [0, 1]; the ambient's irradiance in both;
// direct light through the frame's shadow maps). The GLSL twin of lighting::dimShadowedVals; counts[3] counts
// the VALs it changed.
#include "lighting/direct_light.glsl"
#include "lighting/techniques/kinect_val/val.glsl"
layout(local_size_x = 64) in;

layout(std430, binding = 0) buffer Vals { Val vals[]; };
layout(std430, binding = 1) buffer Counts { uint counts[]; };  // [0] all, [1] real, [2] virtual, [3] dimmed
uniform int uRealCount;          // the real VALs lead the buffer
uniform vec3 uAmbientIrradiance;  // pi x the ambient radiance, W/m^2

void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= uRealCount) return;
  vec3 x = vals[i].posArea.xyz, n = vals[i].normalWeight.xyz;
  vec3 eWith = uAmbientIrradiance + directIrradiance(true, x, n);
  vec3 eWithout = uAmbientIrradiance + directIrradiance(false, x, n);
  if (eWith == eWithout) return;
  vec3 f = vals[i].flux.rgb;
  for (int c = 0; c < 3; ++c)
    if (eWithout[c] > 0.0) f[c] *= clamp(eWith[c] / eWithout[c], 0.0, 1.0);
  vals[i].flux.rgb = f;
  atomicAdd(counts[3], 1u);
}
