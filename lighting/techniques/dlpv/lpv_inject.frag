#version 450 core
// Additive blending sums every point that lands in a cell (no hit-count averaging).
flat in vec4 gShR;
flat in vec4 gShG;
flat in vec4 gShB;
layout(location = 0) out vec4 outR;
layout(location = 1) out vec4 outG;
layout(location = 2) out vec4 outB;
void main() {
  outR = gShR;
  outG = gShG;
  outB = gShB;
}
