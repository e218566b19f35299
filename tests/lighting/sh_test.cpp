#include "lighting/sh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/calib3d.hpp>

using namespace mrgi::lighting;

namespace {

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n).
void gaussLegendre(int n, std::vector<double>& x, std::vector<double>& w) {
  x.resize(n), w.resize(n);
  for (int i = 0; i < n; ++i) {
    double t = std::cos(CV_PI * (i + 0.75) / (n + 0.5));
    for (int it = 0; it < 100; ++it) {
      const double p = sh::legendre(n, t), q = sh::legendre(n - 1, t);
      const double dp = n * (t * p - q) / (t * t - 1);
      const double step = p / dp;
      t -= step;
      if (std::abs(step) < 1e-16) break;
    }
    const double p = sh::legendre(n, t), q = sh::legendre(n - 1, t);
    const double dp = n * (t * p - q) / (t * t - 1);
    x[i] = t, w[i] = 2 / ((1 - t * t) * dp * dp);
  }
}

/// Integrates g over the sphere: Gauss-Legendre in z (nz nodes) x uniform phi (nphi): exact for
/// polynomials of degree < 2 nz in z and trigonometric degree < nphi in phi.
template <class G>
void sphereQuadrature(int nz, int nphi, G&& g) {
  std::vector<double> x, w;
  gaussLegendre(nz, x, w);
  for (int i = 0; i < nz; ++i)
    for (int j = 0; j < nphi; ++j) {
      const double phi = 2 * CV_PI * (j + 0.5) / nphi, s = std::sqrt(1 - x[i] * x[i]);
      g(cv::Vec3d(s * std::cos(phi), s * std::sin(phi), x[i]), w[i] * 2 * CV_PI / nphi);
    }
}

std::vector<double> projectQuadrature(const std::function<double(const cv::Vec3d&)>& f, int bands, int nz = 64,
                                      int nphi = 128) {
  std::vector<double> c(bands * bands, 0.0);
  sphereQuadrature(nz, nphi, [&](const cv::Vec3d& d, double wt) {
    const auto y = sh::evaluate(d, bands);
    const double fd = f(d);
    for (size_t i = 0; i < c.size(); ++i) c[i] += wt * fd * y[i];
  });
  return c;
}

}  // namespace

TEST(SH, BandZeroAndOneConstants) {
  const cv::Vec3d d = cv::normalize(cv::Vec3d(0.3, -0.5, 0.8));
  const auto y = sh::evaluate(d, 2);
  EXPECT_NEAR(y[0], 0.282094792, 1e-9);
  EXPECT_NEAR(y[1], 0.488602512 * d[1], 1e-9);
  EXPECT_NEAR(y[2], 0.488602512 * d[2], 1e-9);
  EXPECT_NEAR(y[3], 0.488602512 * d[0], 1e-9);
}

TEST(SH, OrthonormalByQuadratureForEightBands) {
  const int B = 8, n = B * B;
  std::vector<double> gram(n * n, 0.0);
  sphereQuadrature(16, 32, [&](const cv::Vec3d& d, double wt) {
    const auto y = sh::evaluate(d, B);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) gram[i * n + j] += wt * y[i] * y[j];
  });
  double worst = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) worst = std::max(worst, std::abs(gram[i * n + j] - (i == j ? 1.0 : 0.0)));
  EXPECT_LT(worst, 1e-12);
}

TEST(SH, BandEnergiesAreRotationInvariantAndZonalRotationMatchesProjection) {
  const int B = 8;
  const cv::Vec3d a = cv::normalize(cv::Vec3d(0.2, 0.9, -0.4));
  auto f = [&](const cv::Vec3d& w) { return std::exp(2.0 * w.dot(a)) + 0.5 * w[0] * w[1]; };
  cv::Matx33d R;
  cv::Rodrigues(cv::Vec3d(0.7, -1.1, 0.4), R);
  const auto c0 = projectQuadrature(f, B);
  const auto c1 = projectQuadrature([&](const cv::Vec3d& w) { return f(R.t() * w); }, B);
  for (int l = 0; l < B; ++l) {
    double e0 = 0, e1 = 0;
    for (int m = -l; m <= l; ++m) e0 += std::pow(c0[sh::index(l, m)], 2), e1 += std::pow(c1[sh::index(l, m)], 2);
    EXPECT_NEAR(e0, e1, 1e-9 * std::max(1.0, e0)) << l;
  }
  // A zonal lobe exp(3 cos) about +z, rotated to a, equals the projection of exp(3 a.w).
  std::vector<double> zonal(B);
  std::vector<double> x, w;
  gaussLegendre(48, x, w);
  for (int l = 0; l < B; ++l) {
    zonal[l] = 0;
    for (size_t i = 0; i < x.size(); ++i)
      zonal[l] += w[i] * 2 * CV_PI * std::exp(3 * x[i]) * std::sqrt((2 * l + 1) / (4 * CV_PI)) * sh::legendre(l, x[i]);
  }
  const auto rotated = sh::rotateZonal(zonal, a);
  const auto direct = projectQuadrature([&](const cv::Vec3d& v) { return std::exp(3 * v.dot(a)); }, B);
  for (size_t i = 0; i < rotated.size(); ++i) EXPECT_NEAR(rotated[i], direct[i], 1e-9) << i;
}

TEST(SH, PhongFactorsGiveTheClampedCosineAndMatchBruteForceConvolution) {
  const auto s = sh::phongLobeFactors(1, 5);
  EXPECT_NEAR(CV_PI * s[0], CV_PI, 1e-15);
  EXPECT_NEAR(CV_PI * s[1], 2 * CV_PI / 3, 1e-15);
  EXPECT_NEAR(CV_PI * s[2], CV_PI / 4, 1e-15);
  EXPECT_NEAR(CV_PI * s[3], 0.0, 1e-15);
  EXPECT_NEAR(CV_PI * s[4], -CV_PI / 24, 1e-15);
  // Funk-Hecke: convolving a band-limited L with the normalised lobe multiplies band l by s_l.
  const int B = 6;
  std::vector<double> L(B * B);
  for (size_t i = 0; i < L.size(); ++i) L[i] = std::sin(1.7 * i + 0.3);
  const cv::Vec3d n = cv::normalize(cv::Vec3d(-0.4, 0.2, 0.9));
  for (const double e : {1.0, 5.0, 20.0}) {
    double brute = 0;
    sphereQuadrature(200, 64, [&](const cv::Vec3d& w, double wt) {
      const double c = n.dot(w);
      if (c > 0) brute += wt * sh::reconstruct(L, w) * (e + 1) / (2 * CV_PI) * std::pow(c, e);
    });
    const auto f = sh::phongLobeFactors(e, B);
    const auto y = sh::evaluate(n, B);
    double viaSh = 0;
    for (int l = 0; l < B; ++l)
      for (int m = -l; m <= l; ++m) viaSh += f[l] * L[sh::index(l, m)] * y[sh::index(l, m)];
    EXPECT_NEAR(brute, viaSh, 2e-3 * std::abs(viaSh) + 1e-4) << e;  // the hemisphere edge limits the quadrature
  }
  // Extremes: exponents 0 to 1e4 stay finite and in [-1, 1].
  for (const double e : {0.0, 1e-6, 1e4, 1e9})
    for (double v : sh::phongLobeFactors(e, 8)) {
      EXPECT_TRUE(std::isfinite(v));
      EXPECT_LE(std::abs(v), 1.0);
    }
}

TEST(SH, ConeProjectionIsStableFromTinyToFullCones) {
  const int B = 8;
  std::vector<double> x, w;
  gaussLegendre(32, x, w);
  for (double alpha = 1e-6; alpha <= CV_PI; alpha *= 1.7) {
    const auto z = sh::coneZonal(alpha, B);
    const double u = 2 * std::pow(std::sin(alpha / 2), 2);
    for (int l = 0; l < B; ++l) {
      const double k = 2 * CV_PI * std::sqrt((2 * l + 1) / (4 * CV_PI));
      double ref;
      if (alpha < 1e-3) {
        ref = k * (u - l * (l + 1) * u * u / 4);  // P_l(1 - s) ~ 1 - l(l+1) s / 2
      } else {
        ref = 0;  // Gauss-Legendre on [cos alpha, 1], exact for P_l
        const double a = 1 - u;
        for (size_t i = 0; i < x.size(); ++i) ref += w[i] * (1 - a) / 2 * sh::legendre(l, a + (1 - a) * (x[i] + 1) / 2);
        ref *= k;
      }
      EXPECT_TRUE(std::isfinite(z[l]));
      EXPECT_NEAR(z[l], ref, 1e-9 * std::abs(ref) + 1e-13) << "alpha " << alpha << " l " << l;
    }
  }
  // Full sphere: only band 0 survives; z_0 y_00 sqrt(4 pi) = 1 everywhere.
  const auto full = sh::coneZonal(CV_PI, B);
  EXPECT_NEAR(full[0], std::sqrt(4 * CV_PI), 1e-12);
  for (int l = 1; l < B; ++l) EXPECT_NEAR(full[l], 0.0, 1e-12);
  // The two evaluation branches meet at u = 0.5 (alpha = 60 degrees).
  const auto below = sh::coneZonal(CV_PI / 3 - 1e-12, B), above = sh::coneZonal(CV_PI / 3 + 1e-12, B);
  for (int l = 0; l < B; ++l) EXPECT_NEAR(below[l], above[l], 1e-9);
}

TEST(SH, MonteCarloProjectionConverges) {
  std::vector<double> L(16);
  for (size_t i = 0; i < L.size(); ++i) L[i] = std::cos(0.9 * i);
  auto f = [&](const cv::Vec3d& d) { return sh::reconstruct(L, d); };
  double err1 = 0, err2 = 0;
  const auto a = sh::projectMonteCarlo(f, 4, 1024), b = sh::projectMonteCarlo(f, 4, 65536);
  for (size_t i = 0; i < L.size(); ++i)
    err1 = std::max(err1, std::abs(a[i] - L[i])), err2 = std::max(err2, std::abs(b[i] - L[i]));
  EXPECT_LT(err2, 0.01);
  EXPECT_LT(err2, err1);
  EXPECT_THROW(sh::evaluate(cv::Vec3d(0, 0, 1), 9), std::invalid_argument);
}
