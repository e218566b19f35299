#version 450 core
// G-buffer, the real surface the camera sees, drawn per pixel from the frame's own depth (positions and normals
// in the camera frame, FrameGeometry::setViewSurface) as a mesh over every uStride-th depth pixel would be
// rasterised (reconstruction::buildDepthMesh: two triangles per grid cell, (00, 01, 10) and (10, 01, 11), each
// only where its three corners have a depth and no edge jumps by more than uMaxRelativeJump of the nearer
// depth): the pixel's position and normal interpolated over the triangle holding it, written as gbuffer.frag
// writes a real mesh's (world position, normal facing the camera, the pixel's albedo, w = 0 / a = 0: real),
// with the depth its point projects to, so that the objects drawn after it are hidden where a real surface lies
// in front of them. No triangle there: the clear value. The interpolation is linear in the image where the
// rasteriser's is perspective-correct: over a triangle a few pixels wide the two differ by well under a
// millimetre at tabletop range.
layout(binding = 0) uniform sampler2D uAlbedoImage;      // rgb albedo per pixel (FrameResources::setRealPixelAlbedo)
layout(binding = 1) uniform sampler2D uCameraPosition;   // xyz camera frame, metres
layout(binding = 2) uniform sampler2D uCameraNormal;     // xyz camera frame; 0 = unknown
uniform mat4 uWorldFromCamera;
uniform mat4 uViewProj;  // clip <- world, the camera's (the objects' pass uses the same)
uniform vec3 uEye;       // camera centre, world
uniform int uStride;     // the mesh's grid, pixels
uniform float uMaxRelativeJump;

layout(location = 0) out vec4 outPosition;
layout(location = 1) out vec4 outNormal;
layout(location = 2) out vec4 outAlbedo;

// Written as a test that passes only for finite positive depths (a NaN fails it).
bool hasDepth(vec3 c) { return c.z > 0.0 && c.z < 1e30 && abs(c.x) < 1e30 && abs(c.y) < 1e30; }
bool joined(float za, float zb) { return abs(za - zb) <= uMaxRelativeJump * min(za, zb); }

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  ivec2 size = textureSize(uCameraPosition, 0);
  ivec2 g = (p / uStride) * uStride;
  // The grid's last row and column of vertices lie at most at size - 1: pixels past them have no cell.
  if (g.x + uStride > size.x - 1 || g.y + uStride > size.y - 1) discard;
  vec2 uv = vec2(p - g) / float(uStride);
  ivec2 a, b, c;
  vec3 w;
  if (uv.x + uv.y < 1.0) {  // a pixel on the shared edge is the second triangle's, as the rasteriser decides
    a = g;
    b = g + ivec2(0, uStride);
    c = g + ivec2(uStride, 0);
    w = vec3(1.0 - uv.x - uv.y, uv.y, uv.x);
  } else {
    a = g + ivec2(uStride, 0);
    b = g + ivec2(0, uStride);
    c = g + ivec2(uStride, uStride);
    w = vec3(1.0 - uv.y, 1.0 - uv.x, uv.x + uv.y - 1.0);
  }
  vec3 pa = texelFetch(uCameraPosition, a, 0).xyz;
  vec3 pb = texelFetch(uCameraPosition, b, 0).xyz;
  vec3 pc = texelFetch(uCameraPosition, c, 0).xyz;
  if (!(hasDepth(pa) && hasDepth(pb) && hasDepth(pc))) discard;
  if (!(joined(pa.z, pb.z) && joined(pb.z, pc.z) && joined(pa.z, pc.z))) discard;
  vec3 cp = w.x * pa + w.y * pb + w.z * pc;
  vec3 cn = w.x * texelFetch(uCameraNormal, a, 0).xyz + w.y * texelFetch(uCameraNormal, b, 0).xyz +
            w.z * texelFetch(uCameraNormal, c, 0).xyz;
  vec3 world = (uWorldFromCamera * vec4(cp, 1.0)).xyz;
  vec4 clip = uViewProj * vec4(world, 1.0);
  float z = clip.z / clip.w;
  if (!(clip.w > 0.0 && z >= -1.0 && z <= 1.0)) discard;  // outside the near and far planes, as a mesh is clipped
  gl_FragDepth = 0.5 * z + 0.5;
  vec3 n = mat3(uWorldFromCamera) * cn;
  // A degenerate normal faces the camera (gbuffer.frag's rule).
  n = dot(n, n) > 1e-20 ? normalize(n) : normalize(uEye - world);
  if (dot(n, uEye - world) < 0.0) n = -n;
  outPosition = vec4(world, 1.0);
  outNormal = vec4(n, 0.0);
  vec4 albedo = texelFetch(uAlbedoImage, p, 0);
  outAlbedo = vec4(max(albedo.rgb, vec3(0.0)), min(albedo.a, 0.0));  // a: minus the clipped channels' bits
}
