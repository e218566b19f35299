#version 450 core
// One propagation step (C++ twin: lpv.h propagateReference): every cell gathers from its 6 neighbours; the
// neighbour's intensity towards each of the receiving cell's 5 non-shared faces times the face's solid angle
// is re-emitted as a clamped-cosine lobe along that face's normal. The step's result is also added to the
// accumulation volume.
#include "lighting/techniques/dlpv/lpv.glsl"
layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;

layout(binding = 0) uniform sampler3D uSrcR;
layout(binding = 1) uniform sampler3D uSrcG;
layout(binding = 2) uniform sampler3D uSrcB;
layout(rgba32f, binding = 0) writeonly uniform image3D uDstR;
layout(rgba32f, binding = 1) writeonly uniform image3D uDstG;
layout(rgba32f, binding = 2) writeonly uniform image3D uDstB;
layout(rgba32f, binding = 3) uniform image3D uAccR;
layout(rgba32f, binding = 4) uniform image3D uAccG;
layout(rgba32f, binding = 5) uniform image3D uAccB;
uniform int uResolution;
uniform float uDamping;
uniform int uClampNegative;

const ivec3 kAxes[6] = ivec3[6](ivec3(1, 0, 0), ivec3(-1, 0, 0), ivec3(0, 1, 0), ivec3(0, -1, 0), ivec3(0, 0, 1),
                                ivec3(0, 0, -1));

void main() {
  ivec3 cell = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(cell, ivec3(uResolution)))) return;
  vec4 outR = vec4(0.0), outG = vec4(0.0), outB = vec4(0.0);
  const float sideDen = 1.0 / sqrt(1.25);
  for (int a = 0; a < 6; ++a) {
    ivec3 d = kAxes[a];
    ivec3 s = cell - d;
    if (any(lessThan(s, ivec3(0))) || any(greaterThanEqual(s, ivec3(uResolution)))) continue;
    vec4 r = texelFetch(uSrcR, s, 0), g = texelFetch(uSrcG, s, 0), b = texelFetch(uSrcB, s, 0);
    vec3 dv = vec3(d);
    float w = lpvDamping(0.2126 * r + 0.7152 * g + 0.0722 * b, dv, uDamping);
    for (int f = 0; f < 6; ++f) {
      ivec3 fa = kAxes[f];
      if (fa == -d) continue;
      bool front = fa == d;
      vec3 dir = front ? dv : (dv + 0.5 * vec3(fa)) * sideDen;
      float solid = front ? kLpvFrontSolidAngle : kLpvSideSolidAngle;
      vec4 y = lpvBasis(dir);
      vec3 flux = w * solid * vec3(dot(r, y), dot(g, y), dot(b, y));
      if (uClampNegative != 0) flux = max(flux, vec3(0.0));
      vec4 lobe = lpvCosineLobe(vec3(fa)) / LPV_PI;
      outR += flux.r * lobe;
      outG += flux.g * lobe;
      outB += flux.b * lobe;
    }
  }
  imageStore(uDstR, cell, outR);
  imageStore(uDstG, cell, outG);
  imageStore(uDstB, cell, outB);
  imageStore(uAccR, cell, imageLoad(uAccR, cell) + outR);
  imageStore(uAccG, cell, imageLoad(uAccG, cell) + outG);
  imageStore(uAccB, cell, imageLoad(uAccB, cell) + outB);
}
