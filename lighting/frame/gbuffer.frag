#version 450 core
// G-buffer: world position, normal facing the camera, albedo and the real/virtual mask. Texels no surface
// covers keep the clear value 0 (w = 0).
in vec3 vPosition;
in vec3 vNormal;
in vec3 vAlbedo;
uniform vec3 uEye;       // camera centre, world
uniform float uVirtual;  // 1 for virtual objects, 0 for the real mesh
uniform float uObject;   // 0 for the real mesh, 1 + index for virtual object index
uniform int uPixelAlbedo;  // 1: real surfaces take their albedo per camera pixel (FrameResources::setRealPixelAlbedo)
layout(binding = 0) uniform sampler2D uAlbedoImage;  // rgb albedo per pixel, negative: none there

layout(location = 0) out vec4 outPosition;  // xyz world, w = 1
layout(location = 1) out vec4 outNormal;    // xyz unit world normal towards the camera, w = uObject
layout(location = 2) out vec4 outAlbedo;    // rgb albedo, a = 1 on virtual surfaces, <= 0 on real ones

void main() {
  // A degenerate interpolated normal (opposite vertex normals) faces the camera instead of becoming NaN.
  vec3 n = dot(vNormal, vNormal) > 1e-20 ? normalize(vNormal) : normalize(uEye - vPosition);
  if (dot(n, uEye - vPosition) < 0.0) n = -n;
  outPosition = vec4(vPosition, 1.0);
  outNormal = vec4(n, uObject);
  vec3 albedo = vAlbedo;
  float alpha = uVirtual;
  if (uPixelAlbedo == 1 && uVirtual < 0.5) {
    vec4 a = texelFetch(uAlbedoImage, ivec2(gl_FragCoord.xy), 0);
    if (a.r >= 0.0) albedo = a.rgb;
    alpha = min(a.a, 0.0);  // minus the pixel's clipped camera channels' bits (lighting/clipped_real.glsl)
  }
  outAlbedo = vec4(albedo, alpha);
}
