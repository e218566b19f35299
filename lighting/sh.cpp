#include "lighting/sh.h"

#include <cmath>
#include <random>
#include <stdexcept>

namespace mrgi::lighting::sh {
namespace {

double factorial(int n) {
  double f = 1;
  for (int i = 2; i <= n; ++i) f *= i;
  return f;
}

/// K_lm = sqrt((2l+1)/(4 pi) (l-|m|)!/(l+|m|)!)
double normalisation(int l, int m) {
  m = std::abs(m);
  return std::sqrt((2.0 * l + 1.0) / (4.0 * CV_PI) * factorial(l - m) / factorial(l + m));
}

void checkBands(int bands) {
  if (bands < 1 || bands > kMaxBands) throw std::invalid_argument("SH bands must be 1..8");
}

}  // namespace

void evaluate(const cv::Vec3d& d, int bands, double* out) {
  checkBands(bands);
  const double x = d[0], y = d[1], z = d[2];
  // Re/Im of (x + iy)^m.
  double re[kMaxBands], im[kMaxBands];
  re[0] = 1, im[0] = 0;
  for (int m = 1; m < bands; ++m) re[m] = re[m - 1] * x - im[m - 1] * y, im[m] = re[m - 1] * y + im[m - 1] * x;
  for (int m = 0; m < bands; ++m) {
    // Pbar_lm(z) for l = m..bands-1.
    double pmm = 1;
    for (int k = 1; k <= m; ++k) pmm *= 2 * k - 1;  // (2m-1)!!
    double p0 = pmm, p1 = z * (2 * m + 1) * pmm;
    for (int l = m; l < bands; ++l) {
      double p;
      if (l == m)
        p = p0;
      else if (l == m + 1)
        p = p1;
      else {
        p = (z * (2 * l - 1) * p1 - (l + m - 1) * p0) / (l - m);
        p0 = p1, p1 = p;
      }
      if (m == 0) {
        out[index(l, 0)] = normalisation(l, 0) * p;
      } else {
        const double k = std::sqrt(2.0) * normalisation(l, m) * p;
        out[index(l, m)] = k * re[m];
        out[index(l, -m)] = k * im[m];
      }
    }
  }
}

std::vector<double> evaluate(const cv::Vec3d& d, int bands) {
  std::vector<double> out(coefficientCount(bands));
  evaluate(d, bands, out.data());
  return out;
}

std::vector<double> projectMonteCarlo(const std::function<double(const cv::Vec3d&)>& f, int bands, int samples,
                                      unsigned seed) {
  checkBands(bands);
  std::vector<double> c(coefficientCount(bands), 0.0), y(c.size());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // Stratified in (cos theta, phi) on a sqrt(N) x sqrt(N) grid.
  const int side = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(samples))));
  const int n = side * side;
  for (int a = 0; a < side; ++a)
    for (int b = 0; b < side; ++b) {
      const double z = 1.0 - 2.0 * (a + u(rng)) / side, phi = 2.0 * CV_PI * (b + u(rng)) / side;
      const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
      const cv::Vec3d w(s * std::cos(phi), s * std::sin(phi), z);
      const double fw = f(w);
      evaluate(w, bands, y.data());
      for (size_t i = 0; i < c.size(); ++i) c[i] += fw * y[i];
    }
  for (auto& v : c) v *= 4.0 * CV_PI / n;
  return c;
}

double reconstruct(const std::vector<double>& c, const cv::Vec3d& d) {
  const int bands = static_cast<int>(std::lround(std::sqrt(static_cast<double>(c.size()))));
  if (bands * bands != static_cast<int>(c.size())) throw std::invalid_argument("SH coefficient count is not a square");
  double y[kMaxBands * kMaxBands];
  evaluate(d, bands, y);
  double s = 0;
  for (size_t i = 0; i < c.size(); ++i) s += c[i] * y[i];
  return s;
}

std::vector<double> rotateZonal(const std::vector<double>& zonal, const cv::Vec3d& d) {
  const int bands = static_cast<int>(zonal.size());
  std::vector<double> y = evaluate(d, bands), c(y.size());
  for (int l = 0; l < bands; ++l)
    for (int m = -l; m <= l; ++m) c[index(l, m)] = std::sqrt(4.0 * CV_PI / (2 * l + 1)) * zonal[l] * y[index(l, m)];
  return c;
}

std::vector<double> phongLobeFactors(double n, int bands) {
  checkBands(bands);
  n = std::max(0.0, n);
  std::vector<double> s(bands);
  s[0] = 1.0;
  if (bands > 1) s[1] = (n + 1) / (n + 2);
  for (int l = 2; l < bands; ++l) s[l] = s[l - 2] * (n + 2 - l) / (n + 1 + l);
  return s;
}

double legendre(int l, double x) {
  if (l == 0) return 1.0;
  double p0 = 1.0, p1 = x;
  for (int k = 2; k <= l; ++k) {
    const double p = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
    p0 = p1, p1 = p;
  }
  return p1;
}

std::vector<double> coneZonal(double alpha, int bands) {
  checkBands(bands);
  alpha = std::clamp(alpha, 0.0, CV_PI);
  // u = 1 - cos(alpha) without cancellation: 2 sin^2(alpha / 2).
  const double u = 2.0 * std::pow(std::sin(alpha / 2.0), 2);
  const double x = std::cos(alpha);
  std::vector<double> z(bands);
  for (int l = 0; l < bands; ++l) {
    double integral;
    if (l == 0) {
      integral = u;
    } else if (u < 0.5) {
      // P_l(1 - s) = sum_k (l+k)! / ((l-k)! (k!)^2) (-s/2)^k, integrated over s in [0, u].
      integral = 0;
      double pw = u;  // u^(k+1)
      for (int k = 0; k <= l; ++k) {
        integral +=
            factorial(l + k) / (factorial(l - k) * factorial(k) * factorial(k)) * std::pow(-0.5, k) * pw / (k + 1);
        pw *= u;
      }
    } else {
      integral = (legendre(l - 1, x) - legendre(l + 1, x)) / (2 * l + 1);
    }
    z[l] = 2.0 * CV_PI * std::sqrt((2 * l + 1) / (4.0 * CV_PI)) * integral;
  }
  return z;
}

}  // namespace mrgi::lighting::sh
