// The object terms carried from frame to frame (frame knob object_terms_history; lighting/terms_history.h is
// the C++ twin and says when the history counts).
const float kHistoryRelativeDistance = 0.02;
const float kHistoryAbsoluteDistance = 0.002;
const float kHistoryNormalCosine = 0.9;

// The previous reduced grid's texel nearest x's image point in the previous camera, or (-1, -1).
ivec2 historyTexel(mat4 cameraFromWorld, vec4 intrinsics, int factor, ivec2 grid, vec3 x) {
  vec4 q = cameraFromWorld * vec4(x, 1.0);
  if (!(q.z > 1e-4)) return ivec2(-1);
  float u = intrinsics.x * q.x / q.z + intrinsics.z, v = intrinsics.y * q.y / q.z + intrinsics.w;
  float f = float(factor), offset = float(factor / 2);
  float i = floor((u - offset) / f + 0.5), j = floor((v - offset) / f + 0.5);
  if (!(i >= 0.0 && j >= 0.0 && i < float(grid.x) && j < float(grid.y))) return ivec2(-1);
  return ivec2(int(i), int(j));
}

bool historyAgrees(vec3 x, vec3 n, vec3 eye, vec4 previousPosition, vec4 previousNormal) {
  if (!(previousPosition.w > 0.5)) return false;
  vec3 d = previousPosition.xyz - x;
  float reach = kHistoryRelativeDistance * length(x - eye) + kHistoryAbsoluteDistance;
  if (!(dot(d, d) <= reach * reach)) return false;
  return dot(n, previousNormal.xyz) >= kHistoryNormalCosine;
}

vec4 blendHistory(vec4 fresh, vec4 history, float weight, bool agrees) {
  if (!agrees || !(weight > 0.0)) return fresh;
  if (any(isnan(history)) || any(isinf(history))) return fresh;
  return (1.0 - weight) * fresh + weight * history;
}
