// Kinect-VAL math, the GLSL twin of lighting/val.cpp (same guards, same accumulation order).
#ifndef MRGI_VAL_GLSL
#define MRGI_VAL_GLSL

const float kValPi = 3.14159265358979;
const float kValEpsilon = 1e-10;
const float kValMinCos = 0.05;
const float kValMinLobe = 1e-3;
const float kValMinDist2 = 1e-6;

struct Val {
  vec4 posArea;       // xyz centre, w area (m^2)
  vec4 normalWeight;  // xyz unit normal, w averaging weight
  vec4 flux;          // rgb W
};
struct Receiver {
  vec4 posExponent;   // xyz position, w Phong exponent
  vec4 normal;        // xyz unit normal
  vec4 view;          // xyz unit direction to the viewer
};
struct Vpl {
  vec4 Ld;            // rgb diffuse VPL, w occlusion factor (1 - o)
  vec4 ld;            // xyz position, w spread radius
  vec4 Ls;            // rgb glossy VPL, w occlusion factor
  vec4 ls;            // xyz position, w spread radius
};

// cos^k with cos^0 = 1 everywhere and 0 below the lobe (pow(0, 0) is undefined in GLSL).
float valPhongLobe(float c, float k) {
  if (k <= 0.0) return 1.0;
  if (c <= 0.0) return 0.0;
  return exp(k * log(c));
}

struct ValSums {
  vec3 E, S, ld, ls, ldSq, lsSq;
  float wd, ws;
};

ValSums valSumsZero() {
  ValSums s;
  s.E = s.S = s.ld = s.ls = s.ldSq = s.lsSq = vec3(0.0);
  s.wd = s.ws = 0.0;
  return s;
}

void valAccumulate(inout ValSums s, Receiver r, vec3 refl, Val v) {
  vec3 l = v.posArea.xyz;
  vec3 dir = l - r.posExponent.xyz;
  float dist2 = dot(dir, dir);
  vec3 w = dist2 > 0.0 ? dir / sqrt(dist2) : vec3(0.0);
  float cosI = max(dot(r.normal.xyz, w), 0.0);
  float cosJ = max(-dot(v.normalWeight.xyz, w), 0.0);
  float denom = kValPi * dist2 + v.posArea.w;
  float geo = denom > 0.0 ? cosJ / denom : 0.0;
  float lobe = cosI > 0.0 ? valPhongLobe(dot(refl, w), r.posExponent.w) : 0.0;
  s.E += v.flux.rgb * (geo * cosI);
  s.S += v.flux.rgb * (geo * lobe);
  float wd = kValEpsilon + v.normalWeight.w * geo * cosI;
  float ws = kValEpsilon + v.normalWeight.w * geo * lobe;
  s.ld += wd * l;
  s.wd += wd;
  s.ldSq += wd * l * l;
  s.ls += ws * l;
  s.ws += ws;
  s.lsSq += ws * l * l;
}

float valSpread(vec3 mean, vec3 sq, float w) {
  vec3 v = sq / w - mean * mean;
  return sqrt(max(max(max(v.x, v.y), v.z), 0.0));
}

Vpl valNormalize(ValSums s, Receiver r, vec3 refl) {
  Vpl v;
  vec3 x = r.posExponent.xyz, n = r.normal.xyz;
  v.ld.xyz = s.wd > 0.0 ? s.ld / s.wd : x + n;
  v.ls.xyz = s.ws > 0.0 ? s.ls / s.ws : x + n;
  v.ld.w = s.wd > 0.0 ? valSpread(v.ld.xyz, s.ldSq, s.wd) : 0.0;
  v.ls.w = s.ws > 0.0 ? valSpread(v.ls.xyz, s.lsSq, s.ws) : 0.0;
  vec3 dd = v.ld.xyz - x, ds = v.ls.xyz - x;
  float d2 = max(dot(dd, dd), kValMinDist2), s2 = max(dot(ds, ds), kValMinDist2);
  float lenD = sqrt(max(dot(dd, dd), 1e-30)), lenS = sqrt(max(dot(ds, ds), 1e-30));
  float cosD = max(dot(n, dd) / lenD, kValMinCos);
  float lobeS = max(valPhongLobe(dot(refl, ds) / lenS, r.posExponent.w), kValMinLobe);
  v.Ld = vec4(s.E * (d2 / cosD), 1.0);
  v.Ls = vec4(s.S * (s2 / lobeS), 1.0);
  return v;
}

// (E, S) of a VPL pair at a point (eq. 10).
void valEvaluate(Vpl v, vec3 x, vec3 n, vec3 view, float k, out vec3 E, out vec3 S) {
  vec3 dd = v.ld.xyz - x, ds = v.ls.xyz - x;
  float d2 = max(dot(dd, dd), kValMinDist2), s2 = max(dot(ds, ds), kValMinDist2);
  float lenD = sqrt(max(dot(dd, dd), 1e-30)), lenS = sqrt(max(dot(ds, ds), 1e-30));
  float cosD = max(dot(n, dd) / lenD, 0.0);
  float cosS = dot(n, ds) / lenS;
  vec3 refl = 2.0 * dot(n, view) * n - view;
  float lobe = cosS > 0.0 ? valPhongLobe(dot(refl, ds) / lenS, k) : 0.0;
  E = v.Ld.rgb * (cosD / d2);
  S = v.Ls.rgb * (lobe / s2);
}

#endif
