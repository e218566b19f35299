#version 450 core
// The averaging weights of every VAL (the GLSL twin of lighting::setValWeights): lum(flux) / mean lum(flux)
// x mean area, over the uRealCount real VALs and the counts[2] virtual ones after them; counts[0] = their
// number, which bounds the gather. One workgroup: per-invocation sums over contiguous runs, then a tree.
#include "lighting/techniques/kinect_val/val.glsl"
layout(local_size_x = 1024) in;

layout(std430, binding = 0) buffer Vals { Val vals[]; };
layout(std430, binding = 1) buffer Counts { uint counts[]; };  // [0] all, [1] real, [2] virtual, [3] dimmed
uniform int uRealCount;
uniform int uCapacity;

shared float lumSum[1024];
shared float areaSum[1024];

float valLum(vec3 c) { return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b; }

void main() {
  uint t = gl_LocalInvocationIndex;
  uint n = min(uint(uRealCount) + counts[2], uint(uCapacity));
  uint per = (n + 1023u) / 1024u;
  uint begin = min(t * per, n), end = min(begin + per, n);
  float l = 0.0, a = 0.0;
  for (uint i = begin; i < end; ++i) {
    l += valLum(vals[i].flux.rgb);
    a += vals[i].posArea.w;
  }
  lumSum[t] = l;
  areaSum[t] = a;
  barrier();
  for (uint s = 512u; s > 0u; s >>= 1) {
    if (t < s) {
      lumSum[t] += lumSum[t + s];
      areaSum[t] += areaSum[t + s];
    }
    barrier();
  }
  float count = float(max(n, 1u));
  float mean = lumSum[0] / count, meanArea = areaSum[0] / count;
  for (uint i = begin; i < end; ++i) vals[i].normalWeight.w = (mean > 0.0 ? valLum(vals[i].flux.rgb) / mean : 1.0) * meanArea;
  if (t == 0u) {
    counts[0] = n;
    counts[1] = uint(uRealCount);
  }
}
