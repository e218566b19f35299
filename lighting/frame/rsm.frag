#version 450 core
// Reflective shadow map texel (algorithms.md §2): position, normal facing the light, reflected flux
// albedo * Phi_t and the flux Phi_t the light sends through this texel.
//   point/spot (perspective, focal f pixels): Phi_t = I * dOmega, dOmega = 1 / (f^2 |d|^3), d = ((u-c)/f, (v-c)/f, 1)
//   directional (orthographic): Phi_t = E * texelArea
in vec3 vPosition;
in vec3 vNormal;
in vec3 vAlbedo;
uniform int uLightType;        // 0 point, 1 spot, 2 directional
uniform vec3 uLightPosition;   // world
uniform vec3 uLightDirection;  // spot axis / directional travel direction, unit
uniform vec3 uLightPower;      // intensity (W/sr) or irradiance (W/m^2)
uniform float uSpotCos;        // cos of the spot half angle
uniform float uFocal;          // perspective focal length, pixels
uniform float uCentre;         // principal point (= size / 2), pixels
uniform float uTexelArea;      // orthographic texel footprint, m^2
uniform float uObject;  // 0 for the real mesh, 1 + index for a virtual object

layout(location = 0) out vec4 outPosition;
layout(location = 1) out vec4 outNormal;  // w = object index + 1 on virtual surfaces, 0 on real ones
layout(location = 2) out vec4 outFlux;
layout(location = 3) out vec4 outDirect;

void main() {
  vec3 toLight = uLightType == 2 ? -uLightDirection : uLightPosition - vPosition;
  // A degenerate interpolated normal (opposite vertex normals) faces the light instead of becoming NaN.
  vec3 n = dot(vNormal, vNormal) > 1e-20 ? normalize(vNormal) : normalize(toLight);
  if (dot(n, toLight) < 0.0) n = -n;
  vec3 phi;
  if (uLightType == 2) {
    phi = uLightPower * uTexelArea;
  } else {
    vec3 d = vec3((gl_FragCoord.xy - vec2(uCentre)) / uFocal, 1.0);
    float len = length(d);
    phi = uLightPower / (uFocal * uFocal * len * len * len);
    if (uLightType == 1 && dot(normalize(vPosition - uLightPosition), uLightDirection) < uSpotCos) phi = vec3(0.0);
  }
  outPosition = vec4(vPosition, 1.0);
  outNormal = vec4(n, uObject);
  outFlux = vec4(vAlbedo * phi, 1.0);
  outDirect = vec4(phi, 1.0);
}
