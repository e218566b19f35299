#include "capture/colour.h"

#include <array>

namespace mrgi::capture {

cv::Mat decodeSrgb(const cv::Mat& rgb8) {
  CV_Assert(rgb8.type() == CV_8UC3);
  static const std::array<float, 256> lut = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = srgbToLinear(i / 255.f);
    return t;
  }();
  cv::Mat out(rgb8.size(), CV_32FC3);
  for (int y = 0; y < rgb8.rows; ++y) {
    const auto* in = rgb8.ptr<cv::Vec3b>(y);
    auto* o = out.ptr<cv::Vec3f>(y);
    for (int x = 0; x < rgb8.cols; ++x)
      for (int c = 0; c < 3; ++c) o[x][c] = lut[in[x][c]];
  }
  return out;
}

cv::Mat encodeSrgb(const cv::Mat& linear) {
  CV_Assert(linear.type() == CV_32FC3);
  cv::Mat out(linear.size(), CV_8UC3);
  for (int y = 0; y < linear.rows; ++y) {
    const auto* in = linear.ptr<cv::Vec3f>(y);
    auto* o = out.ptr<cv::Vec3b>(y);
    for (int x = 0; x < linear.cols; ++x)
      for (int c = 0; c < 3; ++c) o[x][c] = static_cast<uchar>(std::lround(linearToSrgb(in[x][c]) * 255.f));
  }
  return out;
}

}  // namespace mrgi::capture
