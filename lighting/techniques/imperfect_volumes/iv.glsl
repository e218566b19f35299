// Imperfect volumes: the GLSL twin of iv.h (grid, voxel records, march, reconstruction). Define SH_BANDS
// (1..8) before including.
#include "lighting/sh.glsl"
#include "lighting/ambient_sh.glsl"

// One voxel's record (std430; iv.h Volume): rgb = mean exitant radiance of its points, w = their count
// (rho: all points, mu: the real ones); normals: xyz = the sum of their unit normals; albedo: rgb mean.
struct IvVoxel {
  vec4 exitantRho;
  vec4 exitantMu;
  vec4 normalRho;
  vec4 normalMu;
  vec4 albedoRho;
  vec4 albedoMu;
  vec4 exitantMuLit;    // rgb: mean radiance of the real points as the objects leave them lit
  vec4 exitantVirtual;  // rgb: mean radiance the lights give the virtual points, w = their count
};

// A voxel's occupancy word (iv_inject.comp writes it beside the record): real points (exitantMu.w > 0),
// virtual points (exitantVirtual.w > 0), any points (exitantRho.w > 0).
const uint IV_REAL = 1u;
const uint IV_VIRTUAL = 2u;
const uint IV_ANY = 4u;



uniform vec3 uGridOrigin;
uniform float uVoxel;
uniform int uResolution;

// A grid's voxel index and the voxel holding p (false outside): iv.h Grid::index / voxelOf, for any grid.
int ivIndexIn(int resolution, ivec3 v) { return (v.z * resolution + v.y) * resolution + v.x; }
bool ivVoxelIn(vec3 origin, float voxel, int resolution, vec3 p, out ivec3 v) {
  vec3 u = (p - origin) / voxel;
  v = ivec3(0);
  if (any(lessThan(u, vec3(0.0))) || any(greaterThanEqual(u, vec3(float(resolution))))) return false;
  v = min(ivec3(u), ivec3(resolution - 1));
  return true;
}

int ivIndex(ivec3 v) { return ivIndexIn(uResolution, v); }
vec3 ivCentre(ivec3 v) { return uGridOrigin + uVoxel * (vec3(v) + 0.5); }
ivec3 ivCoords(int index) { return ivec3(index % uResolution, (index / uResolution) % uResolution, index / (uResolution * uResolution)); }
bool ivVoxelOf(vec3 p, out ivec3 v) { return ivVoxelIn(uGridOrigin, uVoxel, uResolution, p, v); }

// Irradiance about unit n of incident SH c: sum_l pi s_l(1) c_lm y_lm(n) (one channel).
float ivShIrradiance(float c[SH_COEFFS], vec3 n) {
  float y[SH_COEFFS];
  shEvaluate(n, y);
  float e = 0.0;
  for (int l = 0; l < SH_BANDS; ++l) {
    float f = SH_PI * shPhongFactor(1.0, l);
    for (int m = -l; m <= l; ++m) e += f * c[l * (l + 1) + m] * y[l * (l + 1) + m];
  }
  return e;
}

// The ambient's irradiance with nothing occluding it, as the shading pass adds it: pi * uniform + the SH
// part's clamped-cosine irradiance (iv.h unoccludedAmbient).
vec3 ivUnoccludedAmbient(vec3 ambient, vec3 sh[9], vec3 n) { return SH_PI * ambient + ambientShIrradiance(sh, n); }
