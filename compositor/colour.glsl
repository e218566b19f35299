// sRGB transfer functions (IEC 61966-2-1); C++ twin: capture/colour.h (compositor_test holds them together).
vec3 srgbToLinear(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), greaterThan(c, vec3(0.04045)));
}

vec3 linearToSrgb(vec3 c) {
  // NaN fails every comparison: max(c, 0) keeps it, so test explicitly and map it to black.
  c = mix(c, vec3(0.0), isnan(c));
  c = clamp(c, 0.0, 1.0);
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}
