// Direct light of the scene's lights at a surface point, with the shadow test against a light's shadow map
// (RSM world positions per light: layer i). Shared by the shading pass and techniques that light their own
// points (imperfect volumes); the C++ side sets the uniforms with lighting::setLightUniforms.
#ifndef MAX_LIGHTS
#define MAX_LIGHTS 16
#endif

uniform int uLightCount;
uniform int uLightType[MAX_LIGHTS];
uniform vec3 uLightPosition[MAX_LIGHTS];
uniform vec3 uLightDirection[MAX_LIGHTS];
uniform vec3 uLightPower[MAX_LIGHTS];
uniform float uSpotCos[MAX_LIGHTS];
uniform mat4 uLightViewProj[MAX_LIGHTS];
uniform float uShadowBias[MAX_LIGHTS];  // metres, distance tolerance of the shadow test

// Shadow-map test with a normal offset: the lookup point moves off the surface by the bias (about two map
// texels) along its normal, so surfaces near the terminator (depth slope ~ tan θ per texel) do not shadow
// themselves; the depth comparison keeps the same tolerance for the remaining slope.
float visibility(sampler2DArray map, int i, vec3 x, vec3 n) {
  x += n * max(uShadowBias[i], 0.0);
  vec4 c = uLightViewProj[i] * vec4(x, 1.0);
  if (c.w <= 0.0) return 1.0;
  vec3 ndc = c.xyz / c.w;
  if (any(greaterThan(abs(ndc.xy), vec2(1.0)))) return 1.0;  // outside the map: not occluded by the object
  vec4 s = texture(map, vec3(ndc.xy * 0.5 + 0.5, float(i)));
  if (s.w < 0.5) return 1.0;
  float dSelf, dOcc;
  if (uLightType[i] == 2) {
    dSelf = dot(x, uLightDirection[i]);
    dOcc = dot(s.xyz, uLightDirection[i]);
  } else {
    dSelf = distance(x, uLightPosition[i]);
    dOcc = distance(s.xyz, uLightPosition[i]);
  }
  return dOcc < dSelf - uShadowBias[i] ? 0.0 : 1.0;
}

vec3 directIrradiance(sampler2DArray map, vec3 x, vec3 n) {
  vec3 e = vec3(0.0);
  for (int i = 0; i < uLightCount; ++i) {
    vec3 contribution;
    if (uLightType[i] == 2) {
      contribution = uLightPower[i] * max(dot(n, -uLightDirection[i]), 0.0);
    } else {
      vec3 l = uLightPosition[i] - x;
      float d2 = max(dot(l, l), 1e-8);
      vec3 ln = l * inversesqrt(d2);
      if (uLightType[i] == 1 && dot(-ln, uLightDirection[i]) < uSpotCos[i]) continue;
      contribution = uLightPower[i] * max(dot(n, ln), 0.0) / d2;
    }
    if (any(greaterThan(contribution, vec3(0.0)))) e += contribution * visibility(map, i, x, n);
  }
  return e;
}
