#version 450 core
// Precomputed illuminance composition: one level of the pull (pic.h pullUp): each inner node of the level
// holds the sum of its children's flux (RGB9E5 or RGBA32F, as pic_light.comp wrote the leaves).
#include "lighting/techniques/pic/pic.glsl"
layout(local_size_x = 64) in;

layout(std430, binding = 2) buffer FluxF { vec4 fluxF[]; };
layout(std430, binding = 3) buffer FluxP { uint fluxP[]; };
layout(std430, binding = 5) readonly buffer Children { ivec2 children[]; };  // per node
layout(std430, binding = 6) readonly buffer LevelNodes { int levelNodes[]; };

uniform int uFirst;  // this level's first entry in levelNodes
uniform int uCount;
uniform int uPacked;

vec3 fluxOf(int k) { return uPacked != 0 ? picUnpackRgb9e5(fluxP[k]) : fluxF[k].rgb; }

void main() {
  int j = int(gl_GlobalInvocationID.x);
  if (j >= uCount) return;
  int k = levelNodes[uFirst + j];
  ivec2 c = children[k];
  vec3 f = fluxOf(c.x) + fluxOf(c.y);
  if (uPacked != 0)
    fluxP[k] = picPackRgb9e5(f);
  else
    fluxF[k] = vec4(f, 0.0);
}
