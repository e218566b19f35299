// The view factor from a surface element to a sphere and a light's cosine with extent (capture/view_factor.h
// is the C++ twin; see it for the closed form's source and regimes). Included once per program.

// The fraction of the element's cosine-weighted hemisphere a sphere covers, its centre H radii away at
// cos theta = cosT to the normal.
float sphereViewFactorH(float H, float cosT) {
  const float pi = 3.14159265358979;
  if (!(H > 1.0)) return 1.0;
  cosT = clamp(cosT, -1.0, 1.0);
  if (H * cosT >= 1.0) return cosT / (H * H);
  if (H * cosT <= -1.0) return 0.0;
  float sinT = sqrt(max(0.0, 1.0 - cosT * cosT)), g = sqrt(H * H - 1.0);
  // asin and acos through the two-argument atan: Mesa's asin/acos are coarse polynomials (errors of 1e-3
  // here), its atan holds the twin to 1e-5.
  float sa = clamp(g / (H * sinT), -1.0, 1.0), cb = clamp(-g * cosT / sinT, -1.0, 1.0);
  float a = atan(sa, sqrt(max(0.0, 1.0 - sa * sa)));
  float b = atan(sqrt(max(0.0, 1.0 - cb * cb)), cb);
  float f = 0.5 - a / pi + (cosT * b - g * sqrt(max(0.0, 1.0 - H * H * cosT * cosT))) / (pi * H * H);
  return clamp(f, 0.0, 1.0);
}

// A disc of uniform radiance seen under half-angle alpha (sin alpha = sinA) at cos theta = cosT: its
// irradiance over its irradiance at normal incidence (max(cosT, 0) for a point direction).
float capCosine(float cosT, float sinA) {
  if (!(sinA > 1e-4)) return clamp(cosT, 0.0, 1.0);
  sinA = min(sinA, 0.999);
  return min(sphereViewFactorH(1.0 / sinA, cosT) / (sinA * sinA), 1.0);
}
