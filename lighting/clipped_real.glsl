// A real pixel whose camera channel is clipped reads the sensor's white W (in scene radiance: 1 / exposure),
// not its radiance L >= W: a sunlit table, a lamp's pool of light. The compositor adds the objects' delta to
// the background, so an object's shadow there would be measured from W and drawn too dark, in the colour the
// clip leaves. Where the channel is clipped and the delta darkens it, the shading pass takes the radiance the
// lights predict there instead, P = albedo E / pi (E the irradiance without the objects), when it is above W:
// the composite becomes min(W, P + delta) where it was W + delta (a shadow deep enough to fall below the white
// reads as the shadowed surface's own radiance; a shallow one stays white, as the sensor would show it).
// C++ twin: lighting/clipped_real.h (tests/lighting/clipped_real_test.cpp holds them together).
//   shaded:    albedo E_delta / pi, what the compositor adds to the background
//   predicted: albedo E / pi
//   white:     the camera's white in scene radiance (<= 0: no correction)
//   code:      the G-buffer albedo's alpha on a real pixel: -(bits of the clipped channels, 1 = red)
vec3 clippedRealShade(vec3 shaded, vec3 predicted, float white, float code) {
  int bits = int(-code + 0.5);
  if (white <= 0.0 || bits <= 0) return shaded;
  vec3 result = shaded;
  for (int k = 0; k < 3; ++k)
    if (((bits >> k) & 1) != 0 && shaded[k] < 0.0)
      result[k] = min(0.0, shaded[k] + max(predicted[k] - white, 0.0));
  return result;
}
