#version 450 core
// DLPV's outputs for the shared shading pass (algorithms.md §3): per G-buffer pixel the irradiance read from
// the volumes (lpv.glsl lpvIrradiance; C++ twin lpv.h irradianceReference).
//   out 0, real pixels (uReal):       E_delta = V^delta, or V^rho - V^mu for the naive difference
//   out 1, virtual pixels (uVirtual): E_indirect = max(V^rho, 0) (bounce light on the virtual object)
// Everything else 0.
#include "lighting/techniques/dlpv/lpv.glsl"

layout(binding = 0) uniform sampler2D uGPosition;
layout(binding = 1) uniform sampler2D uGNormal;
layout(binding = 2) uniform sampler2D uGAlbedo;
layout(binding = 3) uniform sampler3D uDeltaR;  // V^delta, or V^rho (direct + indirect) for the naive difference
layout(binding = 4) uniform sampler3D uDeltaG;
layout(binding = 5) uniform sampler3D uDeltaB;
layout(binding = 6) uniform sampler3D uMuR;     // naive difference only: V^mu, subtracted
layout(binding = 7) uniform sampler3D uMuG;
layout(binding = 8) uniform sampler3D uMuB;
layout(binding = 9) uniform sampler3D uRhoR;    // V^rho, indirect only
layout(binding = 10) uniform sampler3D uRhoG;
layout(binding = 11) uniform sampler3D uRhoB;

uniform vec3 uGridOrigin;
uniform float uCellSize;
uniform int uResolution;
uniform int uReal;        // 1: this technique serves real pixels
uniform int uVirtual;     // 1: this technique serves the virtual object
uniform int uDifference;  // 1: the naive two-volume difference

layout(location = 0) out vec4 outRealDelta;
layout(location = 1) out vec4 outVirtualIrradiance;

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  outRealDelta = vec4(0.0);
  outVirtualIrradiance = vec4(0.0);
  vec4 pos = texelFetch(uGPosition, p, 0);
  if (pos.w < 0.5) return;
  vec3 n = texelFetch(uGNormal, p, 0).xyz;
  bool isVirtual = texelFetch(uGAlbedo, p, 0).a > 0.5;
  LpvGrid grid = LpvGrid(uGridOrigin, uCellSize, uResolution);
  if (isVirtual) {
    if (uVirtual == 1) outVirtualIrradiance = vec4(max(lpvIrradiance(uRhoR, uRhoG, uRhoB, grid, pos.xyz, n), vec3(0.0)), 0.0);
  } else if (uReal == 1) {
    vec3 delta = lpvIrradiance(uDeltaR, uDeltaG, uDeltaB, grid, pos.xyz, n);
    if (uDifference == 1) delta -= lpvIrradiance(uMuR, uMuG, uMuB, grid, pos.xyz, n);
    outRealDelta = vec4(delta, 0.0);
  }
}
