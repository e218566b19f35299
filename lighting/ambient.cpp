#include "lighting/ambient.h"

#include <algorithm>
#include <cmath>

#include "lighting/sh.h"
#include "reconstruction/light_estimation.h"

namespace mrgi::lighting {

std::array<cv::Vec3f, 9> Ambient::coefficients() const {
  std::array<cv::Vec3f, 9> a = sh;
  a[0] += uniform * static_cast<float>(1.0 / sh::kY00);
  return a;
}

cv::Vec3f Ambient::irradiance(const cv::Vec3f& n) const {
  std::array<cv::Vec3d, 9> s;
  for (size_t k = 0; k < 9; ++k) s[k] = cv::Vec3d(sh[k]);
  cv::Vec3f e = static_cast<float>(CV_PI) * uniform + cv::Vec3f(reconstruction::ambientShIrradiance(s, cv::Vec3d(n)));
  for (int c = 0; c < 3; ++c) e[c] = std::isfinite(e[c]) ? std::max(e[c], 0.0f) : 0.0f;
  return e;
}

cv::Vec3f Ambient::radiance(const cv::Vec3f& w) const {
  double y[9];
  sh::evaluate(cv::Vec3d(w), 3, y);
  cv::Vec3f L = uniform;
  for (int i = 0; i < 9; ++i) L += static_cast<float>(y[i]) * sh[static_cast<size_t>(i)];
  // Three bands of a sky seen from above ring below the horizon; radiance is never negative.
  for (int c = 0; c < 3; ++c) L[c] = std::max(L[c], 0.0f);
  return L;
}

}  // namespace mrgi::lighting
