#version 450 core
// Imperfect volumes (iv.h ambientHiddenByObjects): per voxel with real points, the ambient irradiance the
// virtual objects hide from its surface: rays in front of its mean real normal, marched through the rho
// occupancy from past the voxel's bounding sphere (iv_ray.glsl), whose first hit within range holds a virtual
// point.
#define SH_BANDS 1
#include "lighting/techniques/imperfect_volumes/iv.glsl"

layout(local_size_x = 32) in;

layout(std430, binding = 2) readonly buffer Voxels { IvVoxel voxels[]; };
#include "lighting/techniques/imperfect_volumes/iv_ray.glsl"
layout(std430, binding = 3) readonly buffer Needed { uint needed[]; };
layout(std430, binding = 4) readonly buffer Directions { vec4 directions[]; };
layout(std430, binding = 12) writeonly buffer Hidden { vec4 hidden[]; };

uniform int uNeededCount;
uniform int uRays;
uniform float uRange;
uniform vec3 uAmbient;
uniform vec3 uAmbientSh[9];

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
    // The first voxel with points holds virtual ones: an object voxel no further than the first real one.
    int real, object;
    float tReal, tObject;
    ivMarch(o, d, real, tReal, object, tObject);
    if (object >= 0 && (real < 0 || tObject <= tReal) && tObject <= uRange)
      e += ambientRadiance(uAmbient, uAmbientSh, d) * c;
  }
  hidden[v] = vec4(e * (4.0 * SH_PI / float(uRays)), 0.0);
}
