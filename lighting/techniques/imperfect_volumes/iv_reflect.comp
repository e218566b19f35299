#version 450 core
// Imperfect volumes, a further bounce (iv.h gather, bounces > 1): each voxel with real points reflects the light its
// surfaces received in the previous bounce, albedo / pi times the irradiance of that bounce's SH about the
// voxel's mean normal (never negative).
#include "lighting/techniques/imperfect_volumes/iv.glsl"

layout(local_size_x = 64) in;

layout(std430, binding = 2) readonly buffer Voxels { IvVoxel voxels[]; };
layout(std430, binding = 3) readonly buffer Needed { uint needed[]; };
layout(std430, binding = 7) writeonly buffer Reflected { vec4 reflected[]; };
layout(std430, binding = 8) readonly buffer Bounce { float bounce[]; };
// The mu pass adds each bounce's reflected light here (uAccumulate): the voxels' outgoing radiance over all
// bounces, which the object's own rays read (iv.h Incident::outgoing).
layout(std430, binding = 11) buffer ReflectedSum { vec4 reflectedSum[]; };

uniform int uNeededCount;
uniform int uAccumulate;

void main() {
  int slot = int(gl_GlobalInvocationID.x);
  if (slot >= uNeededCount) return;
  int v = int(needed[slot]);
  IvVoxel r = voxels[v];
  // The real surfaces only, in rho too: the objects' own further bounces are the shading pass's reflection
  // of the light they hide.
  float count = r.exitantMu.w;
  vec3 nSum = r.normalMu.xyz;
  vec3 albedo = r.albedoMu.rgb;
  reflected[v] = vec4(0.0);
  if (count <= 0.0 || dot(nSum, nSum) <= 0.0) return;
  vec3 n = normalize(nSum);
  vec3 e;
  for (int ch = 0; ch < 3; ++ch) {
    float c[SH_COEFFS];
    for (int q = 0; q < SH_COEFFS; ++q) c[q] = bounce[(v * 3 + ch) * SH_COEFFS + q];
    e[ch] = ivShIrradiance(c, n);
  }
  vec3 out_ = max(albedo / SH_PI * e, vec3(0.0));
  reflected[v] = vec4(out_, 1.0);
  if (uAccumulate == 1) reflectedSum[v].rgb += out_;
}
