#version 450 core
// Imperfect volumes, each gathered voxel's rays marched once (iv.h marchSurfaces): per needed voxel and ray
// direction, the first voxel with real points within range and the first with virtual points up to it and
// within range (-1: none), kept for the passes that read the same rays — the ambient the objects hide, the
// gathers of both scene versions and every bounce (iv_march.glsl ivRayHits) — instead of each marching them
// again: the march is the same in all of them.
#include "lighting/techniques/imperfect_volumes/iv.glsl"

layout(local_size_x = 32) in;

layout(std430, binding = 14) readonly buffer Occupancy { uint occupancy[]; };  // iv.glsl IV_REAL ...
layout(std430, binding = 3) readonly buffer Needed { uint needed[]; };
layout(std430, binding = 4) readonly buffer Directions { vec4 directions[]; };
layout(std430, binding = 1) writeonly buffer Hits { ivec2 hits[]; };  // [slot * uRays + ray]: (real, object)

uniform int uNeededCount;
uniform int uRays;
uniform float uRange;
#include "lighting/techniques/imperfect_volumes/iv_ray.glsl"

void main() {
  int slot = int(gl_GlobalInvocationID.x);
  if (slot >= uNeededCount) return;
  vec3 o = ivCentre(ivCoords(int(needed[slot])));
  for (int j = 0; j < uRays; ++j) hits[slot * uRays + j] = ivHitsWithinRange(o, directions[j].xyz);
}
