// Imperfect volumes: a ray's march (iv.h marchSurfaces), for shaders that declare `occupancy` (uint[], the
// voxels' occupancy words) and uRange before including it (iv_march.glsl adds what a gather ray brings). From
// o past its voxel's bounding sphere, one voxel per step: the first voxel with real points (real = -1: none)
// and the first with virtual points up to it (object = -1: none), with their march distances.
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
    uint holds = occupancy[u];
    if (object < 0 && (holds & IV_VIRTUAL) != 0u) {
      object = u;
      tObject = t;
    }
    if ((holds & IV_REAL) != 0u) {
      real = u;
      tReal = t;
      return;
    }
  }
}

// The march's hits within range (uRange, declared by the includer): (first real voxel, first object voxel up
// to it), -1 where none.
ivec2 ivHitsWithinRange(vec3 o, vec3 d) {
  int real, object;
  float tReal, tObject;
  ivMarch(o, d, real, tReal, object, tObject);
  return ivec2(real >= 0 && tReal <= uRange ? real : -1, object >= 0 && tObject <= uRange ? object : -1);
}
