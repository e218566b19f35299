#version 450 core
// Precomputed illuminance composition: each cache's SH radiance (pic.h gatherCaches): the sum over its links
// of the node's flux times the link's factor G, minus the ambient the room hides from it (its transfer
// matrix T times the ambient's 9 coefficients); accumulated as YCoCg, luma over every coefficient and chroma
// over the first PIC_CHROMA_COEFFS only (chroma compression saves their multiply-adds and storage).
#include "lighting/techniques/pic/pic.glsl"
layout(local_size_x = 64) in;

layout(std430, binding = 2) readonly buffer FluxF { vec4 fluxF[]; };
layout(std430, binding = 3) readonly buffer FluxP { uint fluxP[]; };
layout(std430, binding = 7) readonly buffer LinkNodes { int linkNode[]; };
layout(std430, binding = 8) readonly buffer LinkFactors { float linkFactor[]; };
layout(std430, binding = 9) readonly buffer Transfer { float transfer[]; };
layout(std430, binding = 10) writeonly buffer Caches { float caches[]; };

uniform int uCount;
uniform int uLinks;
uniform int uPacked;
uniform vec3 uAmbientCoefficients[9];  // pic.h Ambient::coefficients, as YCoCg

void main() {
  int c = int(gl_GlobalInvocationID.x);
  if (c >= uCount) return;
  float y[SH_COEFFS];
  vec2 chroma[PIC_CHROMA_COEFFS];
  for (int i = 0; i < SH_COEFFS; ++i) y[i] = 0.0;
  for (int i = 0; i < PIC_CHROMA_COEFFS; ++i) chroma[i] = vec2(0.0);
  for (int l = 0; l < uLinks; ++l) {
    int k = linkNode[c * uLinks + l];
    if (k < 0) continue;
    vec3 f = picToYCoCg(uPacked != 0 ? picUnpackRgb9e5(fluxP[k]) : fluxF[k].rgb);
    int base = (c * uLinks + l) * SH_COEFFS;
    for (int i = 0; i < SH_COEFFS; ++i) y[i] += f.x * linkFactor[base + i];
    for (int i = 0; i < PIC_CHROMA_COEFFS; ++i) chroma[i] += f.yz * linkFactor[base + i];
  }
  for (int i = 0; i < SH_COEFFS; ++i) {
    vec3 hidden = vec3(0.0);
    for (int j = 0; j < 9; ++j) hidden += transfer[(c * SH_COEFFS + i) * 9 + j] * uAmbientCoefficients[j];
    y[i] -= hidden.x;
    if (i < PIC_CHROMA_COEFFS) chroma[i] -= hidden.yz;
  }
  int out0 = c * PIC_CACHE_FLOATS;
  for (int i = 0; i < SH_COEFFS; ++i) caches[out0 + i] = y[i];
  for (int i = 0; i < PIC_CHROMA_COEFFS; ++i) {
    caches[out0 + SH_COEFFS + i] = chroma[i].x;
    caches[out0 + SH_COEFFS + PIC_CHROMA_COEFFS + i] = chroma[i].y;
  }
}
