#version 450 core
// Imperfect volumes (iv.h ambientHiddenByObjects): per voxel with real points, the ambient irradiance the
// virtual objects hide from its surface: rays in front of its mean real normal, marched through the rho
// occupancy from past the voxel's bounding sphere (iv_ray.glsl; their hits from iv_hits.comp), whose first
// hit within range holds a virtual point.
#define SH_BANDS 1
#include "lighting/techniques/imperfect_volumes/iv.glsl"

layout(local_size_x = 32) in;

layout(std430, binding = 2) readonly buffer Voxels { IvVoxel voxels[]; };
layout(std430, binding = 14) readonly buffer Occupancy { uint occupancy[]; };  // iv.glsl IV_REAL ...
layout(std430, binding = 3) readonly buffer Needed { uint needed[]; };
layout(std430, binding = 4) readonly buffer Directions { vec4 directions[]; };
layout(std430, binding = 1) readonly buffer Hits { ivec2 hits[]; };  // iv_hits.comp (uCachedHits)
uniform int uCachedHits;  // 1: the rays' hits from iv_hits.comp, 0: marched here
layout(std430, binding = 12) writeonly buffer Hidden { vec4 hidden[]; };

uniform int uNeededCount;
uniform int uRays;
uniform float uRange;
uniform vec3 uAmbient;
uniform vec3 uAmbientSh[9];
#include "lighting/techniques/imperfect_volumes/iv_ray.glsl"

void main() {
  int slot = int(gl_GlobalInvocationID.x);
  if (slot >= uNeededCount) return;
  int v = int(needed[slot]);
  hidden[v] = vec4(0.0);
  IvVoxel r = voxels[v];
  if (!(r.exitantMu.w > 0.0) || !(dot(r.normalMu.xyz, r.normalMu.xyz) > 0.0)) return;
  vec3 n = normalize(r.normalMu.xyz);
  vec3 o = ivCentre(ivCoords(v));
  vec3 e = vec3(0.0);
  for (int j = 0; j < uRays; ++j) {
    vec3 d = directions[j].xyz;
    float c = dot(n, d);
    if (!(c > 0.0)) continue;
    // The first voxel with points holds virtual ones: an object voxel within range (the march keeps one only
    // up to the first real voxel).
    ivec2 h = uCachedHits == 1 ? hits[slot * uRays + j] : ivHitsWithinRange(o, d);
    if (h.y >= 0)
      e += ambientRadiance(uAmbient, uAmbientSh, d) * c;
  }
  hidden[v] = vec4(e * (4.0 * SH_PI / float(uRays)), 0.0);
}
