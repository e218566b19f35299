// Light propagation volume math shared by injection, propagation and shading; C++ twin: lighting/techniques/dlpv/lpv.h.
// Two SH bands per colour channel, coefficient order (y00, y1-1, y10, y11) = (1, y, z, x) directions.
#define LPV_PI 3.14159265358979
const float kLpvY00 = 0.282094792;
const float kLpvY1 = 0.488602512;
const float kLpvCos0 = 0.886226925;  // sqrt(pi) / 2
const float kLpvCos1 = 1.023326708;  // sqrt(pi / 3)
const float kLpvFrontSolidAngle = 0.4006696846;
const float kLpvSideSolidAngle = 0.4234413544;
const float kLpvDirectLobeScale = 12.0 / 7.0;

vec4 lpvBasis(vec3 d) { return vec4(kLpvY00, kLpvY1 * d.y, kLpvY1 * d.z, kLpvY1 * d.x); }
vec4 lpvCosineLobe(vec3 n) { return vec4(kLpvCos0, kLpvCos1 * n.y, kLpvCos1 * n.z, kLpvCos1 * n.x); }

// Directional damping (lpv.h dampingFactor): flux leaving towards d is reduced where the cell's lobe is
// directional and d leaves its forward hemisphere sideways or backwards.
float lpvDamping(vec4 c, vec3 d, float damping) {
  if (damping <= 0.0) return 1.0;
  vec3 c1 = vec3(c.w, c.y, c.z);
  float len1 = length(c1);
  float c0 = abs(c.x);
  if (len1 <= 0.0 || c0 <= 0.0) return 1.0;
  float r = min(1.0, 0.8660254 * len1 / c0);
  vec3 m = c1 * ((c.x >= 0.0 ? 1.0 : -1.0) / len1);
  return 1.0 - damping * r * (1.0 - max(0.0, dot(d, m)));
}

struct LpvGrid {
  vec3 origin;
  float cellSize;
  int resolution;
};

// Irradiance at a surface point (lpv.h irradianceReference): trilinear SH half a cell along n, 0 outside.
vec3 lpvIrradiance(sampler3D r, sampler3D g, sampler3D b, LpvGrid grid, vec3 position, vec3 n) {
  vec3 p = position + n * (0.5 * grid.cellSize);
  vec3 uvw = (p - grid.origin) / (grid.cellSize * float(grid.resolution));
  if (any(lessThan(uvw, vec3(0.0))) || any(greaterThan(uvw, vec3(1.0)))) return vec3(0.0);
  vec4 y = lpvBasis(-n);
  vec4 a = vec4(LPV_PI, 2.0 * LPV_PI / 3.0, 2.0 * LPV_PI / 3.0, 2.0 * LPV_PI / 3.0) * y;
  float inv = 1.0 / (grid.cellSize * grid.cellSize);
  return inv * vec3(dot(texture(r, uvw), a), dot(texture(g, uvw), a), dot(texture(b, uvw), a));
}
