#version 450 core
// Splatting: one level of a sum pyramid (splat.h buildPyramid): each texel of level k+1 is the sum of its four
// children on level k. Levels lie one after the other in one buffer.
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = 0) buffer Pyramid { float p[]; };
uniform int uSrcOffset, uDstOffset, uDstSide;
void main() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  if (t.x >= uDstSide || t.y >= uDstSide) return;
  int s = 2 * uDstSide;
  int a = uSrcOffset + (2 * t.y) * s + 2 * t.x;
  p[uDstOffset + t.y * uDstSide + t.x] = p[a] + p[a + 1] + p[a + s] + p[a + s + 1];
}
