#version 450 core
// Imperfect volumes, voxelisation (iv.h voxelise): per voxel, the points that fall in it (sorted on the CPU)
// are lit by the scene's lights with the shadow maps of both scene versions (rho: the objects cast shadows,
// mu: they are not there) and by the ambient (unoccluded: a surface's own occlusion of the sky is left out),
// and their mean reflected radiance, normal sum and albedo are written; a virtual point's radiance from the
// lights alone also goes to exitantVirtual (what the objects send real surfaces in the rho gather), and what
// the voxel holds to its occupancy word.
#define SH_BANDS 1
#include "lighting/techniques/imperfect_volumes/iv.glsl"

layout(local_size_x = 64) in;

#include "lighting/direct_light.glsl"

struct IvPoint {
  vec4 position;  // w = 1 on a virtual object
  vec4 normal;
  vec4 albedo;
};
layout(std430, binding = 0) readonly buffer Points { IvPoint points[]; };
layout(std430, binding = 1) readonly buffer Offsets { uint offsets[]; };  // voxel v's points: [offsets[v], offsets[v + 1])
layout(std430, binding = 2) writeonly buffer Voxels { IvVoxel voxels[]; };
// Per voxel what it holds, as the marches read it (iv.glsl IV_REAL, IV_VIRTUAL, IV_ANY): four bytes a voxel
// instead of the record's 128, so a ray's steps stay in cache.
layout(std430, binding = 14) writeonly buffer Occupancy { uint occupancy[]; };

uniform int uVoxelCount;
uniform vec3 uAmbient;
uniform vec3 uAmbientSh[9];

void main() {
  int v = int(gl_GlobalInvocationID.x);
  if (v >= uVoxelCount) return;
  IvVoxel r;
  r.exitantRho = r.exitantMu = r.normalRho = r.normalMu = r.albedoRho = r.albedoMu = r.exitantMuLit = vec4(0.0);
  r.exitantVirtual = vec4(0.0);
  for (uint k = offsets[v]; k < offsets[v + 1]; ++k) {
    IvPoint p = points[k];
    vec3 x = p.position.xyz, n = p.normal.xyz;
    vec3 eAmbient = ivUnoccludedAmbient(uAmbient, uAmbientSh, n);
    vec3 eLights = directIrradiance(true, x, n), eRho = eLights + eAmbient;
    r.exitantRho += vec4(p.albedo.rgb / SH_PI * eRho, 1.0);
    if (p.position.w >= 0.5) r.exitantVirtual += vec4(p.albedo.rgb / SH_PI * eLights, 1.0);
    r.normalRho.xyz += n;
    r.albedoRho.rgb += p.albedo.rgb;
    if (p.position.w < 0.5) {
      vec3 eMu = directIrradiance(false, x, n) + eAmbient;
      r.exitantMu += vec4(p.albedo.rgb / SH_PI * eMu, 1.0);
      r.exitantMuLit += vec4(p.albedo.rgb / SH_PI * eRho, 1.0);
      r.normalMu.xyz += n;
      r.albedoMu.rgb += p.albedo.rgb;
    }
  }
  if (r.exitantRho.w > 0.0) {
    r.exitantRho.rgb /= r.exitantRho.w;
    r.albedoRho.rgb /= r.exitantRho.w;
  }
  if (r.exitantMu.w > 0.0) {
    r.exitantMu.rgb /= r.exitantMu.w;
    r.albedoMu.rgb /= r.exitantMu.w;
    r.exitantMuLit.rgb /= r.exitantMu.w;
  }
  if (r.exitantVirtual.w > 0.0) r.exitantVirtual.rgb /= r.exitantVirtual.w;
  voxels[v] = r;
  occupancy[v] = (r.exitantMu.w > 0.0 ? IV_REAL : 0u) | (r.exitantVirtual.w > 0.0 ? IV_VIRTUAL : 0u) |
                 (r.exitantRho.w > 0.0 ? IV_ANY : 0u);
}
