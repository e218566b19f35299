#version 450 core
// Gather (eq. 7) and renormalisation (eq. 11) of every receiver over every VAL. The VALs stream through
// shared memory in tiles of K_CACHE (the paper's texture-cache batch): each tile is loaded once per
// workgroup and read by all its receivers. Receivers are sparse points (sparse method) or visible pixels
// (brute force); sums[2i] = (E, 0), sums[2i+1] = (S, 0) are written for the brute-force path.
// Large VAL sets are gathered in chunks [uValBegin, uValEnd), one dispatch each, the running sums kept per
// receiver in `partial` between them (llvmpipe cuts a shader invocation's loops after 65535 iterations, and
// a bounded dispatch keeps a GPU's watchdog away); the last chunk renormalises. The set's size is counts[0]
// (a set built on the GPU is dispatched for its capacity; chunks past its end carry the sums through).
#include "lighting/techniques/kinect_val/val.glsl"
layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Vals { Val vals[]; };
layout(std430, binding = 1) readonly buffer Receivers { Receiver receivers[]; };
layout(std430, binding = 2) writeonly buffer Vpls { Vpl vpls[]; };
layout(std430, binding = 3) writeonly buffer Sums { vec4 sums[]; };
layout(std430, binding = 4) buffer Partial { vec4 partial[]; };  // 5 per receiver
layout(std430, binding = 6) readonly buffer Counts { uint counts[]; };  // [0]: the VALs in `vals` (built on the GPU)
uniform int uValBegin;
uniform int uValEnd;
uniform int uFirstChunk;  // 1: start from zero sums
uniform int uLastChunk;   // 1: renormalise and write the VPLs and sums
uniform int uReceiverCount;

shared Val tile[K_CACHE];

void main() {
  int i = int(gl_GlobalInvocationID.x);
  bool live = i < uReceiverCount;
  Receiver r = receivers[min(i, uReceiverCount - 1)];
  vec3 n = r.normal.xyz, view = r.view.xyz;
  vec3 refl = 2.0 * dot(n, view) * n - view;
  ValSums s = valSumsZero();
  if (uFirstChunk == 0 && live) {
    vec4 p0 = partial[5 * i], p1 = partial[5 * i + 1], p2 = partial[5 * i + 2], p3 = partial[5 * i + 3],
         p4 = partial[5 * i + 4];
    s.E = p0.xyz;
    s.wd = p0.w;
    s.S = p1.xyz;
    s.ws = p1.w;
    s.ld = p2.xyz;
    s.ls = p3.xyz;
    s.ldSq = vec3(p2.w, p4.xy);
    s.lsSq = vec3(p3.w, p4.zw);
  }
  int valEnd = min(uValEnd, int(counts[0]));  // the chunk ends at the set's end
  for (int base = uValBegin; base < valEnd; base += K_CACHE) {
    for (int t = int(gl_LocalInvocationIndex); t < K_CACHE; t += 64)
      if (base + t < valEnd) tile[t] = vals[base + t];
    barrier();
    int count = min(K_CACHE, valEnd - base);
    if (live)
      for (int j = 0; j < count; ++j) valAccumulate(s, r, refl, tile[j]);
    barrier();
  }
  if (!live) return;
  if (uLastChunk == 0) {
    partial[5 * i] = vec4(s.E, s.wd);
    partial[5 * i + 1] = vec4(s.S, s.ws);
    partial[5 * i + 2] = vec4(s.ld, s.ldSq.x);
    partial[5 * i + 3] = vec4(s.ls, s.lsSq.x);
    partial[5 * i + 4] = vec4(s.ldSq.yz, s.lsSq.yz);
    return;
  }
  vpls[i] = valNormalize(s, r, refl);
  sums[2 * i] = vec4(s.E, 0.0);
  sums[2 * i + 1] = vec4(s.S, 0.0);
}
