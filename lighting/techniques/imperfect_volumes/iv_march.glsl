// What a gather ray brings back: its march (iv_ray.glsl) and the surfaces it meets.
#include "lighting/techniques/imperfect_volumes/iv_ray.glsl"

// What the surfaces along a gather ray send towards its origin (iv.cpp rayRadiance, without the ambient): the
// first real voxel within range (uBounceLight), as the objects leave it lit in rho (exitantMuLit) or without
// them in mu (exitantMu), or in a later bounce what it reflects (ivReflectedAt: fromBuffer); in rho and the
// first bounce, plus what the first object voxel within range sends of the lights' light (the objects hide
// nothing). hit: a surface within range was met; open: no real one was, so the ambient of the direction
// arrives.
vec3 ivSurfaces(vec3 o, vec3 d, bool rho, bool fromBuffer, out bool hit, out bool open) {
  int real, object;
  float tReal, tObject;
  ivMarch(o, d, real, tReal, object, tObject);
  vec3 L = vec3(0.0);
  hit = rho && object >= 0 && tObject <= uRange;
  if (hit && uBounceLight == 1 && !fromBuffer) {
    vec3 n = voxels[object].normalRho.xyz - voxels[object].normalMu.xyz;
    if (dot(n, -d) > 0.0) L += voxels[object].exitantVirtual.rgb;
  }
  open = !(real >= 0 && tReal <= uRange);
  if (!open) {
    hit = true;
    if (uBounceLight == 1 && dot(voxels[real].normalMu.xyz, -d) > 0.0)
      L += fromBuffer ? ivReflectedAt(real) : (rho ? voxels[real].exitantMuLit.rgb : voxels[real].exitantMu.rgb);
  }
  return L;
}
