#version 450 core
// Imperfect volumes, gather (iv.h gather): per voxel near a surface, N rays (the same directions for every
// voxel) march one voxel per step from past the voxel's bounding sphere to the first occupied voxel or the
// border. A hit within range returns the hit voxel's exitant radiance towards the origin (when it faces it);
// otherwise the ambient of the ray's direction (uAmbientOn). In rho the objects hide nothing: the ray goes on
// to the first voxel with real points, lit as the objects leave it, and the first object voxel on its way adds
// the lights' light it reflects (iv_march.glsl). The incident radiance is projected to SH and
// added into the output (3 x SH_COEFFS floats per voxel, channel-major), with the fraction of rays that hit
// within range (ambient occlusion) when uOcclusionOn.
#include "lighting/techniques/imperfect_volumes/iv.glsl"

layout(local_size_x = 32) in;

layout(std430, binding = 2) readonly buffer Voxels { IvVoxel voxels[]; };
layout(std430, binding = 14) readonly buffer Occupancy { uint occupancy[]; };  // iv.glsl IV_REAL ...
layout(std430, binding = 3) readonly buffer Needed { uint needed[]; };
layout(std430, binding = 4) readonly buffer Directions { vec4 directions[]; };
layout(std430, binding = 1) readonly buffer Hits { ivec2 hits[]; };  // iv_hits.comp (uCachedHits)
uniform int uCachedHits;  // 1: the rays' hits from iv_hits.comp, 0: marched here
layout(std430, binding = 5) buffer Incident { float incident[]; };
layout(std430, binding = 6) buffer Occlusion { float occlusion[]; };
// Exitant radiance per voxel of a later bounce (rgb; uExitantFromBuffer): what the voxel reflects.
layout(std430, binding = 7) readonly buffer Reflected { vec4 reflected[]; };
// The light of surfaces alone (no ambient), written when uWriteBounce: what the next bounce reflects.
layout(std430, binding = 8) writeonly buffer Bounce { float bounce[]; };

uniform int uNeededCount;
uniform int uRays;
uniform float uRange;
uniform int uRho;                // 1: rho (every occupied voxel), 0: mu (real ones)
uniform int uAmbientOn;
uniform int uOcclusionOn;
uniform int uExitantFromBuffer;  // 1: exitant radiance from Reflected, 0: the voxels' direct light
uniform int uBounceLight;        // 0: surfaces send nothing (ambient occlusion only)
uniform int uWriteBounce;
uniform vec3 uAmbient;           // uniform radiance
uniform vec3 uAmbientSh[9];      // SH bands 0-2 of the ambient radiance

vec3 ivReflectedAt(int v) { return reflected[v].rgb; }
#include "lighting/techniques/imperfect_volumes/iv_march.glsl"


void main() {
  int slot = int(gl_GlobalInvocationID.x);
  if (slot >= uNeededCount) return;
  int v = int(needed[slot]);
  ivec3 from = ivCoords(v);
  vec3 o = ivCentre(from);
  float acc[3 * SH_COEFFS], accBounce[3 * SH_COEFFS];
  for (int q = 0; q < 3 * SH_COEFFS; ++q) acc[q] = accBounce[q] = 0.0;
  int hits = 0;
  for (int j = 0; j < uRays; ++j) {
    vec3 d = directions[j].xyz;
    bool hit, open;
    // In rho the objects hide nothing: the ray goes on to the first real surface (iv.h marchSurfaces).
    vec3 surfaces = ivSurfaces(ivRayHits(slot, j, o, d), d, uRho == 1, uExitantFromBuffer == 1, hit, open);
    if (hit) ++hits;
    vec3 L = surfaces;
    if (open && uAmbientOn == 1) L += ambientRadiance(uAmbient, uAmbientSh, d);
    bool fromSurface = surfaces != vec3(0.0);
    if (L == vec3(0.0)) continue;
    float y[SH_COEFFS];
    shEvaluate(d, y);
    for (int q = 0; q < SH_COEFFS; ++q) {
      acc[q] += L.r * y[q];
      acc[SH_COEFFS + q] += L.g * y[q];
      acc[2 * SH_COEFFS + q] += L.b * y[q];
    }
    if (fromSurface)
      for (int q = 0; q < SH_COEFFS; ++q) {
        accBounce[q] += surfaces.r * y[q];
        accBounce[SH_COEFFS + q] += surfaces.g * y[q];
        accBounce[2 * SH_COEFFS + q] += surfaces.b * y[q];
      }
  }
  float w = 4.0 * SH_PI / float(uRays);
  int base = v * 3 * SH_COEFFS;
  for (int q = 0; q < 3 * SH_COEFFS; ++q) incident[base + q] += w * acc[q];
  if (uWriteBounce == 1)
    for (int q = 0; q < 3 * SH_COEFFS; ++q) bounce[base + q] = w * accBounce[q];
  if (uOcclusionOn == 1) occlusion[v] = float(hits) / float(uRays);
}
