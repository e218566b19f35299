#version 450 core
// dst += src for the three channel volumes (joins the direct delta to a propagation in progress).
layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
layout(binding = 0) uniform sampler3D uSrcR;
layout(binding = 1) uniform sampler3D uSrcG;
layout(binding = 2) uniform sampler3D uSrcB;
layout(rgba32f, binding = 0) uniform image3D uDstR;
layout(rgba32f, binding = 1) uniform image3D uDstG;
layout(rgba32f, binding = 2) uniform image3D uDstB;
uniform int uResolution;
void main() {
  ivec3 c = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(c, ivec3(uResolution)))) return;
  imageStore(uDstR, c, imageLoad(uDstR, c) + texelFetch(uSrcR, c, 0));
  imageStore(uDstG, c, imageLoad(uDstG, c) + texelFetch(uSrcG, c, 0));
  imageStore(uDstB, c, imageLoad(uDstB, c) + texelFetch(uSrcB, c, 0));
}
