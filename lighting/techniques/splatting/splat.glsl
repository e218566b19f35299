// Splatting: the GLSL twin of splat.h (pixel-light lobes, irradiance, splat boxes, hierarchical warping).
#ifndef SPLAT_PI
#define SPLAT_PI 3.14159265358979
#endif

// splat.h kFarStride: samples per far light, and the ratio of I_low between far levels.
#define SPLAT_FAR_STRIDE 16

// One pixel light (std430; splat.h PixelLight).
struct PixelLight {
  vec4 positionArea;    // xyz x_p, w A_p (m^2)
  vec4 normalExponent;  // xyz n_p, w P (0 = diffuse)
  vec4 fluxWiden;       // rgb Phi_p x weight (negative: subtracted), w the widening distance a
  vec4 axis;            // xyz r_p (glossy) or n_p
};

float splatLum(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// splat.h scaledILow: I_low = scale x lum|Phi|.
float splatScaledILow(PixelLight l, float scale) { return scale * splatLum(abs(l.fluxWiden.rgb)); }

float splatWidened(float P, float d, float a) { return a > 0.0 ? min(P, P * d / a) : P; }

vec3 splatIntensity(PixelLight l, vec3 w, float d) {
  float cn = dot(l.normalExponent.xyz, w);
  if (!(cn > 0.0)) return vec3(0.0);
  float P0 = l.normalExponent.w;
  if (!(P0 > 0.0)) return l.fluxWiden.rgb * (cn / SPLAT_PI);
  float P = splatWidened(P0, d, l.fluxWiden.w);
  float ca = max(dot(l.axis.xyz, w), 0.0);
  float lobe = P > 0.0 ? pow(ca, P) : 1.0;
  return l.fluxWiden.rgb * ((P + 1.0) / (2.0 * SPLAT_PI) * lobe);
}

vec3 splatIrradiance(PixelLight l, vec3 x, vec3 n) {
  vec3 v = x - l.positionArea.xyz;
  float d2 = dot(v, v);
  if (!(d2 > 0.0) || isinf(d2)) return vec3(0.0);
  float d = sqrt(d2);
  vec3 w = v / d;
  float cr = -dot(n, w);
  if (!(cr > 0.0)) return vec3(0.0);
  return splatIntensity(l, w, d) * (cr / (d2 + max(l.positionArea.w, 0.0) / SPLAT_PI));
}

float splatOutline(float x, float n) {
  if (!(x > 0.0) || x >= 1.0) return 0.0;
  return pow(x, n / (n + 2.0)) * sqrt(max(0.0, 1.0 - pow(x, 4.0 / (n + 2.0))));
}

// The box around a light's significant region for the cut-off iLow (splat.h splatBox).
struct SplatBox {
  vec3 centre, a0, a1, a2, halfExtent;
};

SplatBox splatBox(PixelLight l, float iLow) {
  SplatBox b;
  float P = l.normalExponent.w;
  float n = P > 0.0 ? P : 1.0;
  vec3 axis = P > 0.0 ? l.axis.xyz : l.normalExponent.xyz;
  b.a0 = axis;
  vec3 helper = abs(axis.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  b.a1 = normalize(cross(axis, helper));
  b.a2 = cross(axis, b.a1);
  float i0 = splatLum(abs(l.fluxWiden.rgb)) * (P > 0.0 ? (P + 1.0) / (2.0 * SPLAT_PI) : 1.0 / SPLAT_PI);
  float R = iLow > 0.0 && i0 > 0.0 ? sqrt(i0 / iLow) : 0.0;
  float c = pow(n / (n + 2.0), (n + 2.0) / 4.0);
  float h = splatOutline(c, n), w = max(c, 1.0 - c);
  float lo = (c - w) * R, hi = (c + w) * R, lateral = h * R;
  float a = l.fluxWiden.w;
  if (P > 0.0 && a > 0.0 && R > 0.0) {
    lo = min(lo, -a);
    hi = max(hi, a);
    lateral = max(lateral, a);
  }
  b.centre = l.positionArea.xyz + axis * (0.5 * (lo + hi));
  b.halfExtent = vec3(0.5 * (hi - lo), lateral, lateral);
  return b;
}

// splat.h boxCoverage: 1 in the box, falling linearly to 0 at SPLAT_BOX_FADE times its half extents beyond it.
#define SPLAT_BOX_FADE 0.04
float splatBoxCoverage(SplatBox b, vec3 x) {
  vec3 v = x - b.centre;
  if (!(b.halfExtent.x > 0.0 && b.halfExtent.y > 0.0 && b.halfExtent.z > 0.0)) return 0.0;
  float u = max(abs(dot(v, b.a0)) / b.halfExtent.x, max(abs(dot(v, b.a1)) / b.halfExtent.y, abs(dot(v, b.a2)) / b.halfExtent.z));
  return clamp((1.0 + SPLAT_BOX_FADE - u) / SPLAT_BOX_FADE, 0.0, 1.0);
}

bool splatInsideBox(SplatBox b, vec3 x) {
  vec3 v = x - b.centre;
  return abs(dot(v, b.a0)) <= b.halfExtent.x && abs(dot(v, b.a1)) <= b.halfExtent.y && abs(dot(v, b.a2)) <= b.halfExtent.z;
}

// splat.h samplePoint: the R2 sequence.
vec2 splatSamplePoint(int i) {
  const float a1 = 0.7548776662466927, a2 = 0.5698402909980532;
  // Split i to keep the products exact in float for large i.
  float fi = float(i);
  return fract(vec2(0.5) + vec2(fract(a1 * fi), fract(a2 * fi)));
}
