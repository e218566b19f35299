// Joint bilateral upsampling of a technique output rendered at 1/factor of the frame's resolution
// (lighting/upsample.h is the C++ twin and says the weights): the four reduced texels around a frame pixel,
// bilinear weights times how much each texel's surface is the pixel's; where they give none, the best
// texel of the 4 x 4 around it; none: zero.

float upsampleWeight(vec4 positionP, vec4 normalP, vec4 positionQ, vec4 normalQ) {
  if (positionP.w < 0.5 || positionQ.w < 0.5) return 0.0;
  if (abs(normalP.w - normalQ.w) > 0.5) return 0.0;  // another object, or real against virtual
  vec3 d = positionQ.xyz - positionP.xyz;
  float len = length(d);
  float s = abs(dot(normalP.xyz, d)) / max(len, 1e-6);
  float c = max(dot(normalP.xyz, normalQ.xyz), 0.0), c2 = c * c, c4 = c2 * c2;
  float w = exp(-(s * s) / (0.3 * 0.3)) * c4 * c4;
  return (isnan(w) || isinf(w)) ? 0.0 : w;
}

// The reduced texels a frame pixel's value comes from: the four around it, each with its bilinear weight times how much
// its surface is the pixel's, and their total; where that total gives none (at most 1e-4), the texel of the 4 x 4
// around them whose surface is most the pixel's (found: false where none is).
struct UpsampleTaps {
  ivec2 q[4];
  float w[4];
  float total;
  ivec2 best;
  bool found;
};

UpsampleTaps upsampleTaps(ivec2 size, sampler2D lowPosition, sampler2D lowNormal, int factor, ivec2 pixel,
                          vec4 position, vec4 normal) {
  UpsampleTaps t;
  vec2 uv = vec2(pixel - ivec2(factor / 2)) / float(factor);
  ivec2 base = ivec2(floor(uv));
  vec2 f = uv - vec2(base);
  t.total = 0.0;
  for (int dj = 0; dj < 2; ++dj)
    for (int di = 0; di < 2; ++di) {
      int k = dj * 2 + di;
      t.q[k] = clamp(base + ivec2(di, dj), ivec2(0), size - 1);
      float b = (di == 1 ? f.x : 1.0 - f.x) * (dj == 1 ? f.y : 1.0 - f.y);
      t.w[k] = b * upsampleWeight(position, normal, texelFetch(lowPosition, t.q[k], 0), texelFetch(lowNormal, t.q[k], 0));
      t.total += t.w[k];
    }
  // The search, as one loop whose count is zero where the four gave a weight: a software rasteriser (llvmpipe)
  // runs a branch's body for a batch of pixels under a mask whether or not any pixel takes it, but leaves a loop
  // once none of the batch is still in it. The same texels in the same order as two nested loops.
  float best = 1e-4;
  t.best = ivec2(0);
  t.found = false;
  int count = t.total > 1e-4 ? 0 : 16;
  for (int i = 0; i < count; ++i) {
    ivec2 q = clamp(base + ivec2(i % 4 - 1, i / 4 - 1), ivec2(0), size - 1);
    float w = upsampleWeight(position, normal, texelFetch(lowPosition, q, 0), texelFetch(lowNormal, q, 0));
    if (w > best) {
      best = w;
      t.best = q;
      t.found = true;
    }
  }
  return t;
}

// A reduced output's value at the pixel its taps were found for.
vec3 upsampledFrom(UpsampleTaps t, sampler2D value) {
  if (t.total > 1e-4) {
    vec3 sum = vec3(0.0);
    for (int k = 0; k < 4; ++k) sum += t.w[k] * texelFetch(value, t.q[k], 0).rgb;
    return sum / t.total;
  }
  return t.found ? texelFetch(value, t.best, 0).rgb : vec3(0.0);
}

vec3 upsampled(sampler2D value, sampler2D lowPosition, sampler2D lowNormal, int factor, ivec2 pixel, vec4 position,
               vec4 normal) {
  if (position.w < 0.5) return vec3(0.0);
  return upsampledFrom(upsampleTaps(textureSize(value, 0), lowPosition, lowNormal, factor, pixel, position, normal),
                       value);
}

// Two outputs of one reduced view (the same lowPosition, lowNormal and factor, the same size) upsampled with the taps
// found once: each the value upsampled() gives it.
void upsampledPair(sampler2D valueA, sampler2D valueB, sampler2D lowPosition, sampler2D lowNormal, int factor,
                   ivec2 pixel, vec4 position, vec4 normal, out vec3 a, out vec3 b) {
  a = vec3(0.0);
  b = vec3(0.0);
  if (position.w < 0.5) return;
  const UpsampleTaps t =
      upsampleTaps(textureSize(valueA, 0), lowPosition, lowNormal, factor, pixel, position, normal);
  a = upsampledFrom(t, valueA);
  b = upsampledFrom(t, valueB);
}
