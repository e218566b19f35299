#include "lighting/clipped_real.h"

namespace mrgi::lighting {

cv::Mat clippedChannels(const cv::Mat& rgb8, int level) {
  CV_Assert(rgb8.type() == CV_8UC3);
  cv::Mat out(rgb8.size(), CV_8UC1);
  for (int y = 0; y < rgb8.rows; ++y) {
    const auto* c = rgb8.ptr<cv::Vec3b>(y);
    auto* o = out.ptr<uint8_t>(y);
    for (int x = 0; x < rgb8.cols; ++x) o[x] = clippedChannelBits(c[x], level);
  }
  return out;
}

}  // namespace mrgi::lighting
