// Precomputed illuminance composition on the GPU: what its passes share (pic.h is the C++ twin).
// Define SH_BANDS (the caches' bands) and PIC_CHROMA_BANDS (bands of Co and Cg, <= SH_BANDS) before including.
#include "lighting/sh.glsl"
#ifndef PIC_CHROMA_BANDS
#define PIC_CHROMA_BANDS SH_BANDS
#endif
#define PIC_CHROMA_COEFFS (PIC_CHROMA_BANDS * PIC_CHROMA_BANDS)
// A cache's stored SH radiance: Y over every coefficient, then Co and Cg over the first PIC_CHROMA_COEFFS.
#define PIC_CACHE_FLOATS (SH_COEFFS + 2 * PIC_CHROMA_COEFFS)

struct PicSurfel {
  vec4 positionArea;    // xyz position, w area
  vec4 normalReceiver;  // xyz unit normal, w its bounce receiver's index (-1: none)
  vec4 albedo;
};

// pic.h toYCoCg / fromYCoCg.
vec3 picToYCoCg(vec3 c) {
  float co = 0.5 * (c.r - c.b);
  float t = c.b + co;
  float cg = 0.5 * (c.g - t);
  return vec3(t + cg, co, cg);
}
vec3 picFromYCoCg(vec3 y) {
  float t = y.x - y.z;
  return vec3(t + y.y, y.x + y.z, t - y.y);
}

// pic.h packRgb9e5 / unpackRgb9e5 (9-bit mantissas, shared 5-bit exponent, bias 15; negatives and NaN as 0).
uint picPackRgb9e5(vec3 c) {
  const float maxValue = 511.0 / 512.0 * 65536.0;
  for (int i = 0; i < 3; ++i) c[i] = c[i] > 0.0 ? min(c[i], maxValue) : 0.0;
  float m = max(c.r, max(c.g, c.b));
  int e = clamp(max(-16, int(floor(log2(max(m, 1e-30))))) + 16, 0, 31);
  float denom = exp2(float(e - 24));
  if (int(round(m / denom)) == 512) {
    denom *= 2.0;
    e += 1;
  }
  uvec3 v = uvec3(min(round(c / denom), vec3(511.0)));
  return v.r | (v.g << 9) | (v.b << 18) | (uint(e) << 27);
}
vec3 picUnpackRgb9e5(uint p) {
  float scale = exp2(float(int(p >> 27) - 24));
  return vec3(float(p & 511u), float((p >> 9) & 511u), float((p >> 18) & 511u)) * scale;
}

// One coefficient of a stored cache as RGB.
vec3 picCacheCoefficient(float cache[PIC_CACHE_FLOATS], int i) {
  vec3 y = vec3(cache[i], 0.0, 0.0);
  if (i < PIC_CHROMA_COEFFS) y.yz = vec2(cache[SH_COEFFS + i], cache[SH_COEFFS + PIC_CHROMA_COEFFS + i]);
  return picFromYCoCg(y);
}

// pic.h shLobeRadiance (exponent 1, times pi: shIrradiance) from a stored cache.
vec3 picLobe(float cache[PIC_CACHE_FLOATS], vec3 r, float exponent) {
  float y[SH_COEFFS];
  shEvaluate(normalize(r), y);
  vec3 sum = vec3(0.0);
  for (int l = 0; l < SH_BANDS; ++l) {
    float s = shPhongFactor(exponent, l);
    for (int m = -l; m <= l; ++m) {
      int i = l * (l + 1) + m;
      sum += s * y[i] * picCacheCoefficient(cache, i);
    }
  }
  return sum;
}
