#version 450 core
// The G-buffer at 1/factor (lighting/upsample.h): each texel takes every channel, depth included, of one frame
// pixel of its block, the one at factor / 2 into it (lighting::reducedSource), so it is an exact sample of a
// surface the camera sees.
layout(binding = 0) uniform sampler2D uPosition;
layout(binding = 1) uniform sampler2D uNormal;
layout(binding = 2) uniform sampler2D uAlbedo;
layout(binding = 3) uniform sampler2D uDepth;
uniform int uFactor;

layout(location = 0) out vec4 outPosition;
layout(location = 1) out vec4 outNormal;
layout(location = 2) out vec4 outAlbedo;

void main() {
  ivec2 size = textureSize(uPosition, 0);
  ivec2 p = min(ivec2(gl_FragCoord.xy) * uFactor + ivec2(uFactor / 2), size - 1);
  outPosition = texelFetch(uPosition, p, 0);
  outNormal = texelFetch(uNormal, p, 0);
  outAlbedo = texelFetch(uAlbedo, p, 0);
  gl_FragDepth = texelFetch(uDepth, p, 0).r;
}
