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

vec3 upsampled(sampler2D value, sampler2D lowPosition, sampler2D lowNormal, int factor, ivec2 pixel, vec4 position,
               vec4 normal) {
  if (position.w < 0.5) return vec3(0.0);
  ivec2 size = textureSize(value, 0);
  vec2 uv = vec2(pixel - ivec2(factor / 2)) / float(factor);
  ivec2 base = ivec2(floor(uv));
  vec2 t = uv - vec2(base);
  vec3 sum = vec3(0.0);
  float total = 0.0;
  for (int dj = 0; dj < 2; ++dj)
    for (int di = 0; di < 2; ++di) {
      ivec2 q = clamp(base + ivec2(di, dj), ivec2(0), size - 1);
      float b = (di == 1 ? t.x : 1.0 - t.x) * (dj == 1 ? t.y : 1.0 - t.y);
      float w = b * upsampleWeight(position, normal, texelFetch(lowPosition, q, 0), texelFetch(lowNormal, q, 0));
      sum += w * texelFetch(value, q, 0).rgb;
      total += w;
    }
  if (total > 1e-4) return sum / total;
  // The search, as one loop whose count is zero where the four gave a weight: a software rasteriser (llvmpipe)
  // runs a branch's body for a batch of pixels under a mask whether or not any pixel takes it, but leaves a loop
  // once none of the batch is still in it. The same texels in the same order as two nested loops.
  float best = 1e-4;
  vec3 result = vec3(0.0);
  int count = total > 1e-4 ? 0 : 16;
  for (int i = 0; i < count; ++i) {
    ivec2 q = clamp(base + ivec2(i % 4 - 1, i / 4 - 1), ivec2(0), size - 1);
    float w = upsampleWeight(position, normal, texelFetch(lowPosition, q, 0), texelFetch(lowNormal, q, 0));
    if (w > best) {
      best = w;
      result = texelFetch(value, q, 0).rgb;
    }
  }
  return result;
}

// Two outputs of one reduced view (the same lowPosition, lowNormal and factor) upsampled with weights computed once:
// each the value upsampled() gives it, the same operations in the same order.
void upsampledPair(sampler2D valueA, sampler2D valueB, sampler2D lowPosition, sampler2D lowNormal, int factor,
                   ivec2 pixel, vec4 position, vec4 normal, out vec3 a, out vec3 b) {
  a = vec3(0.0);
  b = vec3(0.0);
  if (position.w < 0.5) return;
  ivec2 size = textureSize(valueA, 0);
  vec2 uv = vec2(pixel - ivec2(factor / 2)) / float(factor);
  ivec2 base = ivec2(floor(uv));
  vec2 t = uv - vec2(base);
  vec3 sumA = vec3(0.0), sumB = vec3(0.0);
  float total = 0.0;
  for (int dj = 0; dj < 2; ++dj)
    for (int di = 0; di < 2; ++di) {
      ivec2 q = clamp(base + ivec2(di, dj), ivec2(0), size - 1);
      float bw = (di == 1 ? t.x : 1.0 - t.x) * (dj == 1 ? t.y : 1.0 - t.y);
      float w = bw * upsampleWeight(position, normal, texelFetch(lowPosition, q, 0), texelFetch(lowNormal, q, 0));
      sumA += w * texelFetch(valueA, q, 0).rgb;
      sumB += w * texelFetch(valueB, q, 0).rgb;
      total += w;
    }
  if (total > 1e-4) {
    a = sumA / total;
    b = sumB / total;
    return;
  }
  float best = 1e-4;
  int count = total > 1e-4 ? 0 : 16;
  for (int i = 0; i < count; ++i) {
    ivec2 q = clamp(base + ivec2(i % 4 - 1, i / 4 - 1), ivec2(0), size - 1);
    float w = upsampleWeight(position, normal, texelFetch(lowPosition, q, 0), texelFetch(lowNormal, q, 0));
    if (w > best) {
      best = w;
      a = texelFetch(valueA, q, 0).rgb;
      b = texelFetch(valueB, q, 0).rgb;
    }
  }
}
