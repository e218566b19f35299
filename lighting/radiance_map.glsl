// A lat-long radiance map with its box-filtered levels (lighting/radiance_map.h is the C++ twin): the
// azimuth from +x towards +y along s (repeating), the polar angle from +z along t (clamped), read with
// GL_LINEAR_MIPMAP_LINEAR at an explicit level.
#define CAP_SAMPLES 32  // lighting::RadianceMap::kCapSamples

// The radiance arriving from unit direction w at level lod.
vec3 radianceMapSample(sampler2D map, vec3 w, float lod) {
  const float pi = 3.14159265358979;
  vec2 st = vec2(atan(w.y, w.x) / (2.0 * pi), acos(clamp(w.z, -1.0, 1.0)) / pi);
  return max(textureLod(map, st, lod).rgb, vec3(0.0));
}

// The level whose texels at the equator each cover solidAngle (RadianceMap::lodFor).
float radianceMapLod(sampler2D map, float solidAngle) {
  const float pi = 3.14159265358979;
  vec2 size = vec2(textureSize(map, 0));
  float lod = 0.5 * log2(solidAngle / ((2.0 * pi / size.x) * (pi / size.y)));
  float maxLevel = float(textureQueryLevels(map) - 1);
  return (isnan(lod) || isinf(lod)) ? 0.0 : clamp(lod, 0.0, maxLevel);
}

// The mean radiance over the cap about unit w whose half-angle has 1 - cos = oneMinusCos, each direction weighted
// by its cosine about n (RadianceMap::capMean): CAP_SAMPLES equal-solid-angle directions, each read at the level
// of a quarter of its share of the cap; the radiance along w when every one lies under n's horizon.
vec3 radianceMapCapMean(sampler2D map, vec3 w, float oneMinusCos, vec3 n) {
  vec3 t = normalize(cross(w, abs(w.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
  vec3 b = cross(w, t);
  float lod = radianceMapLod(map, 2.0 * 3.14159265358979 * oneMinusCos / (4.0 * float(CAP_SAMPLES)));
  vec3 sum = vec3(0.0);
  float weights = 0.0;
  for (int k = 0; k < CAP_SAMPLES; ++k) {
    float omc = oneMinusCos * (float(k) + 0.5) / float(CAP_SAMPLES);
    float c = 1.0 - omc, sn = sqrt(max(0.0, omc * (2.0 - omc))), phi = 2.399963229728653 * float(k);
    vec3 d = sn * cos(phi) * t + sn * sin(phi) * b + c * w;
    float weight = max(0.0, dot(d, n));
    if (!(weight > 0.0)) continue;
    sum += weight * radianceMapSample(map, d, lod);
    weights += weight;
  }
  return weights > 0.0 ? sum / weights : radianceMapSample(map, w, lod);
}
