// The objects' shadow of the ambient on real surfaces and the lights they reflect onto them
// (lighting/object_shadow.h is the C++ twin): each object a sphere, its view factor from the surface element
// times the ambient's radiance towards its centre less what the sphere reflects of the ambient back along it,
// the total within +- the ambient's irradiance. Needs lighting/ambient_sh.glsl and lighting/radiance_map.glsl.
#define MAX_OCCLUDERS 16

uniform int uOccluderCount;
uniform vec4 uOccluders[MAX_OCCLUDERS];  // xyz centre (lighting world), w radius; object_shadow.h occluderSphere
uniform vec3 uOccluderAlbedo[MAX_OCCLUDERS];  // diffuse albedo of what each reflects of the ambient

#define OBJECTS_MIN_VIEW_FACTOR 1e-3  // lighting::kObjectsMinViewFactor: a sphere seen less adds nothing

#include "lighting/view_factor.glsl"

float sphereViewFactor(vec3 x, vec3 n, vec4 s) {
  vec3 d = s.xyz - x;
  float dist = length(d), r = s.w;
  if (!(r > 0.0)) return 0.0;
  if (dist <= r) return 1.0;
  return sphereViewFactorH(dist / r, dot(n, d) / dist);
}

// Whether any sphere reaches (x, n): seen at a view factor of at least OBJECTS_MIN_VIEW_FACTOR. Where none
// does, what the spheres hide and reflect is exactly zero.
bool objectsSeen(vec3 x, vec3 n) {
  for (int i = 0; i < uOccluderCount && i < MAX_OCCLUDERS; ++i)
    if (sphereViewFactor(x, n, uOccluders[i]) >= OBJECTS_MIN_VIEW_FACTOR) return true;
  return false;
}

// What the spheres hide from (x, n) of a light (uniform part and SH bands 1-2), and what they would reflect of
// it towards x were their surroundings unshadowed (each: its view factor times the radiance along its centre).
// With `throughMap`, `mapped` is what they hide of the same light held sharper than its SH bands, a lat-long
// radiance map (lighting/radiance_map.glsl): each view factor times pi times the map's mean radiance over the cap
// the sphere covers, cosine-weighted about n (lighting::ambientShadow's; zero without).
void ambientShadowParts(vec3 uniformPart, vec3 sh[9], vec3 x, vec3 n, bool throughMap, sampler2D map,
                        out vec3 hides, out vec3 mapped, out vec3 reflects) {
  const float pi = 3.14159265358979;
  hides = vec3(0.0);
  mapped = vec3(0.0);
  reflects = vec3(0.0);
  float texel = 0.0, maxLevel = 0.0;
  if (throughMap) {
    texel = radianceMapTexel(map);
    maxLevel = float(textureQueryLevels(map) - 1);
  }
  for (int i = 0; i < uOccluderCount && i < MAX_OCCLUDERS; ++i) {
    float f = sphereViewFactor(x, n, uOccluders[i]);
    if (!(f >= OBJECTS_MIN_VIEW_FACTOR)) continue;
    vec3 d = uOccluders[i].xyz - x;
    float len = length(d), r = uOccluders[i].w;
    vec3 w = len > 0.0 ? d / len : n;
    hides += pi * f * ambientRadiance(uniformPart, sh, w);
    reflects += f * uOccluderAlbedo[i] * ambientIrradiance(uniformPart, sh, -w);
    if (throughMap) {
      // The cap's half-angle alpha: sin alpha = r / distance, 1 - cos alpha without cancellation.
      float sinA = len > r ? r / len : 1.0;
      float oneMinusCos = sinA * sinA / (1.0 + sqrt(max(0.0, 1.0 - sinA * sinA)));
      mapped += pi * f * radianceMapCapMean(map, texel, maxLevel, w, oneMinusCos, n);
    }
  }
}

// The fraction of its light (x, n) keeps beside the objects (lighting::litFraction): the direct light with
// them over without, the hidden light (irradiance `full` about n) less what the spheres hide of it.
vec3 litFraction(vec3 full, vec3 hides, vec3 directWithout, vec3 directWith) {
  vec3 v = (directWith + full - clamp(hides, vec3(0.0), full)) / max(directWithout + full, vec3(1e-6));
  return (any(isnan(v)) || any(isinf(v))) ? vec3(1.0) : clamp(v, 0.0, 1.0);
}

// The ground under the face of the sphere x sees most, turned towards x (lighting::facedGround): the foot of
// its centre on x's plane; `weight` = sin^2 of the angle under the plane from the centre to x.
vec3 facedGround(vec3 x, vec3 n, out float weight) {
  float best = 0.0;
  vec3 ground = x;
  weight = 0.0;
  for (int i = 0; i < uOccluderCount && i < MAX_OCCLUDERS; ++i) {
    float f = sphereViewFactor(x, n, uOccluders[i]);
    if (!(f > best)) continue;
    best = f;
    vec3 toX = x - uOccluders[i].xyz;
    float dist = length(toX);
    float sinB = dist > 0.0 ? clamp(-dot(toX, n) / dist, 0.0, 1.0) : 1.0;
    weight = isnan(sinB) ? 0.0 : sinB * sinB;
    ground = uOccluders[i].xyz - dot(uOccluders[i].xyz - x, n) * n;
  }
  return ground;
}

// The irradiance the objects take from (x, n) under a light of irradiance `full` about n, net of what they
// reflect of it (> 0: subtract it; lighting::ambientShadow), what they reflect lit as x's surroundings and the
// ground under them are (blendLit).
vec3 ambientShadow(vec3 full, vec3 hides, vec3 reflects, vec3 lit) {
  vec3 e = clamp(hides - lit * reflects, -full, full);
  return (any(isnan(e)) || any(isinf(e))) ? vec3(0.0) : e;
}

// What the objects reflect of the lights towards (x, n) (lighting::reflectedLight is the C++ twin): each
// sphere's Lambertian radiance albedo E(p, m) / pi over REFLECTION_SAMPLES equal-area points of its half facing
// x, averaged with the form factor of those x sees above its horizon, times the sphere's view factor. A light
// counts where it lights the sphere's point facing it (spot cone) and the real scene's map sees that point.
// Needs lighting/direct_light.glsl.
#define REFLECTION_SAMPLES 16  // lighting::kReflectionSamples
vec3 reflectionSample(int k) {
  float z = 1.0 - (float(k) + 0.5) / float(REFLECTION_SAMPLES);
  float rho = sqrt(max(0.0, 1.0 - z * z)), phi = 2.399963229728653 * float(k);
  return vec3(rho * cos(phi), rho * sin(phi), z);
}

vec3 reflectedLight(vec3 x, vec3 n) {
  vec3 e = vec3(0.0);
  for (int i = 0; i < uOccluderCount && i < MAX_OCCLUDERS; ++i) {
    vec4 s = uOccluders[i];
    float f = sphereViewFactor(x, n, s);
    if (!(f >= OBJECTS_MIN_VIEW_FACTOR) || all(equal(uOccluderAlbedo[i], vec3(0.0)))) continue;
    vec3 toX = x - s.xyz;
    float dist = length(toX);
    if (!(dist > 0.0)) continue;
    vec3 v = toX / dist;
    vec3 t = normalize(cross(v, abs(v.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
    vec3 b = cross(v, t);
    // The form-factor weights of the samples do not depend on the light: their sum first.
    float weights = 0.0;
    for (int k = 0; k < REFLECTION_SAMPLES; ++k) {
      vec3 h = reflectionSample(k), m = h.x * t + h.y * b + h.z * v;
      vec3 d = x - (s.xyz + s.w * m);
      float r2 = dot(d, d);
      weights += r2 > 0.0 ? max(0.0, dot(m, d)) * max(0.0, -dot(n, d)) / (r2 * r2) : 0.0;
    }
    if (!(weights > 0.0)) continue;
    for (int j = 0; j < uLightCount && j < MAX_LIGHTS; ++j) {
      bool directional = uLightType[j] == 2;
      vec3 l = directional ? -uLightDirection[j] : normalize(uLightPosition[j] - s.xyz);
      vec3 facing = s.xyz + s.w * l;
      // At normal incidence on the point facing the light: its spot cone, and whether the real scene hides it.
      if (!any(greaterThan(unshadowedIrradiance(j, facing, l), vec3(0.0)))) continue;
      if (shadowTest(uShadowMu, j, uLightViewProj[j], uShadowBias[j], facing, l) <= 0.0) continue;
      // sum_k w_k (E_j(p_k, m_k) / the light's power): each sample's own direction and distance to a lamp.
      float lit = 0.0;
      for (int k = 0; k < REFLECTION_SAMPLES; ++k) {
        vec3 h = reflectionSample(k), m = h.x * t + h.y * b + h.z * v, p = s.xyz + s.w * m;
        vec3 toLight = directional ? l : uLightPosition[j] - p;
        float c = directional ? dot(m, l) : dot(m, toLight) / pow(max(dot(toLight, toLight), 1e-8), 1.5);
        if (!(c > 0.0)) continue;
        vec3 d = x - p;
        float r2 = dot(d, d);
        lit += r2 > 0.0 ? c * max(0.0, dot(m, d)) * max(0.0, -dot(n, d)) / (r2 * r2) : 0.0;
      }
      e += f * uOccluderAlbedo[i] * uLightPower[j] * (lit / weights);
    }
  }
  e = max(e, vec3(0.0));
  return (any(isnan(e)) || any(isinf(e))) ? vec3(0.0) : e;
}
