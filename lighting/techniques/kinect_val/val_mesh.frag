#version 450 core
// Kinect-VAL per-pixel evaluation (eq. 10) of the interpolated VPL pair on the virtual object:
//   out 0: indirect radiance  albedo/pi * E + specular * (k+1)/(2 pi) * S, a = 1
//   out 1: E (W/m^2), a = 1
#include "lighting/techniques/kinect_val/val.glsl"
in vec3 vPosition;
in vec3 vNormal;
in vec3 vAlbedo;
in vec4 vLd, vld, vLs, vls;
uniform vec3 uEye;
uniform vec3 uSpecular;
uniform float uExponent;

layout(location = 0) out vec4 outRadiance;
layout(location = 1) out vec4 outIrradiance;

void main() {
  vec3 view = normalize(uEye - vPosition);
  vec3 n = dot(vNormal, vNormal) > 1e-20 ? normalize(vNormal) : view;
  if (dot(n, view) < 0.0) n = -n;
  Vpl v = Vpl(vLd, vld, vLs, vls);
  vec3 E, S;
  valEvaluate(v, vPosition, n, view, uExponent, E, S);
  outRadiance = vec4(vAlbedo * E / kValPi + uSpecular * S * ((uExponent + 1.0) / (2.0 * kValPi)), 1.0);
  outIrradiance = vec4(E, 1.0);
}
