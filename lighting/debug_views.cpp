#include "lighting/debug_views.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "capture/colour.h"

namespace mrgi::lighting {

cv::Vec3b signedColour(double v, double scale) {
  const double t = std::clamp(std::abs(v) / scale, 0.0, 1.0);
  const auto u = static_cast<uchar>(std::lround(255 * std::sqrt(t)));  // sqrt: small values stay visible
  return v >= 0 ? cv::Vec3b(u, u, u) : cv::Vec3b(u, 0, 0);
}

double percentile99(std::vector<double>& v) {
  if (v.empty()) return 1.0;
  const size_t k = static_cast<size_t>(0.99 * (v.size() - 1));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k] > 0 ? v[k] : 1.0;
}

cv::Mat signedImage(const cv::Mat& image, double& scale) {
  CV_Assert(image.depth() == CV_32F && image.channels() >= 3);
  const int ch = image.channels();
  cv::Mat lum(image.size(), CV_64F);
  std::vector<double> mags;
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      const float* p = image.ptr<float>(y) + x * ch;
      const double l = capture::luminance(cv::Vec3d(p[0], p[1], p[2]));
      lum.at<double>(y, x) = l;
      if (l != 0) mags.push_back(std::abs(l));
    }
  if (scale <= 0) scale = percentile99(mags);
  cv::Mat out(image.size(), CV_8UC3);
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) out.at<cv::Vec3b>(y, x) = signedColour(lum.at<double>(y, x), scale);
  return out;
}

cv::Mat normalImage(const cv::Mat& normals) {
  cv::Mat out(normals.size(), CV_8UC3, cv::Scalar::all(0));
  for (int y = 0; y < normals.rows; ++y)
    for (int x = 0; x < normals.cols; ++x) {
      const cv::Vec4f n = normals.at<cv::Vec4f>(y, x);
      if (n[3] < 0.5f) continue;
      for (int c = 0; c < 3; ++c) out.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<uchar>(127.5 * (n[c] + 1.0));
    }
  return out;
}

cv::Mat linearImage(const cv::Mat& image, double multiply) {
  cv::Mat rgb;
  if (image.channels() == 4)
    cv::cvtColor(image, rgb, cv::COLOR_RGBA2RGB);
  else
    rgb = image.clone();
  rgb.convertTo(rgb, CV_32FC3, multiply);
  return capture::encodeSrgb(rgb);
}

}  // namespace mrgi::lighting
