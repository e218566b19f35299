#version 450 core
// Gather (eq. 7) and renormalisation (eq. 11) of every receiver over every VAL. The VALs stream through
// shared memory in tiles of K_CACHE (the paper's texture-cache batch): each tile is loaded once per
// workgroup and read by all its receivers. Receivers are sparse points (sparse method) or visible pixels
// (brute force); sums[2i] = (E, 0), sums[2i+1] = (S, 0) are written for the brute-force path.
#include "lighting/val.glsl"
layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Vals { Val vals[]; };
layout(std430, binding = 1) readonly buffer Receivers { Receiver receivers[]; };
layout(std430, binding = 2) writeonly buffer Vpls { Vpl vpls[]; };
layout(std430, binding = 3) writeonly buffer Sums { vec4 sums[]; };
uniform int uValCount;
uniform int uReceiverCount;

shared Val tile[K_CACHE];

void main() {
  int i = int(gl_GlobalInvocationID.x);
  bool live = i < uReceiverCount;
  Receiver r = receivers[min(i, uReceiverCount - 1)];
  vec3 n = r.normal.xyz, view = r.view.xyz;
  vec3 refl = 2.0 * dot(n, view) * n - view;
  ValSums s = valSumsZero();
  for (int base = 0; base < uValCount; base += K_CACHE) {
    for (int t = int(gl_LocalInvocationIndex); t < K_CACHE; t += 64)
      if (base + t < uValCount) tile[t] = vals[base + t];
    barrier();
    int count = min(K_CACHE, uValCount - base);
    if (live)
      for (int j = 0; j < count; ++j) valAccumulate(s, r, refl, tile[j]);
    barrier();
  }
  if (!live) return;
  vpls[i] = valNormalize(s, r, refl);
  sums[2 * i] = vec4(s.E, 0.0);
  sums[2 * i + 1] = vec4(s.S, 0.0);
}
