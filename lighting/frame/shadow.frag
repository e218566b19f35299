#version 450 core
// The objects' shadow map: world position of the nearest virtual surface (w = 1 where one was seen), read
// by lighting/direct_light.glsl's shadow test.
in vec3 vPosition;
layout(location = 0) out vec4 outPosition;
void main() { outPosition = vec4(vPosition, 1.0); }
