// Shared by test shaders: proves #include resolution.
vec4 testColour() { return vec4(COLOUR_R, 0.25, 0.75, 1.0); }
