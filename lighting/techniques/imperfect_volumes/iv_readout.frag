#version 450 core
// Imperfect volumes' outputs for the shared shading pass (iv.h irradiance, the reconstruction): per G-buffer
// pixel at x with normal n, p = x + n voxel / 2; of the 27 voxels around p the six nearest to p that were
// gathered, lie in front of x (cos theta > 0) and are not x's own voxel, free ones only when there are any,
// weighted by cos theta; the irradiance of the weighted incident SH about n.
//   out 0, real pixels (uReal):       E_delta = E^rho - E^mu
//   out 1, virtual pixels (uVirtual): E^mu minus the unoccluded ambient the shading pass adds itself: the
//                                     ambient the real surfaces hide from the object and their bounce (the
//                                     object's own voxels neither occlude nor light it: a surface of voxels
//                                     next to a curved object hides far more of its sky than the object does)
//                                     With uObjectRays > 0 the object's pixels cast their own rays through the
//                                     mu volume instead (iv.h pointGather): no SH band limit, no voxel offset;
//                                     past the grid they go on through the coarser outer volume.
#include "lighting/techniques/imperfect_volumes/iv.glsl"

layout(binding = 0) uniform sampler2D uGPosition;
layout(binding = 1) uniform sampler2D uGNormal;
layout(binding = 2) uniform sampler2D uGAlbedo;

layout(std430, binding = 2) readonly buffer Voxels { IvVoxel voxels[]; };
layout(std430, binding = 14) readonly buffer Occupancy { uint occupancy[]; };  // iv.glsl IV_REAL ...
layout(std430, binding = 5) readonly buffer IncidentRho { float incidentRho[]; };
layout(std430, binding = 9) readonly buffer IncidentMu { float incidentMu[]; };
layout(std430, binding = 10) readonly buffer Computed { uint computed[]; };  // 1 per voxel whose rays were cast
// The object's own rays (uObjectRays > 0; iv.h pointGather): their directions, and what the mu voxels
// reflect of bounces 1 .. B-1 (uReflectedOn).
layout(std430, binding = 4) readonly buffer ObjectDirections { vec4 objectDirections[]; };
layout(std430, binding = 11) readonly buffer ReflectedSumMu { vec4 reflectedSumMu[]; };
layout(std430, binding = 12) readonly buffer Hidden { vec4 hidden[]; };  // iv_hidden.comp
// The coarser outer volume the object's rays continue in past the grid (iv.h outerGrid; uOuterResolution 0: none).
layout(std430, binding = 13) readonly buffer OuterVoxels { IvVoxel outerVoxels[]; };
layout(std430, binding = 15) readonly buffer OuterOccupancy { uint outerOccupancy[]; };
uniform vec3 uOuterOrigin;
uniform float uOuterVoxel;
uniform int uOuterResolution;
uniform int uObjectRays;
uniform float uRange;
uniform int uBounceLight;  // 0: surfaces send nothing (bounces 0)
uniform int uReflectedOn;

uniform int uReal;
uniform int uVirtual;
uniform vec3 uAmbient;
uniform vec3 uAmbientSh[9];

layout(location = 0) out vec4 outRealDelta;
layout(location = 1) out vec4 outVirtualIrradiance;

// The voxels reconstruction reads and their weights (count 0: none qualifies).
int chosen[6];
float weight[6];
int chooseVoxels(vec3 x, vec3 n) {
  vec3 p = x + 0.5 * uVoxel * n;
  ivec3 own = ivec3(-1), centre;
  ivVoxelOf(x, own);
  if (!ivVoxelOf(p, centre)) return 0;
  bool anyFree = false;
  for (int pass = 0; pass < 2; ++pass) {
    // Pass 0 looks for a free candidate; pass 1 keeps the six nearest (free ones only if any).
    int count = 0;
    float d2s[6];
    for (int dk = -1; dk <= 1; ++dk)
      for (int dj = -1; dj <= 1; ++dj)
        for (int di = -1; di <= 1; ++di) {
          ivec3 c = centre + ivec3(di, dj, dk);
          if (c == own || any(lessThan(c, ivec3(0))) || any(greaterThanEqual(c, ivec3(uResolution)))) continue;
          int v = ivIndex(c);
          if (computed[v] == 0u) continue;
          vec3 q = ivCentre(c);
          vec3 to = q - x;
          float len = length(to);
          float cosT = len > 0.0 ? dot(n, to) / len : 0.0;
          if (!(cosT > 0.0)) continue;
          bool occupied = (occupancy[v] & IV_ANY) != 0u;
          if (pass == 0) {
            anyFree = anyFree || !occupied;
            continue;
          }
          if (anyFree && occupied) continue;
          float d2 = dot(q - p, q - p);
          // Insert into the sorted six (by distance, then index, as the C++ partial sort).
          int at = count < 6 ? count : 6;
          while (at > 0 && (d2s[at - 1] > d2 || (d2s[at - 1] == d2 && chosen[at - 1] > v))) {
            if (at < 6) {
              d2s[at] = d2s[at - 1];
              chosen[at] = chosen[at - 1];
              weight[at] = weight[at - 1];
            }
            --at;
          }
          if (at < 6) {
            d2s[at] = d2;
            chosen[at] = v;
            weight[at] = cosT;
            count = min(count + 1, 6);
          }
        }
    if (pass == 1) return count;
  }
  return 0;
}

// The irradiance about n of the weighted incident SH of the scene versions asked for: the basis and the
// clamped cosine's band factors evaluated once.
void reconstruct(int count, vec3 n, bool rho, bool mu, out vec3 eRho, out vec3 eMu) {
  float y[SH_COEFFS];
  shEvaluate(n, y);
  float f[SH_COEFFS];
  for (int l = 0; l < SH_BANDS; ++l) {
    float a = SH_PI * shPhongFactor(1.0, l);
    for (int m = -l; m <= l; ++m) f[l * (l + 1) + m] = a * y[l * (l + 1) + m];
  }
  float wsum = 0.0;
  for (int k = 0; k < count; ++k) wsum += weight[k];
  eRho = vec3(0.0);
  eMu = vec3(0.0);
  for (int k = 0; k < count; ++k) {
    float w = weight[k] / wsum;
    for (int ch = 0; ch < 3; ++ch) {
      int base = (chosen[k] * 3 + ch) * SH_COEFFS;
      float r = 0.0, u = 0.0;
      for (int q = 0; q < SH_COEFFS; ++q) {
        if (rho) r += f[q] * incidentRho[base + q];
        if (mu) u += f[q] * incidentMu[base + q];
      }
      eRho[ch] += w * r;
      eMu[ch] += w * u;
    }
  }
}

// iv.h marchFromPoint: samples at (k + 1/2) voxel from x, x's own voxel skipped, the mu occupancy; tExit: the
// first sample outside the grid.
int marchFromPoint(vec3 x, vec3 d, out float t, out float tExit) {
  ivec3 own = ivec3(-1);
  ivVoxelOf(x, own);
  tExit = 0.0;
  int maxSteps = int(ceil(sqrt(3.0) * float(uResolution))) + 1;
  for (int step = 0; step <= maxSteps; ++step) {
    t = (float(step) + 0.5) * uVoxel;
    ivec3 c;
    if (!ivVoxelOf(x + t * d, c)) {
      tExit = t;
      return -1;
    }
    if (c == own) continue;
    int v = ivIndex(c);
    if ((occupancy[v] & IV_REAL) != 0u) return v;
  }
  return -1;
}

bool outerVoxelOf(vec3 p, out ivec3 v) { return ivVoxelIn(uOuterOrigin, uOuterVoxel, uOuterResolution, p, v); }

// iv.h marchOuter: samples at from + k outer voxels, x's own outer voxel skipped, the real occupancy.
int marchOuter(vec3 x, vec3 d, float from, out float t) {
  ivec3 own = ivec3(-1);
  outerVoxelOf(x, own);
  int maxSteps = int(ceil(sqrt(3.0) * float(uOuterResolution))) + 1;
  for (int step = 0; step <= maxSteps; ++step) {
    t = from + float(step) * uOuterVoxel;
    ivec3 c;
    if (!outerVoxelOf(x + t * d, c)) return -1;
    if (c == own) continue;
    int v = ivIndexIn(uOuterResolution, c);
    if ((outerOccupancy[v] & IV_REAL) != 0u) return v;
  }
  return -1;
}

// What mu voxel v's surface sends towards -d (iv.cpp pointGather's `sends`); false where it does not face the ray.
bool surfaceSends(int v, vec3 d, out vec3 L) {
  L = vec3(0.0);
  if (!(dot(voxels[v].normalMu.xyz, -d) > 0.0)) return false;
  if (uBounceLight == 1) L = max(voxels[v].exitantMuLit.rgb - voxels[v].albedoMu.rgb / SH_PI * hidden[v].rgb, vec3(0.0));
  if (uReflectedOn == 1) L += reflectedSumMu[v].rgb;
  return true;
}

// iv.h pointGather over the mu volume (and the outer one past it): the change against the unoccluded ambient.
vec3 pointGather(vec3 x, vec3 n) {
  vec3 change = vec3(0.0);
  for (int j = 0; j < uObjectRays; ++j) {
    vec3 d = objectDirections[j].xyz;
    float c = dot(n, d);
    if (!(c > 0.0)) continue;
    float t, tExit;
    int h = marchFromPoint(x, d, t, tExit);
    if (h < 0 && uOuterResolution > 0 && tExit <= uRange) {
      int o = marchOuter(x, d, tExit, t);
      if (o < 0 || t > uRange) continue;
      vec3 L = vec3(0.0);
      if (dot(outerVoxels[o].normalMu.xyz, -d) > 0.0 && uBounceLight == 1) L = outerVoxels[o].exitantMuLit.rgb;
      change += (L - ambientRadiance(uAmbient, uAmbientSh, d)) * c;
      continue;
    }
    if (h < 0 || t > uRange) continue;
    // The surface's light at the hit, trilinear between the occupied voxels around it that face the ray.
    vec3 q = (x + t * d - uGridOrigin) / uVoxel - vec3(0.5);
    ivec3 base = ivec3(floor(q));
    vec3 f = q - vec3(base);
    vec3 sum = vec3(0.0), L = vec3(0.0);
    float wSum = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
      ivec3 k = base + ivec3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
      if (any(lessThan(k, ivec3(0))) || any(greaterThanEqual(k, ivec3(uResolution)))) continue;
      int v = ivIndex(k);
      vec3 Lv;
      if ((occupancy[v] & IV_REAL) == 0u || !surfaceSends(v, d, Lv)) continue;
      float w = ((corner & 1) != 0 ? f.x : 1.0 - f.x) * ((corner & 2) != 0 ? f.y : 1.0 - f.y) * ((corner & 4) != 0 ? f.z : 1.0 - f.z);
      sum += w * Lv;
      wSum += w;
    }
    if (wSum > 1e-6)
      L = sum / wSum;
    else if (!surfaceSends(h, d, L))
      L = vec3(0.0);
    change += (L - ambientRadiance(uAmbient, uAmbientSh, d)) * c;
  }
  return change * (4.0 * SH_PI / float(max(uObjectRays, 1)));
}

void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  outRealDelta = vec4(0.0);
  outVirtualIrradiance = vec4(0.0);
  vec4 pos = texelFetch(uGPosition, px, 0);
  if (pos.w < 0.5) return;
  vec3 n = texelFetch(uGNormal, px, 0).xyz;
  bool isVirtual = texelFetch(uGAlbedo, px, 0).a > 0.5;
  if (isVirtual && uVirtual == 1 && uObjectRays > 0) {
    outVirtualIrradiance = vec4(pointGather(pos.xyz, n), 0.0);
    return;
  }
  int count = chooseVoxels(pos.xyz, n);
  if (count == 0) return;
  vec3 eRho, eMu;
  if (isVirtual) {
    if (uVirtual == 0) return;
    reconstruct(count, n, false, true, eRho, eMu);
    outVirtualIrradiance = vec4(eMu - ivUnoccludedAmbient(uAmbient, uAmbientSh, n), 0.0);
  } else if (uReal == 1) {
    reconstruct(count, n, true, true, eRho, eMu);
    outRealDelta = vec4(eRho - eMu, 0.0);
  }
}
