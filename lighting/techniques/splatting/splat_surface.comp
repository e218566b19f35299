#version 450 core
// Splatting, the surface lights (splat.h surfaceLight): each point on the objects' surfaces gathers the
// object's pixel lights (the real surfaces' bounce and the ambient they block, unbounded) and the ambient
// about its normal and about the opposite one, and becomes a diffuse light of flux
// A (albedo E(x, n) - E(x, -n)): the object's second bounce, minus what it hides from the surfaces in front.
#include "lighting/techniques/splatting/splat.glsl"
#include "lighting/ambient_sh.glsl"
layout(local_size_x = 64) in;

struct SurfacePoint {
  vec4 positionArea;
  vec4 normal;
  vec4 albedo;
};
layout(std430, binding = 2) readonly buffer ObjectLights { PixelLight objectLights[]; };
layout(std430, binding = 3) readonly buffer Points { SurfacePoint points[]; };
layout(std430, binding = 4) writeonly buffer SurfaceLights { PixelLight lights[]; };

uniform int uCount;         // surface points
uniform int uObjectLights;  // the object's pixel lights
uniform vec3 uAmbient;
uniform vec3 uAmbientSh[9];

vec3 ambientIrradiance(vec3 n) { return SPLAT_PI * uAmbient + ambientShIrradiance(uAmbientSh, n); }

void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= uCount) return;
  SurfacePoint s = points[i];
  vec3 x = s.positionArea.xyz, n = s.normal.xyz;
  vec3 front = ambientIrradiance(n), back = ambientIrradiance(-n);
  for (int j = 0; j < uObjectLights; ++j) {
    front += splatIrradiance(objectLights[j], x, n);
    back += splatIrradiance(objectLights[j], x, -n);
  }
  PixelLight l;
  l.positionArea = s.positionArea;
  l.normalExponent = vec4(n, 0.0);
  vec3 f = s.positionArea.w * (s.albedo.rgb * front - back);
  l.fluxWiden = vec4((any(isnan(f)) || any(isinf(f))) ? vec3(0.0) : f, 0.0);
  l.axis = vec4(n, 0.0);
  lights[i] = l;
}
