#version 450 core
#include "common.glsl"
layout(location = 0) out vec4 outColour;
void main() { outColour = testColour(); }
