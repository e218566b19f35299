#version 450 core
// Occlusion of each sparse point's VPLs by the other sparse points as discs (§3.3; val.cpp occlusion()).
#include "lighting/techniques/kinect_val/val.glsl"
layout(local_size_x = 64) in;

struct Occluder {
  vec4 posRadius;  // xyz world position, w disc radius
  vec4 normal;
};
layout(std430, binding = 0) readonly buffer Occluders { Occluder occ[]; };
layout(std430, binding = 1) readonly buffer VplsIn { Vpl vin[]; };
layout(std430, binding = 2) writeonly buffer VplsOut { Vpl vout[]; };
uniform int uCount;

float occlusion(int i, vec3 c, float R) {
  vec3 x = occ[i].posRadius.xyz, n = occ[i].normal.xyz;
  vec3 toL = c - x;
  float dl = sqrt(dot(toL, toL));
  if (!(dl > 0.0)) return 0.0;
  vec3 wl = toL / dl;
  float cosL = dot(n, wl);
  if (cosL <= 0.0) return 0.0;
  vec3 t = abs(n.x) < 0.9 ? normalize(cross(n, vec3(1, 0, 0))) : normalize(cross(n, vec3(0, 1, 0)));
  vec3 b = cross(n, t);
  float Rs = max(R, 1e-6);
  float areaL = kValPi * Rs * Rs * cosL / (dl * dl + Rs * Rs);
  float hl = 0.5 * sqrt(areaL);
  vec2 lc = vec2(dot(wl, t), dot(wl, b));
  float covered = 0.0;
  for (int k = 0; k < uCount; ++k) {
    if (k == i) continue;
    vec3 toO = occ[k].posRadius.xyz - x;
    float d2 = dot(toO, toO);
    if (!(d2 > 0.0)) continue;
    float dk = sqrt(d2);
    vec3 wo = toO / dk;
    float cosX = dot(n, wo);
    if (cosX <= 0.0 || dk >= dl) continue;
    float fade = min((dl - dk) / Rs, 1.0);
    float rk = occ[k].posRadius.w;
    float a = kValPi * rk * rk;
    float areaO = kValPi * a * abs(dot(occ[k].normal.xyz, wo)) * cosX / (kValPi * d2 + a);
    float ho = 0.5 * sqrt(areaO);
    vec2 oc = vec2(dot(wo, t), dot(wo, b));
    float w = max(0.0, min(lc.x + hl, oc.x + ho) - max(lc.x - hl, oc.x - ho));
    float h = max(0.0, min(lc.y + hl, oc.y + ho) - max(lc.y - hl, oc.y - ho));
    covered += w * h * fade;
  }
  return areaL > 0.0 ? min(covered / areaL, 1.0) : 0.0;
}

void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= uCount) return;
  Vpl v = vin[i];
  float od = 1.0 - occlusion(i, v.ld.xyz, v.ld.w);
  float os = 1.0 - occlusion(i, v.ls.xyz, v.ls.w);
  v.Ld = vec4(v.Ld.rgb * od, od);
  v.Ls = vec4(v.Ls.rgb * os, os);
  vout[i] = v;
}
