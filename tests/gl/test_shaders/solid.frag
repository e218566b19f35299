#version 450 core
layout(location = 0) out vec4 outColour;
uniform vec4 uColour;
void main() { outColour = uColour; }
