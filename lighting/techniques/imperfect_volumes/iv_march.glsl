// What a gather ray brings back: its march (iv_ray.glsl), kept by the hits pass, and the surfaces it meets.
#include "lighting/techniques/imperfect_volumes/iv_ray.glsl"

// The hits within range of voxel slot `slot`'s ray j from o along d (iv_ray.glsl ivHitsWithinRange): read
// from the hits pass's buffer (`hits`, declared by the includer with uCachedHits) or marched here.
ivec2 ivRayHits(int slot, int j, vec3 o, vec3 d) {
  return uCachedHits == 1 ? hits[slot * uRays + j] : ivHitsWithinRange(o, d);
}

// What the surfaces along a gather ray with hits h send towards its origin (iv.cpp rayRadiance, without the
// ambient): the first real voxel within range (uBounceLight), as the objects leave it lit in rho
// (exitantMuLit) or without them in mu (exitantMu), or in a later bounce what it reflects (ivReflectedAt:
// fromBuffer); in rho and the first bounce, plus what the first object voxel within range sends of the lights'
// light (the objects hide nothing). hit: a surface within range was met; open: no real one was, so the ambient
// of the direction arrives.
vec3 ivSurfaces(ivec2 h, vec3 d, bool rho, bool fromBuffer, out bool hit, out bool open) {
  int real = h.x, object = h.y;
  vec3 L = vec3(0.0);
  hit = rho && object >= 0;
  if (hit && uBounceLight == 1 && !fromBuffer) {
    vec3 n = voxels[object].normalRho.xyz - voxels[object].normalMu.xyz;
    if (dot(n, -d) > 0.0) L += voxels[object].exitantVirtual.rgb;
  }
  open = real < 0;
  if (!open) {
    hit = true;
    if (uBounceLight == 1 && dot(voxels[real].normalMu.xyz, -d) > 0.0)
      L += fromBuffer ? ivReflectedAt(real) : (rho ? voxels[real].exitantMuLit.rgb : voxels[real].exitantMu.rgb);
  }
  return L;
}
