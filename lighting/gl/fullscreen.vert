#version 450 core
// A triangle covering the viewport, generated from gl_VertexID (draw 3 vertices, no buffers).
void main() {
  const vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
