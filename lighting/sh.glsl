// Real spherical harmonics: GLSL twin of lighting/sh.h (same convention, same recurrences; float).
// Define SH_BANDS (1..8) before including; default 4.
#ifndef SH_BANDS
#define SH_BANDS 4
#endif
#define SH_COEFFS (SH_BANDS * SH_BANDS)
#define SH_PI 3.14159265358979

float shFactorial(int n) {
  float f = 1.0;
  for (int i = 2; i <= n; ++i) f *= float(i);
  return f;
}

// K_lm = sqrt((2l+1)/(4 pi) (l-|m|)!/(l+|m|)!)
float shNormalisation(int l, int m) {
  m = abs(m);
  return sqrt(float(2 * l + 1) / (4.0 * SH_PI) * shFactorial(l - m) / shFactorial(l + m));
}

// y_i(d) for a unit vector d; y_lm = sqrt(2) K_lm Pbar_lm(z) Re/Im((x + iy)^|m|), no Condon-Shortley phase.
void shEvaluate(vec3 d, out float y[SH_COEFFS]) {
  float re[SH_BANDS];
  float im[SH_BANDS];
  re[0] = 1.0;
  im[0] = 0.0;
  for (int m = 1; m < SH_BANDS; ++m) {
    re[m] = re[m - 1] * d.x - im[m - 1] * d.y;
    im[m] = re[m - 1] * d.y + im[m - 1] * d.x;
  }
  for (int m = 0; m < SH_BANDS; ++m) {
    float pmm = 1.0;
    for (int k = 1; k <= m; ++k) pmm *= float(2 * k - 1);
    float p0 = pmm, p1 = d.z * float(2 * m + 1) * pmm;
    for (int l = m; l < SH_BANDS; ++l) {
      float p;
      if (l == m) {
        p = p0;
      } else if (l == m + 1) {
        p = p1;
      } else {
        p = (d.z * float(2 * l - 1) * p1 - float(l + m - 1) * p0) / float(l - m);
        p0 = p1;
        p1 = p;
      }
      if (m == 0) {
        y[l * (l + 1)] = shNormalisation(l, 0) * p;
      } else {
        float k = sqrt(2.0) * shNormalisation(l, m) * p;
        y[l * (l + 1) + m] = k * re[m];
        y[l * (l + 1) - m] = k * im[m];
      }
    }
  }
}

// s_l(n) of the normalised Phong lobe ((n+1)/(2 pi)) cos^n.
float shPhongFactor(float n, int l) {
  n = max(n, 0.0);
  float s0 = 1.0, s1 = (n + 1.0) / (n + 2.0);
  if (l == 0) return s0;
  if (l == 1) return s1;
  float a = s0, b = s1;  // s_{k-2}, s_{k-1}
  for (int k = 2; k <= l; ++k) {
    float s = a * (n + 2.0 - float(k)) / (n + 1.0 + float(k));
    a = b;
    b = s;
  }
  return b;
}

float shLegendre(int l, float x) {
  if (l == 0) return 1.0;
  float p0 = 1.0, p1 = x;
  for (int k = 2; k <= l; ++k) {
    float p = (float(2 * k - 1) * x * p1 - float(k - 1) * p0) / float(k);
    p0 = p1;
    p1 = p;
  }
  return p1;
}

// Zonal coefficient z_l of the cone of half-angle alpha about +z, stable as alpha -> 0 (see sh.h).
float shConeZonal(float alpha, int l) {
  alpha = clamp(alpha, 0.0, SH_PI);
  float sh2 = sin(0.5 * alpha);
  float u = 2.0 * sh2 * sh2;
  float integral;
  if (l == 0) {
    integral = u;
  } else if (u < 0.5) {
    integral = 0.0;
    float pw = u;
    for (int k = 0; k <= l; ++k) {
      float c = shFactorial(l + k) / (shFactorial(l - k) * shFactorial(k) * shFactorial(k));
      integral += c * pow(0.5, float(k)) * ((k & 1) == 1 ? -1.0 : 1.0) * pw / float(k + 1);
      pw *= u;
    }
  } else {
    float x = cos(alpha);
    integral = (shLegendre(l - 1, x) - shLegendre(l + 1, x)) / float(2 * l + 1);
  }
  return 2.0 * SH_PI * sqrt(float(2 * l + 1) / (4.0 * SH_PI)) * integral;
}
