#pragma once
/// Real spherical harmonics, bands l = 0..B-1 (B <= 8, B^2 coefficients, index i = l(l+1)+m), as used by
/// DLPV and the later volume techniques (shared/notes/algorithms.md §1). GLSL twin: lighting/sh.glsl.
///
/// Convention (no Condon-Shortley phase): y_00 = 1/(2 sqrt(pi)), y_1m = sqrt(3/(4 pi)) (y, z, x) for
/// m = -1, 0, 1; generally y_lm = sqrt(2) K_lm Pbar_lm(z) Re((x + iy)^m) for m > 0 and Im((x + iy)^|m|) for
/// m < 0, with Pbar_lm = P_lm / sin^m (a polynomial in z), so evaluation needs no trigonometry.
#include <array>
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

namespace mrgi::lighting::sh {

constexpr int kMaxBands = 8;

/// Band 0 and 1 constants (float, as the two-band volumes store them): y_00 = 1/(2 sqrt(pi)),
/// y_1m = sqrt(3/(4 pi)) (y, z, x); the clamped cosine <n, w>+ projects to (sqrt(pi)/2, sqrt(pi/3) n).
constexpr float kY00 = 0.282094792f;
constexpr float kY1 = 0.488602512f;
constexpr float kCosineBand0 = 0.886226925f;  // sqrt(pi) / 2
constexpr float kCosineBand1 = 1.023326708f;  // sqrt(pi / 3)
constexpr int coefficientCount(int bands) { return bands * bands; }
constexpr int index(int l, int m) { return l * (l + 1) + m; }

/// y_i(d) for i < bands^2, d a unit vector. out must hold bands^2 values.
void evaluate(const cv::Vec3d& d, int bands, double* out);
std::vector<double> evaluate(const cv::Vec3d& d, int bands);

/// Monte-Carlo projection with N uniform sphere samples (stratified, deterministic seed):
/// c_i = 4 pi / N sum f(w_j) y_i(w_j).
std::vector<double> projectMonteCarlo(const std::function<double(const cv::Vec3d&)>& f, int bands, int samples,
                                      unsigned seed = 1);

/// Sum_i c_i y_i(d).
double reconstruct(const std::vector<double>& c, const cv::Vec3d& d);

/// Coefficients of a zonal function (per-band z_l about +z) rotated so its axis points along d:
/// c_lm = sqrt(4 pi / (2l+1)) z_l y_lm(d).
std::vector<double> rotateZonal(const std::vector<double>& zonal, const cv::Vec3d& d);

/// Convolution factors s_l(n) of the normalised Phong lobe ((n+1)/(2 pi)) cos^n (hemisphere), l < bands:
/// s_0 = 1, s_1 = (n+1)/(n+2), s_l = s_{l-2} (n+2-l)/(n+1+l). n = 1: pi s_l are the clamped-cosine
/// (irradiance) factors. Finite for any n >= 0.
std::vector<double> phongLobeFactors(double n, int bands);

/// Zonal coefficients z_l of the indicator of the cone of half-angle alpha around +z:
/// z_l = 2 pi sqrt((2l+1)/(4 pi)) int_{cos alpha}^1 P_l(t) dt; evaluated through u = 1 - cos alpha
/// (exact polynomial) for small cones, so it stays accurate as alpha -> 0, and by the Legendre closed form
/// for wide ones.
std::vector<double> coneZonal(double alpha, int bands);

/// Legendre polynomial P_l(x).
double legendre(int l, double x);

}  // namespace mrgi::lighting::sh
