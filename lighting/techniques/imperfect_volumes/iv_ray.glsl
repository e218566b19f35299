// Imperfect volumes: a ray's march (iv.h marchSurfaces), for shaders that declare `voxels` (IvVoxel[])
// before including it (iv_march.glsl adds what a gather ray brings). From o past its voxel's bounding sphere,
// one voxel per step: the first voxel with real points (real = -1: none) and the first with virtual points up
// to it (object = -1: none), with their march distances. A voxel holds real points where exitantMu.w > 0 and virtual ones where exitantVirtual.w > 0.
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
