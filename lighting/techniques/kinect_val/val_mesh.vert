#version 450 core
// Kinect-VAL per-vertex interpolation (eq. 12-13): each vertex blends the averaged VPL pairs of its 8
// nearest sparse points (weights precomputed in model space). The same transform as mesh.vert, invariant,
// so the pass depth-tests EQUAL-or-less against the G-buffer's depth and shades only visible fragments.
#include "lighting/techniques/kinect_val/val.glsl"
invariant gl_Position;

layout(location = 0) in vec3 inPosition;  // model frame, metres
layout(location = 1) in vec3 inNormal;
layout(location = 2) in vec3 inAlbedo;

uniform mat4 uModel;
uniform mat3 uNormalModel;
uniform mat4 uViewProj;
uniform int uBase;  // this object's first sparse point in the VPL buffer

struct VertexWeights {
  ivec4 index0, index1;  // sparse point per neighbour (-1 unused), relative to the object
  vec4 weight0, weight1; // summing to 1
};
layout(std430, binding = 2) readonly buffer Vpls { Vpl vpls[]; };
layout(std430, binding = 5) readonly buffer Weights { VertexWeights weights[]; };

out vec3 vPosition;
out vec3 vNormal;
out vec3 vAlbedo;
out vec4 vLd, vld, vLs, vls;

void blend(int i, float w) {
  if (i < 0) return;
  Vpl v = vpls[uBase + i];
  vLd += w * v.Ld;
  vld += w * v.ld;
  vLs += w * v.Ls;
  vls += w * v.ls;
}

void main() {
  vec4 world = uModel * vec4(inPosition, 1.0);
  vPosition = world.xyz;
  vNormal = uNormalModel * inNormal;
  vAlbedo = inAlbedo;
  vLd = vld = vLs = vls = vec4(0.0);
  VertexWeights w = weights[gl_VertexID];
  for (int k = 0; k < 4; ++k) {
    blend(w.index0[k], w.weight0[k]);
    blend(w.index1[k], w.weight1[k]);
  }
  gl_Position = uViewProj * world;
}
