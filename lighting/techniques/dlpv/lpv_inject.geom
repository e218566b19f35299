#version 450 core
// Routes each injected point to its volume slice (gl_Layer) and cell (pixel).
layout(points) in;
layout(points, max_vertices = 1) out;
in ivec3 vCell[];
in vec4 vShR[];
in vec4 vShG[];
in vec4 vShB[];
uniform int uResolution;
flat out vec4 gShR;
flat out vec4 gShG;
flat out vec4 gShB;

void main() {
  if (vCell[0].x < 0) return;
  vec2 xy = (vec2(vCell[0].xy) + 0.5) / float(uResolution) * 2.0 - 1.0;
  gl_Position = vec4(xy, 0.0, 1.0);
  gl_Layer = vCell[0].z;
  gShR = vShR[0];
  gShG = vShG[0];
  gShB = vShB[0];
  EmitVertex();
  EndPrimitive();
}
