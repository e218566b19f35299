// The ambient's SH part (bands 0-2, lighting/sh.h convention; reconstruction::shBasis2's basis): its basis,
// its irradiance about a normal and the ambient's radiance along a direction. The shading pass, the imperfect
// volumes and splatting read the ambient through it; reconstruction::ambientShIrradiance is the C++ twin.

// y_i(d) for i < 9, d a unit vector.
void ambientShBasis(vec3 d, out float b[9]) {
  b = float[9](0.282094791773878, 0.488602511902920 * d.y, 0.488602511902920 * d.z, 0.488602511902920 * d.x,
               1.092548430592079 * d.x * d.y, 1.092548430592079 * d.y * d.z, 0.315391565252520 * (3.0 * d.z * d.z - 1.0),
               1.092548430592079 * d.x * d.z, 0.546274215296040 * (d.x * d.x - d.y * d.y));
}

// sum_lm A_l c_lm y_lm(n), A = (pi, 2 pi / 3, pi / 4), clamped at 0.
vec3 ambientShIrradiance(vec3 sh[9], vec3 n) {
  const float pi = 3.14159265358979;
  float b[9];
  ambientShBasis(n, b);
  vec3 e = pi * b[0] * sh[0];
  for (int k = 1; k < 4; ++k) e += (2.0 * pi / 3.0) * b[k] * sh[k];
  for (int k = 4; k < 9; ++k) e += (pi / 4.0) * b[k] * sh[k];
  return max(e, vec3(0.0));
}

// The ambient's radiance seen looking along unit w: the uniform part plus the SH part, each channel clamped
// at 0 (three bands of a sky seen from above ring below the horizon; iv::Ambient::radiance is the C++ twin).
vec3 ambientRadiance(vec3 uniformPart, vec3 sh[9], vec3 w) {
  float b[9];
  ambientShBasis(w, b);
  vec3 L = uniformPart;
  for (int k = 0; k < 9; ++k) L += b[k] * sh[k];
  return max(L, vec3(0.0));
}

// The ambient's irradiance about unit n: pi x the uniform part plus the SH part's, clamped at 0
// (lighting::Ambient::irradiance is the C++ twin).
vec3 ambientIrradiance(vec3 uniformPart, vec3 sh[9], vec3 n) {
  return max(3.14159265358979 * uniformPart + ambientShIrradiance(sh, n), vec3(0.0));
}
