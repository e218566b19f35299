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

// The solid angle of a level-0 texel at the equator (RadianceMap::texelSolidAngle).
float radianceMapTexel(sampler2D map) {
  const float pi = 3.14159265358979;
  vec2 size = vec2(textureSize(map, 0));
  return (2.0 * pi / size.x) * (pi / size.y);
}

// The level whose texels at the equator each cover solidAngle (RadianceMap::lodFor), given a level-0 texel's
// solid angle and the last level.
float radianceMapLod(float texel, float maxLevel, float solidAngle) {
  float lod = 0.5 * log2(solidAngle / texel);
  return (isnan(lod) || isinf(lod)) ? 0.0 : clamp(lod, 0.0, maxLevel);
}

// The mean radiance over the cap about unit w whose half-angle has 1 - cos = oneMinusCos, each direction weighted
// by its cosine about n (RadianceMap::capMean): one equal-solid-angle direction per level-0 texel the cap covers (1
// to CAP_SAMPLES), each read at the level of a quarter of its share of the cap; the radiance along w when every one
// lies under n's horizon.
// `texel` and `maxLevel`: radianceMapTexel(map) and its last level, the same for every cap of a pixel.
vec3 radianceMapCapMean(sampler2D map, float texel, float maxLevel, vec3 w, float oneMinusCos, vec3 n) {
  vec3 t = normalize(cross(w, abs(w.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
  vec3 b = cross(w, t);
  // One direction per level-0 texel the cap covers, 1 to CAP_SAMPLES (RadianceMap::capSamples).
  float perTexel = ceil(2.0 * 3.14159265358979 * oneMinusCos / texel);
  int count = (isnan(perTexel) || isinf(perTexel)) ? 1 : int(clamp(perTexel, 1.0, float(CAP_SAMPLES)));
  float lod = radianceMapLod(texel, maxLevel, 2.0 * 3.14159265358979 * oneMinusCos / (4.0 * float(count)));
  vec3 sum = vec3(0.0);
  float weights = 0.0;
  // The azimuth steps by the golden angle, its cosine and sine turned each step (RadianceMap::capMean).
  const float goldenCos = -0.737368878, goldenSin = 0.675490294;
  float cosPhi = 1.0, sinPhi = 0.0;
  for (int k = 0; k < count; ++k) {
    float omc = oneMinusCos * (float(k) + 0.5) / float(count);
    float c = 1.0 - omc, sn = sqrt(max(0.0, omc * (2.0 - omc)));
    vec3 d = sn * cosPhi * t + sn * sinPhi * b + c * w;
    float turned = cosPhi * goldenCos - sinPhi * goldenSin;
    sinPhi = sinPhi * goldenCos + cosPhi * goldenSin;
    cosPhi = turned;
    float weight = max(0.0, dot(d, n));
    if (!(weight > 0.0)) continue;
    sum += weight * radianceMapSample(map, d, lod);
    weights += weight;
  }
  return weights > 0.0 ? sum / weights : radianceMapSample(map, w, lod);
}
