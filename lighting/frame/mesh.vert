#version 450 core
// Transforms a mesh into a camera or light view; world-space attributes for the G-buffer and RSM passes.
layout(location = 0) in vec3 inPosition;  // model frame, metres
layout(location = 1) in vec3 inNormal;
layout(location = 2) in vec3 inAlbedo;    // linear RGB

uniform mat4 uModel;       // world <- model
uniform mat3 uNormalModel; // inverse transpose of uModel's 3x3
uniform mat4 uViewProj;    // clip <- world

invariant gl_Position;  // val_mesh.vert repeats this transform and depth-tests against it

out vec3 vPosition;
out vec3 vNormal;
out vec3 vAlbedo;

void main() {
  vec4 world = uModel * vec4(inPosition, 1.0);
  vPosition = world.xyz;
  vNormal = uNormalModel * inNormal;
  vAlbedo = inAlbedo;
  gl_Position = uViewProj * world;
}
