#version 450 core
// The virtual object's lit texels of one light's RSM as VALs, the GLSL twin of lighting::valsFromRsm (same
// order, same guards): every uStride-th texel per axis (from uStride / 2), standing for its uStride² block,
// appended to `vals` after the counts[2] virtual VALs already there, counts[2] raised by as many.
// One workgroup compacts the grid in order without reading anything back: each invocation takes a contiguous
// run of the grid's cells and counts its VALs, an exclusive scan over the invocations gives each run its
// first slot, and each run is evaluated again and written there.
#include "lighting/techniques/kinect_val/val.glsl"
layout(local_size_x = 1024) in;

layout(binding = 0) uniform sampler2D uRsmPosition;  // xyz world, w = 1 where a surface was seen
layout(binding = 1) uniform sampler2D uRsmNormal;    // xyz facing the light, w = object index + 1 on virtual texels
layout(binding = 2) uniform sampler2D uRsmFlux;      // reflected flux through the texel, W
layout(binding = 3) uniform sampler2D uRsmDirect;    // incident flux through the texel, W
layout(std430, binding = 0) buffer Vals { Val vals[]; };
layout(std430, binding = 1) buffer Counts { uint counts[]; };  // [0] all, [1] real, [2] virtual, [3] dimmed
uniform int uStride;
uniform int uCapacity;    // slots of `vals`
uniform int uLightType;   // 0 point, 1 spot, 2 directional (lighting/direct_light.glsl)
uniform vec3 uLightPosition;
uniform vec3 uLightDirection;
uniform vec3 uLightPower;  // irradiance (directional) or intensity

shared uint runStart[1024];

bool rsmVal(ivec2 px, out Val v) {
  v.posArea = v.normalWeight = v.flux = vec4(0.0);
  vec4 n4 = texelFetch(uRsmNormal, px, 0);
  if (n4.w < 0.5) return false;  // real texel (or empty)
  vec4 p4 = texelFetch(uRsmPosition, px, 0), f4 = texelFetch(uRsmFlux, px, 0), d4 = texelFetch(uRsmDirect, px, 0);
  vec3 p = p4.xyz, n = n4.xyz, toLight, beam;  // beam: irradiance across the beam at the texel
  if (uLightType == 2) {
    toLight = -uLightDirection;
    beam = uLightPower;
  } else {
    vec3 d = uLightPosition - p;
    float d2 = max(dot(d, d), 1e-12);
    toLight = d / sqrt(d2);
    beam = uLightPower / d2;
  }
  int c = beam.r >= beam.g && beam.r >= beam.b ? 0 : (beam.g >= beam.b ? 1 : 2);
  if (!(beam[c] > 0.0) || !(d4[c] > 0.0)) return false;
  float across = d4[c] / beam[c];
  float block = float(uStride * uStride);
  v.posArea = vec4(p, block * across / max(dot(n, toLight), 0.1));
  v.normalWeight = vec4(n, 1.0);
  v.flux = vec4(block * f4.rgb, 0.0);
  return true;
}

void main() {
  uint t = gl_LocalInvocationIndex;
  int size = textureSize(uRsmNormal, 0).x;
  int first = uStride / 2;
  int side = size > first ? (size - first + uStride - 1) / uStride : 0;  // grid cells per axis
  uint cells = uint(side * side);
  uint per = (cells + 1023u) / 1024u;
  uint begin = min(t * per, cells), end = min(begin + per, cells);
  uint base = counts[2];
  Val v;
  uint mine = 0u;
  for (uint c = begin; c < end; ++c)
    if (rsmVal(ivec2(first + int(c % uint(side)) * uStride, first + int(c / uint(side)) * uStride), v)) ++mine;
  runStart[t] = mine;
  barrier();
  if (t == 0u) {
    uint sum = 0u;
    for (uint i = 0u; i < 1024u; ++i) {
      uint n = runStart[i];
      runStart[i] = sum;
      sum += n;
    }
    counts[2] = min(base + sum, uint(uCapacity));
  }
  barrier();
  uint slot = base + runStart[t];
  for (uint c = begin; c < end && slot < uint(uCapacity); ++c)
    if (rsmVal(ivec2(first + int(c % uint(side)) * uStride, first + int(c / uint(side)) * uStride), v)) vals[slot++] = v;
}
