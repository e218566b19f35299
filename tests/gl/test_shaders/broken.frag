#version 450 core
layout(location = 0) out vec4 outColour;
// The next line's error must be reported as gl/test_shaders/broken.frag:4.
void main() { outColour = undefinedThing; }
