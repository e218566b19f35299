// Imperfect volumes: a gather ray's march (iv.h marchSurfaces), for shaders that declare `voxels` (IvVoxel[])
// before including it. From o past its voxel's bounding sphere, one voxel per step: the first voxel with real
// points (real = -1: none) and the first with virtual points up to it (object = -1: none), with their march
// distances. A voxel holds real points where exitantMu.w > 0 and virtual ones where exitantVirtual.w > 0.
void ivMarch(vec3 o, vec3 d, out int real, out float tReal, out int object, out float tObject) {
  float start = 0.5 * sqrt(3.0) * uVoxel;
  int maxSteps = int(ceil(sqrt(3.0) * float(uResolution))) + 1;
  real = object = -1;
  tReal = tObject = 0.0;
  for (int step = 0; step <= maxSteps; ++step) {
    float t = start + float(step) * uVoxel;
    ivec3 c;
    if (!ivVoxelOf(o + t * d, c)) return;
    int u = ivIndex(c);
    if (object < 0 && voxels[u].exitantVirtual.w > 0.0) {
      object = u;
      tObject = t;
    }
    if (voxels[u].exitantMu.w > 0.0) {
      real = u;
      tReal = t;
      return;
    }
  }
}

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
